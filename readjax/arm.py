"""Differentiable Panda kinematics in jnp: the arm chain as data and forward kinematics.

An :class:`ArmChain` holds numpy constants of the serial chain (world -> link0 -> link1..link7 ->
hand -> site "tcp"); :func:`fk` and :func:`fk_jacobian` are pure functions of joint angles, so they
jit, vmap and differentiate (the kinematics-aware autoencoder back-propagates through them).
No MuJoCo import: :func:`readjax.sim.kinematics.chain_from_model` extracts the chain from the
MJCF the simulator compiles.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

FINGER_MAX = 0.04  # metres per finger; grip = mean finger opening / FINGER_MAX
HOME_Q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], np.float32)


class ArmChain(NamedTuple):
    """Fixed transforms and joint data of the serial chain ending at the end-effector site."""

    body_pos: np.ndarray  # (nb, 3) position of each body in its parent
    body_rot: np.ndarray  # (nb, 3, 3)
    joint_of_body: tuple  # per body: index into q, or -1 for a fixed body
    joint_axis: np.ndarray  # (7, 3) in the body frame
    joint_pos: np.ndarray  # (7, 3) in the body frame
    site_pos: np.ndarray  # (3,) end-effector site in the last body
    site_rot: np.ndarray  # (3, 3)
    lower: np.ndarray  # (7,) joint limits
    upper: np.ndarray  # (7,)
    qpos_adr: np.ndarray  # (7,) addresses of the arm joints in qpos
    qvel_adr: np.ndarray  # (7,)


def _axis_rotation(axis: np.ndarray, angle: jax.Array) -> jax.Array:
    """Rodrigues rotation about a constant unit axis."""
    a = jnp.asarray(axis / np.linalg.norm(axis))
    k = jnp.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]], dtype=jnp.float32)
    s, c = jnp.sin(angle), jnp.cos(angle)
    return jnp.eye(3, dtype=jnp.float32) + s * k + (1 - c) * (k @ k)


def _walk(chain: ArmChain, q: jax.Array):
    """World frames along the chain; returns site pose and per-joint (axis, point) in world."""
    rot = jnp.eye(3, dtype=q.dtype)
    pos = jnp.zeros(3, q.dtype)
    axes = [None] * 7
    points = [None] * 7
    for i, k in enumerate(chain.joint_of_body):
        pos = pos + rot @ chain.body_pos[i]
        rot = rot @ chain.body_rot[i]
        if k >= 0:
            p = pos + rot @ chain.joint_pos[k]
            axes[k] = rot @ chain.joint_axis[k]
            points[k] = p
            r_j = _axis_rotation(chain.joint_axis[k], q[k])
            # rotation about an axis through joint_pos: x -> p + R (x - p)
            pos = p + rot @ (r_j @ (-chain.joint_pos[k]))
            rot = rot @ r_j
    site_pos = pos + rot @ chain.site_pos
    site_rot = rot @ chain.site_rot
    return site_pos, site_rot, jnp.stack(axes), jnp.stack(points)


def fk(chain: ArmChain, q: jax.Array) -> tuple[jax.Array, jax.Array]:
    """End-effector site position (..., 3) and rotation (..., 3, 3) in world for q (..., 7)."""
    q = jnp.asarray(q, jnp.float32)
    flat = q.reshape(-1, 7)
    p, r, _, _ = jax.vmap(lambda x: _walk(chain, x))(flat)
    return p.reshape(q.shape[:-1] + (3,)), r.reshape(q.shape[:-1] + (3, 3))


def fk_jacobian(chain: ArmChain, q: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Site pose and its geometric Jacobian (6, 7): rows 0-2 linear, 3-5 angular (world)."""
    p, r, axes, points = _walk(chain, jnp.asarray(q, jnp.float32))
    jp = jnp.cross(axes, p[None, :] - points)  # (7, 3)
    return p, r, jnp.concatenate([jp.T, axes.T], axis=0)


def grip_from_fingers(finger_qpos: jax.Array) -> jax.Array:
    """Gripper opening in [0, 1] (1 = open) from the two finger joint positions (..., 2)."""
    return jnp.clip(jnp.mean(finger_qpos, axis=-1) / FINGER_MAX, 0.0, 1.0)
