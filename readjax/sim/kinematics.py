"""The Panda arm chain read from the same MJCF the simulator compiles.

The chain (world -> link0 -> link1..link7 -> hand -> site "tcp") is extracted once from a
``mujoco.MjModel`` into an :class:`readjax.arm.ArmChain` of numpy constants; the pure forward
kinematics (:func:`fk`, :func:`fk_jacobian`) live in :mod:`readjax.arm` and are re-exported here.
"""

from __future__ import annotations

import jax.numpy as jnp
import mujoco
import numpy as np

from readjax import geometry as geo
from readjax.arm import FINGER_MAX, HOME_Q, ArmChain, fk, fk_jacobian, grip_from_fingers  # noqa: F401

ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
FINGER_JOINTS = ("finger_left", "finger_right")


def chain_from_model(model: mujoco.MjModel, site: str = "tcp") -> ArmChain:
    """Extract the arm chain from a compiled model (names as in tasks_mjcf/robot/panda.xml)."""
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if site_id < 0:
        raise ValueError(f"model has no site {site!r}")
    bodies = []
    b = int(model.site_bodyid[site_id])
    while b != 0:
        bodies.append(b)
        b = int(model.body_parentid[b])
    bodies.reverse()
    arm_jnt = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in ARM_JOINTS]
    if min(arm_jnt) < 0:
        raise ValueError("model lacks the Panda arm joints joint1..joint7")
    joint_of_body, axes, jpos = [], [], []
    for body in bodies:
        jnts = [j for j in range(model.body_jntadr[body], model.body_jntadr[body] + model.body_jntnum[body])]
        if not jnts:
            joint_of_body.append(-1)
            continue
        if len(jnts) != 1 or jnts[0] not in arm_jnt:
            raise ValueError(f"body {model.body(body).name} on the arm chain has unexpected joints")
        joint_of_body.append(arm_jnt.index(jnts[0]))
    for k in range(7):
        j = arm_jnt[k]
        axes.append(model.jnt_axis[j])
        jpos.append(model.jnt_pos[j])
    rots = np.stack([np.asarray(geo.quat_to_mat(jnp.asarray(model.body_quat[b]))) for b in bodies])
    return ArmChain(
        body_pos=model.body_pos[bodies].astype(np.float32),
        body_rot=rots.astype(np.float32),
        joint_of_body=tuple(joint_of_body),
        joint_axis=np.asarray(axes, np.float32),
        joint_pos=np.asarray(jpos, np.float32),
        site_pos=model.site_pos[site_id].astype(np.float32),
        site_rot=np.asarray(geo.quat_to_mat(jnp.asarray(model.site_quat[site_id])), np.float32),
        lower=model.jnt_range[arm_jnt, 0].astype(np.float32),
        upper=model.jnt_range[arm_jnt, 1].astype(np.float32),
        qpos_adr=model.jnt_qposadr[arm_jnt].astype(np.int32),
        qvel_adr=model.jnt_dofadr[arm_jnt].astype(np.int32),
    )
