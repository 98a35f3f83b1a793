"""PB: success-predicate truth table and expert success."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("push_button")


@pytest.mark.parametrize("travel, expected", [(0.0, False), (-0.002, False), (-0.0035, True), (-0.011, True)])
def test_truth_table(env, travel, expected):
    scene = env.sample_scene(jax.random.key(3))
    qpos = np.array(scene.qpos)
    qpos[env.button_qadr] = travel
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, None))
    assert (ok, fail) == (expected, False)


def test_expert_succeeds(env):
    _, ok, _, _ = expert_run("push_button")
    assert ok.sum() >= len(ok) - 1
