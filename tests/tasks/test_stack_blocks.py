"""SB: two red cubes stacked on the spot AND released; distractors never count; sampling; expert."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.stack_blocks import MIN_DIST, SIZE, SPOT_CLEAR
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

H = SIZE / 2


@pytest.fixture(scope="module")
def env():
    return tasks.make("stack_blocks")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(7))


def state(env, scene, moves):
    """``moves``: {cube index (0-3 red, 4-7 distractors): (dx, dy, z) relative to the spot}."""
    qpos = np.array(scene.qpos)
    for i, (dx, dy, z) in moves.items():
        a = env.cube_qadr[i]
        qpos[a:a + 3] = (env.spot[0] + dx, env.spot[1] + dy, z)
        qpos[a + 3:a + 7] = (1.0, 0.0, 0.0, 0.0)
    return hand_built(env, qpos)


@pytest.mark.parametrize(
    "moves, attached, expected",
    [
        ({0: (0, 0, H), 1: (0, 0, 3 * H)}, None, True),  # two reds stacked on the spot
        ({2: (0.005, -0.004, H), 3: (-0.006, 0.01, 3 * H)}, None, True),  # any two reds, slightly off
        ({0: (0, 0, H), 1: (0, 0, 3 * H)}, 1, False),  # the top one still grasped
        ({0: (0, 0, H), 1: (0, 0, 3 * H)}, 5, False),  # a distractor grasped (nothing-grasped fails)
        ({0: (-0.0225, 0, H), 1: (0.0225, 0, H)}, None, False),  # side by side, not stacked
        ({0: (0, 0, H)}, None, False),  # only one red on the spot
        ({0: (0, 0, H), 4: (0, 0, 3 * H)}, None, False),  # red + distractor
        ({4: (0, 0, H), 5: (0, 0, 3 * H)}, None, False),  # two distractors stacked
        ({0: (0.15, 0.1, H), 1: (0.15, 0.1, 3 * H)}, None, False),  # stacked away from the spot
    ],
)
def test_truth_table(env, scene, moves, attached, expected):
    ok, fail, _ = judge(env, scene, state(env, scene, moves), grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_scene_sampling(env):
    keys = jax.vmap(jax.random.key)(np.arange(100))
    scenes = jax.vmap(env.sample_scene)(keys)
    xy = np.asarray(scenes.params["xy"])  # (100, 8, 2)
    d = np.linalg.norm(xy[:, :, None] - xy[:, None], axis=-1) + np.eye(8) * 1e3
    assert d.min() >= MIN_DIST - 1e-6
    assert np.linalg.norm(xy - env.spot, axis=-1).min() >= SPOT_CLEAR - 1e-6
    rgba = np.asarray(scenes.rgba)  # distractor colours: 4 different, none red
    assert all(len({tuple(c) for c in r}) == 4 for r in rgba)
    assert not np.any((rgba[..., 0] > 0.8) & (rgba[..., 1] < 0.3) & (rgba[..., 2] < 0.3))


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("stack_blocks")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released at the end
