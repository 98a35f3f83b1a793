"""Helpers for task tests: hand-built states and a shared, cached expert run per task.

Truth tables evaluate a task's predicates on states built by hand with C MuJoCo
(``mj_forward``) and converted with ``mjx.put_data`` — no compile needed. Expert runs use the
library's cached batched episode function, so each task compiles once per test session (and
the persistent compilation cache makes later sessions fast).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from readjax import tasks
from readjax.data.generate import episode_fn
from readjax.sim import mjx

EXPERT_SEEDS = 4  # a few seeds per task (a multiple of the 2 forced devices)


def hand_built(env, qpos: np.ndarray, mocap_pos=None, mocap_quat=None):
    """mjx.Data for a hand-built configuration (kinematics, contacts, positions all computed)."""
    m = env.mj_model
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    if m.nmocap:
        d.mocap_pos[:] = env.default_scene().mocap_pos if mocap_pos is None else mocap_pos
        d.mocap_quat[:] = env.default_scene().mocap_quat if mocap_quat is None else mocap_quat
    mujoco.mj_forward(m, d)
    return mjx.put_data(m, d)


def grasping(env, index: int | None):
    """A grasp state with object ``index`` attached (None: nothing attached)."""
    g = env.grasp_spec.init()
    if index is None:
        return g
    return g.replace(attached=g.attached.at[index].set(True))


def judge(env, scene, data, grasp, progress=None):
    """(success, failure) of the task predicates on one hand-built state."""
    progress = env.init_progress() if progress is None else progress
    progress = env.update_progress(progress, data, grasp, scene)
    fail = bool(env.is_failure(progress, data, grasp, scene))
    ok = bool(env.is_success(progress, data, grasp, scene)) and not fail
    return ok, fail, progress


@functools.cache
def expert_run(task: str):
    """Scenes, success flags, start joints and traces of the expert on the first seeds."""
    env = tasks.make(task)
    seeds = jnp.arange(EXPERT_SEEDS, dtype=jnp.int32)
    out = episode_fn(env)(seeds)
    return jax.tree.map(np.asarray, out)
