"""PC: truth table (grasped AND out of the success sensor; the distractor grasp fails), RLBench's
placement (boundary turned +-pi, cups turned +-pi, >= 0.1 m apart), the rim grasp, expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.pick_up_cup import BOUNDARY, MIN_DIST, WALL_CENTRE, rim_grasp
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("pick_up_cup")


@pytest.mark.parametrize(
    "lift, side, attached, expected",
    [
        (0.15, 0.0, 0, (True, False)),  # red cup grasped and lifted out of the sensor
        (0.15, 0.0, None, (False, False)),  # out of the sensor but not grasped (e.g. knocked up)
        (0.05, 0.0, 0, (False, False)),  # grasped, still in the sensor
        (0.095, 0.0, 0, (False, False)),  # its bottom 5 mm below the sensor's top
        (0.105, 0.0, 0, (True, False)),  # its bottom 5 mm above it
        (0.0, 0.12, 0, (True, False)),  # carried out sideways: not detected either (RLBench's semantics)
        (0.0, 0.06, 0, (False, False)),  # moved 6 cm: partly still in the 10 cm box
        (0.15, 0.0, 1, (False, True)),  # the distractor is grasped: failure (the paper)
    ],
)
def test_truth_table(env, lift, side, attached, expected):
    scene = env.sample_scene(jax.random.key(5))
    qpos = np.array(scene.qpos)
    qpos[env.cup_qadr:env.cup_qadr + 3] += [side, 0.0, lift]
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, attached))
    assert (ok, fail) == expected


def test_distractor_grasp_fails_even_after_success(env):
    """Success is only counted while no failure happened (the rollout keeps the flags)."""
    scene = env.sample_scene(jax.random.key(5))
    qpos = np.array(scene.qpos)
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, 1))
    assert fail and not ok


def test_placement_is_rlbench(env):
    scenes = jax.jit(jax.vmap(env.sample_scene))(jax.vmap(jax.random.key)(jnp.arange(48)))
    p = jax.tree.map(np.asarray, scenes.params)
    assert np.all(p["feasible"])
    cup, other = p["cup"][:, :2], p["distractor"][:, :2]
    assert np.all(np.linalg.norm(cup - other, axis=1) >= MIN_DIST - 1e-6)
    assert p["task_yaw"].min() < -2.5 and p["task_yaw"].max() > 2.5
    rel = (p["cup_yaw"] - p["task_yaw"] + np.pi) % (2 * np.pi) - np.pi  # the sensor's own turn
    assert rel.min() < -2.5 and rel.max() > 2.5
    assert np.ptp(cup[:, 0]) > 0.2 and np.ptp(cup[:, 1]) > 0.4  # over the workspace, not a patch
    # both cups inside the boundary, in the task frame recovered from the task yaw: all within the
    # boundary's turned half-diagonal of each other
    assert np.all(np.linalg.norm(cup - other, axis=1) <= 2 * np.linalg.norm(BOUNDARY))
    # the cups stand upright, turned about z only
    q = np.asarray(scenes.qpos)[:, env.cup_qadr + 3:env.cup_qadr + 7]
    np.testing.assert_allclose(q[:, 1:3], 0.0, atol=1e-6)


@pytest.mark.parametrize("seed", range(6))
def test_rim_grasp_on_the_far_wall(seed):
    rng = np.random.default_rng(seed)
    cup = np.array([rng.uniform(0.3, 0.7), rng.uniform(-0.4, 0.4), 0.0], np.float32)
    cup_yaw, away = rng.uniform(-np.pi, np.pi, 2)
    pos, yaw = map(np.asarray, rim_grasp(jnp.asarray(cup), jnp.float32(cup_yaw), jnp.float32(away)))
    radial = pos[:2] - cup[:2]
    assert np.linalg.norm(radial) == pytest.approx(WALL_CENTRE, abs=1e-5)
    wall = np.arctan2(radial[1], radial[0])
    k = (wall - cup_yaw) / (np.pi / 4)
    assert abs(k - round(k)) < 1e-3  # on a wall's centre
    assert abs((wall - away + np.pi) % (2 * np.pi) - np.pi) <= np.pi / 8 + 1e-4  # facing away
    fingers = np.array([-np.sin(yaw), np.cos(yaw)])  # the fingers open along Rz(yaw) * y
    assert abs(abs(fingers @ radial) / WALL_CENTRE - 1.0) < 1e-4  # radially
    centre = np.arctan2(pos[1], pos[0]) + np.pi / 4
    assert abs((yaw - centre + np.pi) % (2 * np.pi) - np.pi) <= np.pi / 2 + 1e-5  # joint 7 near its centre


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("pick_up_cup")
    assert ok.sum() >= len(ok) - 1
    # the gripper really closed on the cup wall and carried it: grip reading below open
    assert np.all(trace.grip[:, -1] < 0.5)
