"""Damped-least-squares IK: reachable targets are reached, limits are kept."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import tasks
from readjax.sim import ik
from readjax.sim.kinematics import HOME_Q, fk


def test_reaches_targets_near_the_workspace():
    env = tasks.make("reach_target")
    rng = np.random.default_rng(0)
    q_true = (HOME_Q + rng.normal(scale=0.35, size=(64, 7))).astype(np.float32)
    q_true = np.clip(q_true, env.chain.lower + 0.05, env.chain.upper - 0.05)
    pos, rot = fk(env.chain, q_true)
    solve = jax.jit(jax.vmap(lambda p, r: ik.solve_ik(env.chain, jnp.asarray(HOME_Q), p, r, 60)))
    q = solve(pos, rot)
    pe, re = jax.vmap(lambda q, p, r: ik.pose_error(env.chain, q, p, r))(q, pos, rot)
    assert np.quantile(np.asarray(pe), 0.95) < 1e-3 and np.quantile(np.asarray(re), 0.95) < 1e-2
    assert np.all(np.asarray(q) >= env.chain.lower) and np.all(np.asarray(q) <= env.chain.upper)
