"""MuJoCo cameras as :class:`readjax.camera.CameraParams` (the pinhole model itself lives there).

MuJoCo cameras look along their -z with y up; :func:`camera_from_model` converts to the OpenCV
convention of :mod:`readjax.camera`. The model's names are re-exported here.
"""

from __future__ import annotations

import mujoco
import numpy as np

from readjax.camera import (CameraParams, camera_to_world, project_uvz, rotation_to_camera,  # noqa: F401
                            rotation_to_world, unproject_uvz, world_to_camera)

# MuJoCo camera axes (x right, y up, z backward) -> OpenCV (x right, y down, z forward).
_MJ_TO_CV = np.diag([1.0, -1.0, -1.0])


def camera_from_model(model: mujoco.MjModel, name: str, width: int, height: int) -> CameraParams:
    """The named fixed camera of a model at a given resolution (square pixels, centred)."""
    cam = model.camera(name)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    rot = data.cam_xmat[cam.id].reshape(3, 3) @ _MJ_TO_CV
    pos = data.cam_xpos[cam.id].copy()
    fy = 0.5 * height / np.tan(np.deg2rad(model.cam_fovy[cam.id]) / 2)
    k = np.array([[fy, 0, width / 2], [0, fy, height / 2], [0, 0, 1]], np.float64)
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, pos
    return CameraParams(k, t, width, height)
