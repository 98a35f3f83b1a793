"""C MuJoCo replay of an MJX rollout: the parity oracle and the benchmark baseline.

Replays the actuator commands an MJX rollout recorded, one control step at a time, in C
MuJoCo (``mj_step``) with the same substeps, pinned fixtures and grasp attachments (taken from
the MJX trace, so both sides carry the same objects). Used to check that MJX and C MuJoCo
simulate the same scene alike and to time sequential C MuJoCo on the same rollout.
"""

from __future__ import annotations

import mujoco
import numpy as np


def replay(env, scene, trace, data: mujoco.MjData | None = None, on_step=None) -> np.ndarray:
    """Replay one episode; returns the tcp position after every control step (T, 3).

    ``on_step(k, data)`` (optional) is called after every control step, e.g. to render a video.
    """
    m = env.mj_model
    d = mujoco.MjData(m) if data is None else data
    mujoco.mj_resetData(m, d)
    d.qpos[:] = np.asarray(scene.qpos)
    if m.nmocap:
        d.mocap_pos[:] = np.asarray(scene.mocap_pos)
        d.mocap_quat[:] = np.asarray(scene.mocap_quat)
    mujoco.mj_forward(m, d)
    pin_q, pin_v = env.pinned_qpos_adr, env.pinned_qvel_adr
    pinned = np.asarray(scene.qpos)[pin_q]
    spec = env.grasp_spec
    tcp = m.site("tcp").id
    ctrl = np.asarray(trace.ctrl)
    attached = np.asarray(trace.attached)
    rel_pos, rel_quat = np.asarray(trace.rel_pos), np.asarray(trace.rel_quat)
    out = np.empty((len(ctrl), 3))
    quat_tcp = np.empty(4)
    obj_q = np.empty(4)
    for k in range(len(ctrl)):
        d.ctrl[:] = ctrl[k]
        # the MJX step applies the grasp state from before the step
        att = attached[k - 1] if k else np.zeros(spec.n, bool)
        for _ in range(env.substeps):
            mujoco.mj_step(m, d)
            if len(pin_q):
                d.qpos[pin_q] = pinned
                d.qvel[pin_v] = 0.0
            if att.any():
                mujoco.mj_kinematics(m, d)
                rot = d.site_xmat[tcp].reshape(3, 3)
                mujoco.mju_mat2Quat(quat_tcp, d.site_xmat[tcp])
                for i in np.flatnonzero(att):
                    a = spec.qpos_adr[i]
                    d.qpos[a:a + 3] = d.site_xpos[tcp] + rot @ rel_pos[k - 1, i]
                    mujoco.mju_mulQuat(obj_q, quat_tcp, rel_quat[k - 1, i])
                    d.qpos[a + 3:a + 7] = obj_q
                    d.qvel[spec.qvel_adr[i]:spec.qvel_adr[i] + 6] = 0.0
        mujoco.mj_kinematics(m, d)
        out[k] = d.site_xpos[tcp]
        if on_step is not None:
            on_step(k, d)
    return out
