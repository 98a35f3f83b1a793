"""Damped-least-squares inverse kinematics for the Panda end effector, in jnp.

One :func:`ik_step` is a DLS update towards a target pose with a null-space pull towards a
rest posture (a plain posture regulariser leaves mm-level error; the null-space term does
not), clamped to the joint limits. :func:`solve_ik` iterates it; the controller warm-starts it
from the previous command, so 2-3 iterations per 20 ms control step track a moving target.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from readjax import geometry as geo
from readjax import linalg
from readjax.sim.kinematics import HOME_Q, ArmChain, fk, fk_jacobian


class IKParams(NamedTuple):
    damping: float = 0.01  # DLS lambda
    rot_weight: float = 0.5  # weight of the orientation error against position (m per rad)
    null_gain: float = 0.2  # pull towards the rest posture, inside the null space
    max_step: float = 0.25  # rad per iteration per joint
    margin: float = 0.01  # rad kept away from the joint limits


def pose_error(chain: ArmChain, q: jax.Array, pos: jax.Array, rot: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(position error in m, orientation error in rad) of q's end effector against a target."""
    p, r = fk(chain, q)
    return jnp.linalg.norm(p - pos, axis=-1), geo.rotation_angle(rot, r)


def ik_step(chain: ArmChain, q: jax.Array, pos: jax.Array, rot: jax.Array,
            params: IKParams = IKParams(), rest: jax.Array | None = None) -> jax.Array:
    p, r, jac = fk_jacobian(chain, q)
    w = jnp.array([1.0, 1.0, 1.0, params.rot_weight, params.rot_weight, params.rot_weight])
    err = jnp.concatenate([pos - p, geo.rotation_error(rot, r)]) * w
    jw = jac * w[:, None]
    jjt = jw @ jw.T + (params.damping**2) * jnp.eye(6)
    dq = jw.T @ linalg.spd_solve(jjt, err)
    rest = jnp.asarray(HOME_Q) if rest is None else rest
    # null-space projector of the damped pseudo-inverse
    pinv = jw.T @ linalg.spd_solve(jjt, jnp.eye(6))
    null = jnp.eye(7) - pinv @ jw
    dq = dq + null @ (params.null_gain * (rest - q))
    dq = jnp.clip(dq, -params.max_step, params.max_step)
    return jnp.clip(q + dq, chain.lower + params.margin, chain.upper - params.margin)


def solve_ik(chain: ArmChain, q0: jax.Array, pos: jax.Array, rot: jax.Array, iterations: int = 3,
             params: IKParams = IKParams(), rest: jax.Array | None = None) -> jax.Array:
    """Iterate :func:`ik_step` from q0 (single configuration; vmap for batches)."""
    return lax.fori_loop(0, iterations, lambda _, q: ik_step(chain, q, pos, rot, params, rest), q0)
