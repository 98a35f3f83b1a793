"""The motion format of METHOD.md section 2 — the one place its key order is written down.

A motion is a float32 array (..., 101, 10) in the FRONT-CAMERA frame, per frame:

    [0:2]  uv     end-effector position projected into the image, normalised to [-1, 1]
    [2:3]  z      its depth along the camera's optical axis, metres
    [3:9]  rot6d  first two rows of the end-effector rotation matrix in the camera frame
    [9:10] grip   gripper opening in [0, 1] (1 = open)

Joint angles (..., 101, 7) are stored beside it (readjax goes beyond the paper here).
Use the accessors below instead of slicing by hand.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax import camera as cam_lib
from readjax.camera import CameraParams

FRAMES = 101
DIM = 10
JOINTS = 7
KEYS = {"uv": slice(0, 2), "z": slice(2, 3), "rot6d": slice(3, 9), "grip": slice(9, 10)}


def uv(m: jax.Array) -> jax.Array:
    return m[..., KEYS["uv"]]


def z(m: jax.Array) -> jax.Array:
    return m[..., KEYS["z"]]


def rot6d(m: jax.Array) -> jax.Array:
    return m[..., KEYS["rot6d"]]


def grip(m: jax.Array) -> jax.Array:
    return m[..., KEYS["grip"]]


def split_keys(m: jax.Array) -> dict[str, jax.Array]:
    return {k: m[..., s] for k, s in KEYS.items()}


def join_keys(parts: dict[str, jax.Array]) -> jax.Array:
    return jnp.concatenate([parts[k] for k in KEYS], axis=-1)


def check_motion(m, name: str = "motion") -> None:
    """Raise a clear ValueError for a wrongly shaped or non-finite motion array."""
    shape = getattr(m, "shape", None)
    if shape is None or len(shape) < 2 or tuple(shape[-2:]) != (FRAMES, DIM):
        raise ValueError(f"{name} must have shape (..., {FRAMES}, {DIM}), got {shape}")
    if not bool(jnp.all(jnp.isfinite(jnp.asarray(m)))):
        raise ValueError(f"{name} contains NaN or infinite values")


def check_motion_shape(m, name: str = "motion") -> None:
    """ValueError unless ``m`` has the static shape (B, 101, 10) (works on tracers)."""
    shape = getattr(m, "shape", None)
    if shape is None or len(shape) != 3 or tuple(shape[1:]) != (FRAMES, DIM):
        raise ValueError(f"{name} must have shape (B, {FRAMES}, {DIM}), got {shape}")


def encode(cam: CameraParams, pos_world: jax.Array, rot_world: jax.Array, grip_open: jax.Array) -> jax.Array:
    """World end-effector poses (..., T, 3), (..., T, 3, 3) and grip (..., T) -> motion (..., T, 10)."""
    uvz = cam_lib.project_uvz(cam, pos_world)
    r_cam = cam_lib.rotation_to_camera(cam, rot_world)
    return jnp.concatenate([uvz, geo.rot6d_from_mat(r_cam), jnp.asarray(grip_open)[..., None]], axis=-1)


def decode(cam: CameraParams, m: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Motion (..., T, 10) -> world positions (..., T, 3), rotations (..., T, 3, 3), grip (..., T)."""
    pos = cam_lib.unproject_uvz(cam, m[..., 0:3])
    r_world = cam_lib.rotation_to_world(cam, geo.mat_from_rot6d(rot6d(m)))
    return pos, r_world, grip(m)[..., 0]


def world_poses(cam: CameraParams, motions) -> tuple[np.ndarray, np.ndarray]:
    """World end-effector positions (..., T, 3) and rotations (..., T, 3, 3) of motions, as NumPy
    arrays (what records and failure diagnoses read)."""
    pos, rot, _ = decode(cam, jnp.asarray(motions))
    return np.asarray(pos), np.asarray(rot)
