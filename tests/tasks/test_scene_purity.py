"""A scene is a pure function of (task, seed): the same alone, at any batch size, at any position in
the batch, with or without jit. (Broken before readjax.prng: under rbg a vmapped batch drew every
scene from its first key, so evaluation ran scenes other than the ones its images showed.)"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks

SEEDS = 1_000_000 + np.arange(100)
PROBE = 37  # index of the probed seed in the batch of 100


def _leaves(scene):
    return [np.asarray(x) for x in jax.tree.leaves(scene)]


@pytest.mark.parametrize("task", tasks.names())
def test_scene_is_independent_of_batching(task):
    env = tasks.make(task)
    batched = jax.jit(jax.vmap(env.sample_scene))
    seed = int(SEEDS[PROBE])
    alone = _leaves(jax.jit(env.sample_scene)(jax.random.key(seed)))
    eager = _leaves(env.sample_scene(jax.random.key(seed)))
    layouts = {
        "batch 100": (SEEDS, PROBE),
        "batch 32, position 0": (np.concatenate([[seed], SEEDS[:31]]), 0),
        "batch 32, position 20": (np.concatenate([SEEDS[50:70], [seed], SEEDS[70:81]]), 20),
        "batch 3, position 2": (np.array([SEEDS[5], SEEDS[9], seed]), 2),
        "batch 1": (np.array([seed]), 0),
    }
    for a, b in zip(alone, eager):  # XLA may fuse trigonometry differently: float32 round-off only
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6, err_msg=f"{task}: jit vs eager")
    for name, (seeds, pos) in layouts.items():
        keys = jax.vmap(jax.random.key)(jnp.asarray(seeds, jnp.int32))
        got = _leaves(batched(keys))
        for a, b in zip(alone, got):
            np.testing.assert_array_equal(a, b[pos], err_msg=f"{task}: seed {seed} alone vs {name}")
    # and the batch still holds different scenes for different seeds
    qpos = np.asarray(batched(jax.vmap(jax.random.key)(jnp.asarray(SEEDS[:3], jnp.int32))).qpos)
    mocap = np.asarray(batched(jax.vmap(jax.random.key)(jnp.asarray(SEEDS[:3], jnp.int32))).mocap_pos)
    assert not (np.allclose(qpos[0], qpos[1]) and np.allclose(mocap[0], mocap[1]))
