"""A scene is a pure function of (task, seed): the same alone, at any batch size, at any position in
the batch, inside the generation's episode or on its own. (Broken before readjax.prng: under rbg a
vmapped batch drew every scene from its first key, so evaluation ran scenes other than the ones its
images showed.)

Each task's expert run (``tests.tasks.helpers.expert_run``: seeds 0..EXPERT_SEEDS-1 in one batch of the
generation's episode function, compiled once per process for the task's other tests) is compared with
the scenes of ``jit(vmap(sample_scene))`` at another batch size, each seed at another position and
behind another first key, and with one seed sampled alone."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from tests.tasks.helpers import EXPERT_SEEDS, expert_run

# seeds 2 and 0 of the expert run, at positions 1 and 2 behind another first key (batch 3, not 4)
REORDERED = np.array([EXPERT_SEEDS + 7, 2, 0])


def _leaves(scene):
    return [np.asarray(x) for x in jax.tree.leaves(scene)]


@pytest.mark.parametrize("task", tasks.names())
def test_scene_is_independent_of_batching(task):
    env = tasks.make(task)
    in_episode = _leaves(expert_run(task)[0])  # batch EXPERT_SEEDS, inside reset + expert rollout
    keys = jax.vmap(jax.random.key)(jnp.asarray(REORDERED, jnp.int32))
    reordered = _leaves(jax.jit(jax.vmap(env.sample_scene))(keys))
    for pos, seed in enumerate(REORDERED):
        if seed >= EXPERT_SEEDS:
            continue
        for a, b in zip(in_episode, reordered):
            # two programs (the episode's and the sampler's): XLA may round trigonometry differently, so
            # float32 round-off only; a batch-dependent draw (rbg) gives another scene altogether
            np.testing.assert_allclose(a[seed], b[pos], rtol=0, atol=1e-6,
                                       err_msg=f"{task}: seed {seed} at position {seed} of {EXPERT_SEEDS} vs {pos} of 3")
    # one seed on its own (no vmap): the same up to float32 round-off (XLA may fuse trigonometry
    # differently without the batch axis)
    alone = _leaves(jax.jit(env.sample_scene)(jax.random.key(2)))
    for a, b in zip(alone, in_episode):
        np.testing.assert_allclose(a, b[2], rtol=0, atol=1e-6, err_msg=f"{task}: seed 2 alone vs batched")
    # and a batch holds different scenes for different seeds
    scenes = jax.tree.map(np.asarray, expert_run(task)[0])
    assert not (np.allclose(scenes.qpos[0], scenes.qpos[1]) and np.allclose(scenes.mocap_pos[0], scenes.mocap_pos[1]))
