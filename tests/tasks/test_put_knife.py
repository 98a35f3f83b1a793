"""PK: RLBench's ordered success (knife detected on the board, THEN nothing grasped), the board's
sensor turning with the task frame, the placement (task yaw +-pi, block yaw +-pi in its boundary),
and the expert."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import placement
from readjax.tasks.put_knife import (BLOCK_HALF, BOARD_LOCAL, BOUNDARY_HIGH, BOUNDARY_LOW, FOOTPRINT_MAX,
                                     FOOTPRINT_MIN, KNIFE_Z)
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("put_knife")


@pytest.fixture(scope="module")
def scenes(env):
    keys = jax.vmap(jax.random.key)(jnp.arange(48, dtype=jnp.int32))
    return jax.tree.map(np.asarray, jax.jit(jax.vmap(env.sample_scene))(keys))


@pytest.fixture(scope="module")
def scene(scenes):
    return jax.tree.map(lambda x: x[3], scenes)


def rot(yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def board_point(scene, local):
    """A world point given in the board's frame (origin on the table under its centre)."""
    return np.asarray(scene.params["board"]) + rot(float(scene.params["yaw"])) @ np.asarray(local, float)


def state(env, scene, pos):
    qpos = np.array(scene.qpos)
    a = env.knife_qadr
    qpos[a:a + 3], qpos[a + 3:a + 7] = pos, [0.0, 0.0, -0.7071068, -0.7071068]  # lying flat
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


ON = (0.0, 0.0, 0.028)  # lying on the board (its top at 0.02)
OFF = (0.0, 0.25, 0.008)  # on the table beside the board


def test_start_state(env, scene):
    block = scene.params["block"]
    knife = scene.qpos[env.knife_qadr:env.knife_qadr + 7]
    assert np.allclose(knife[:2], block[:2]) and knife[2] == pytest.approx(KNIFE_Z)
    np.testing.assert_allclose(knife[3:], scene.mocap_quat[env.block_mocap], atol=1e-6)  # blade along the slit
    assert np.allclose(scene.mocap_pos[env.block_mocap], block)
    ok, fail, progress = judge(env, scene, hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat),
                               grasping(env, None))
    assert (ok, fail, bool(progress["detected"])) == (False, False, False)


@pytest.mark.parametrize(
    "steps, expected",
    [
        ([(ON, 0)], False),  # on the board but still held
        ([(ON, 0), (ON, None)], True),  # detected while held, then released there
        ([(ON, None)], True),  # detected and nothing grasped at the same step (RLBench counts it)
        ([(ON, 0), (OFF, None)], True),  # detected, then released anywhere (RLBench's ordered set)
        ([(OFF, None), (ON, 0)], False),  # nothing grasped only BEFORE the detection: wrong order
        ([(OFF, None), (ON, 0), (OFF, 0)], False),  # detected, but never released
        ([((0.0, 0.0, 0.075), 0), (ON, None)], True),  # held 5.5 cm above the board (inside the sensor)
        ([((0.0, 0.0, 0.10), 0), ((0.0, 0.0, 0.10), None)], False),  # held too high: never detected
        ([((0.13, 0.0, 0.03), 0), (OFF, None)], True),  # near the end of the board's long side
        ([((0.0, 0.13, 0.03), 0), (OFF, None)], False),  # as far along its short side: off the board
    ],
)
def test_truth_table(env, scene, steps, expected):
    progress, ok = None, False
    for local, attached in steps:
        ok, fail, progress = judge(env, scene, state(env, scene, board_point(scene, local)), grasping(env, attached),
                                   progress)
        assert not fail
    assert ok == expected


def test_placement(env, scenes):
    """The board turns with the task frame (yaw +-pi) and the block turns freely (+-pi) inside its
    boundary of that frame; the whole footprint lies in the workspace."""
    p = scenes.params
    assert p["feasible"].mean() > 0.9
    yaw, block_yaw = p["yaw"], p["block_yaw"]
    assert yaw.min() < -2.5 and yaw.max() > 2.5
    rel = (block_yaw - yaw + np.pi) % (2 * np.pi) - np.pi
    assert rel.min() < -2.5 and rel.max() > 2.5
    np.testing.assert_allclose(scenes.mocap_pos[:, env.board_mocap], p["board"], atol=1e-6)
    for i in range(len(yaw)):
        r = rot(float(yaw[i]))[:2, :2]
        origin = p["board"][i, :2] - r @ BOARD_LOCAL
        lo, hi = (np.asarray(v) for v in placement.turned_extent(FOOTPRINT_MIN, FOOTPRINT_MAX, yaw[i]))
        assert np.all(origin + lo >= placement.WORKSPACE_LOW - 1e-5) and np.all(origin + hi <= placement.WORKSPACE_HIGH + 1e-5)
        local = r.T @ (p["block"][i, :2] - origin)
        blo, bhi = (np.asarray(v) for v in placement.turned_extent(-BLOCK_HALF, BLOCK_HALF, rel[i]))
        assert np.all(local + blo >= BOUNDARY_LOW - 1e-5) and np.all(local + bhi <= BOUNDARY_HIGH + 1e-5)
        q = scenes.mocap_quat[i, env.board_mocap]
        np.testing.assert_allclose(q, [np.cos(yaw[i] / 2), 0, 0, np.sin(yaw[i] / 2)], atol=1e-5)


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("put_knife")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released at the end
