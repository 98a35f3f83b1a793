"""SB: two red cubes stacked in the spot's (turned) sensor AND released; RLBench's boundaries, one
distractor colour, the task yaw; an expert whose only still phases are the gripper's own actuation."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.arm import FINGER_MAX
from readjax.sim import placement
from readjax.sim.env import GRIPPER_SPEED
from readjax.tasks.stack_blocks import (BOUNDARY_HIGH, BOUNDARY_LOW, CLOSE_STEPS, CYCLE, MIN_DIST, OPEN_STEPS,
                                        SIZE)
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

H = SIZE / 2


@pytest.fixture(scope="module")
def env():
    return tasks.make("stack_blocks")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(7))


@pytest.fixture(scope="module")
def scenes(env):
    keys = jax.vmap(jax.random.key)(np.arange(64))
    return jax.tree.map(np.asarray, jax.jit(jax.vmap(env.sample_scene))(keys))


def state(env, scene, moves):
    """``moves``: {cube index (0-3 red, 4-7 distractors): (dx, dy, z)}, dx, dy in the spot's own
    (turned) frame."""
    qpos = np.array(scene.qpos)
    yaw = float(scene.params["task_yaw"])
    c, s = np.cos(yaw), np.sin(yaw)
    for i, (dx, dy, z) in moves.items():
        a = env.cube_qadr[i]
        qpos[a:a + 3] = (env.spot[0] + c * dx - s * dy, env.spot[1] + s * dx + c * dy, z)
        qpos[a + 3:a + 7] = (np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


@pytest.mark.parametrize(
    "moves, attached, expected",
    [
        ({0: (0, 0, H), 1: (0, 0, 3 * H)}, None, True),  # two reds stacked on the spot
        ({2: (0.005, -0.004, H), 3: (-0.006, 0.01, 3 * H)}, None, True),  # any two reds, slightly off
        ({0: (0.028, 0.028, H), 1: (0.028, 0.028, 3 * H)}, None, True),  # in a corner of the turned column
        ({0: (0.035, 0, H), 1: (0.035, 0, 3 * H)}, None, False),  # just outside it
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


def test_sensor_turns_with_the_task(env):
    """A corner of the column at task yaw pi/4 lies outside the unturned column: the sensor is turned."""
    s = env.sample_scene(jax.random.key(7))
    s = s.replace(params={**s.params, "task_yaw": jnp.float32(np.pi / 4)})
    data = state(env, s, {0: (0.028, 0.028, H), 1: (0.028, 0.028, 3 * H)})
    assert judge(env, s, data, grasping(env, None))[:2] == (True, False)
    unturned = s.replace(params={**s.params, "task_yaw": jnp.float32(0.0)})
    assert judge(env, unturned, data, grasping(env, None))[:2] == (False, False)


def test_scene_sampling(env, scenes):
    p = scenes.params
    assert p["feasible"].mean() > 0.9
    xy, yaw, bnd, task_yaw = p["xy"], p["yaw"], p["boundary"], p["task_yaw"]
    # the task yaw covers the full turn; the spot stays at the table centre
    assert np.histogram(task_yaw, bins=4, range=(-np.pi, np.pi))[0].min() >= 8
    assert np.allclose(env.spot, [0.5, 0.0])
    for i in range(len(xy)):
        c, s = np.cos(task_yaw[i]), np.sin(task_yaw[i])
        local = (xy[i] - env.spot) @ np.array([[c, -s], [s, c]])  # world -> task frame
        for k in range(8):  # each cube wholly inside its boundary (its turned corners)
            a = yaw[i, k] - task_yaw[i]
            corners = local[k] + H * np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]]) @ np.array(
                [[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
            assert np.all(corners >= BOUNDARY_LOW[bnd[i, k]] - 1e-5)
            assert np.all(corners <= BOUNDARY_HIGH[bnd[i, k]] + 1e-5)
        d = np.linalg.norm(xy[i][:, None] - xy[i][None], axis=-1) + np.eye(8)
        same = bnd[i][:, None] == bnd[i][None]
        assert d[same].min() >= MIN_DIST - 1e-5  # RLBench's min_distance within a boundary
        assert d.min() >= SIZE  # and nothing overlaps
        assert np.all(xy[i] >= placement.WORKSPACE_LOW) and np.all(xy[i] <= placement.WORKSPACE_HIGH)
    # block yaws cover the full turn
    assert np.histogram(yaw, bins=8, range=(-np.pi, np.pi))[0].min() > 20
    # the 4 distractors share one colour per episode (RLBench), never red or a look-alike
    rgba = scenes.rgba
    assert np.all(rgba == rgba[:, :1])
    assert len({tuple(r[0]) for r in rgba}) > 3
    assert not np.any((rgba[..., 0] > 0.8) & (rgba[..., 1] < 0.6) & (rgba[..., 2] < 0.8))


def test_expert_holds_still_only_while_the_gripper_actuates(env):
    """The close lasts what the gripper needs to reach the cube (+ at most 2 steps), the open ~1 frame,
    and no other segment keeps the arm still (no settle pauses)."""
    dt = env.control_dt
    need = (FINGER_MAX - SIZE / 2) / (GRIPPER_SPEED * dt)
    assert need <= CLOSE_STEPS <= need + 2
    assert OPEN_STEPS <= 4
    plan = env.expert_plan(env.sample_scene(jax.random.key(3)))
    pos, grip = np.asarray(plan.pos), np.asarray(plan.grip)
    still = np.flatnonzero(np.linalg.norm(np.diff(pos, axis=0), axis=1) < 1e-6) + 1
    assert np.all(grip[still] != grip[still - 1])  # a still segment is a gripper change
    assert sorted(set(np.asarray(env.expert_durations)[still])) == [OPEN_STEPS, CLOSE_STEPS]
    assert 350 <= sum(CYCLE) * 2 <= 400  # the paper's 350-400-frame SB demos


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("stack_blocks")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released at the end
