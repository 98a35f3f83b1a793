"""PC: truth table (lifted and grasped, both cups) and expert success."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("pick_up_cup")


@pytest.mark.parametrize(
    "cup_z, attached, expected",
    [
        (0.15, 0, (True, False)),  # red cup grasped and lifted
        (0.15, None, (False, False)),  # lifted but not grasped (e.g. knocked up)
        (0.05, 0, (False, False)),  # grasped, not lifted enough
        (0.15, 1, (False, True)),  # the distractor is grasped: failure
    ],
)
def test_truth_table(env, cup_z, attached, expected):
    scene = env.sample_scene(jax.random.key(5))
    qpos = np.array(scene.qpos)
    qpos[env.cup_qadr + 2] = cup_z
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, attached))
    assert (ok, fail) == expected


def test_distractor_grasp_fails_even_after_success(env):
    """Success is only counted while no failure happened (the rollout keeps the flags)."""
    scene = env.sample_scene(jax.random.key(5))
    qpos = np.array(scene.qpos)
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, 1))
    assert fail and not ok


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("pick_up_cup")
    assert ok.sum() >= len(ok) - 1
    # the gripper really closed on the cup wall and carried it: grip reading below open
    assert np.all(trace.grip[:, -1] < 0.5)
