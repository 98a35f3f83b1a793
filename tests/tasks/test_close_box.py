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


def test_success_is_relative_to_the_start(env):
    """RLBench's JointCondition measures |q - q0|: a lid starting at 2.5 rad must reach below -0.1 rad
    (impossible here), so 0.15 rad is no success from that start."""
    scene = env.sample_scene(jax.random.key(2))
    qpos = np.array(scene.qpos)
    qpos[env.lid_qadr] = 2.5
    start = scene.replace(qpos=jax.numpy.asarray(qpos))
    qpos[env.lid_qadr] = 0.15
    ok, fail, _ = judge(env, start, hand_built(env, qpos), grasping(env, None))
    assert (ok, fail) == (False, False)


def test_placement_is_rlbench_place_task(env):
    """The whole box within +-pi/8 of facing the robot, anywhere its footprint (with the open lid)
    fits the workspace; every early seed placeable."""
    from readjax.sim import placement
    from readjax.tasks.close_box import FOOTPRINT_MAX, FOOTPRINT_MIN
    scenes = jax.jit(jax.vmap(env.sample_scene))(jax.vmap(jax.random.key)(jax.numpy.arange(48)))
    yaw = np.asarray(scenes.params["yaw"])
    assert np.all(np.abs(yaw) <= np.pi / 8 + 1e-6) and yaw.min() < -0.3 and yaw.max() > 0.3
    box = np.asarray(scenes.params["box"])
    for b, y in zip(box, yaw):
        c, s = np.cos(y), np.sin(y)
        corners = np.array([[x, yy] for x in (FOOTPRINT_MIN[0], FOOTPRINT_MAX[0]) for yy in (FOOTPRINT_MIN[1], FOOTPRINT_MAX[1])])
        world = corners @ np.array([[c, -s], [s, c]]).T + b[:2]
        assert np.all(world >= placement.WORKSPACE_LOW - 1e-5) and np.all(world <= placement.WORKSPACE_HIGH + 1e-5)
    assert np.ptp(box[:, 1]) > 0.4  # spread across the workspace, not a patch
    assert np.all(np.asarray(scenes.params["feasible"]))


def test_expert_succeeds(env):
    _, ok, _, _ = expert_run("close_box")
    assert ok.sum() >= len(ok) - 1
