"""CB: hinge truth table and expert success."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.close_box import OPEN
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("close_box")


@pytest.mark.parametrize("angle, expected", [(OPEN, False), (1.5, False), (0.25, False), (0.15, True), (0.0, True)])
def test_truth_table(env, angle, expected):
    scene = env.sample_scene(jax.random.key(2))
    qpos = np.array(scene.qpos)
    qpos[env.lid_qadr] = angle
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, None))
    assert (ok, fail) == (expected, False)


def test_lid_starts_open(env):
    scene = env.sample_scene(jax.random.key(0))
    assert float(scene.qpos[env.lid_qadr]) == pytest.approx(OPEN)


def test_expert_succeeds(env):
    _, ok, _, _ = expert_run("close_box")
    assert ok.sum() >= len(ok) - 1
