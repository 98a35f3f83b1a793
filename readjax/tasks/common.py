"""Small pieces the task modules share: gripper orientations and state placement."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo

# The tcp pointing straight down with the fingers opening along world y (the home orientation).
DOWN = jnp.array([0.0, 1.0, 0.0, 0.0])


def down_quat(yaw) -> jax.Array:
    """tcp pointing down, rotated by ``yaw`` about world z; the fingers open along the line of
    Rz(yaw) * y (the hand's +y axis is -Rz(yaw) * y)."""
    return geo.quat_mul(geo.yaw_quat(jnp.asarray(yaw, jnp.float32)), DOWN)


def set_free_body(qpos: jax.Array, adr: int, pos, quat=None) -> jax.Array:
    """Write a free joint's position (and orientation) at qpos address ``adr``."""
    qpos = qpos.at[adr:adr + 3].set(jnp.asarray(pos, jnp.float32))
    if quat is not None:
        qpos = qpos.at[adr + 3:adr + 7].set(jnp.asarray(quat, jnp.float32))
    return qpos


def free_adr(model, body: str) -> int:
    b = model.body(body).id
    return int(model.jnt_qposadr[model.body_jntadr[b]])


def mocap_index(model, body: str) -> int:
    idx = int(model.body_mocapid[model.body(body).id])
    if idx < 0:
        raise ValueError(f"body {body!r} is not a mocap body")
    return idx


def in_box(point: jax.Array, centre: jax.Array, rot: jax.Array, half: np.ndarray) -> jax.Array:
    """Whether a world point lies inside an oriented box (centre, rotation, half sizes)."""
    local = jnp.einsum("...ji,...j->...i", rot, point - centre)
    return jnp.all(jnp.abs(local) <= jnp.asarray(half), axis=-1)
