"""PK: ordered success (on the board while held, THEN released there), scene sampling, expert."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.put_knife import BLOCK_HIGH, BLOCK_LOW, KNIFE_Z
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

FLAT = np.array([0.0, 0.0, -0.7071068, -0.7071068])  # knife lying flat, blade towards -y
ON_BOARD = np.array([0.52, -0.17, 0.028])
OFF_BOARD = np.array([0.35, 0.3, 0.008])


@pytest.fixture(scope="module")
def env():
    return tasks.make("put_knife")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(3))


def state(env, scene, pos, quat=FLAT):
    qpos = np.array(scene.qpos)
    a = env.knife_qadr
    qpos[a:a + 3], qpos[a + 3:a + 7] = pos, quat
    return hand_built(env, qpos, np.asarray(scene.mocap_pos), np.asarray(scene.mocap_quat))


def test_start_state(env, scene):
    block = np.asarray(scene.params["block"])
    knife = np.asarray(scene.qpos[env.knife_qadr:env.knife_qadr + 3])
    assert np.allclose(knife[:2], block[:2]) and knife[2] == pytest.approx(KNIFE_Z)
    assert np.allclose(np.asarray(scene.mocap_pos[env.block_mocap]), block)
    ok, fail, progress = judge(env, scene, hand_built(env, np.array(scene.qpos), np.asarray(scene.mocap_pos),
                                                      np.asarray(scene.mocap_quat)), grasping(env, None))
    assert (ok, fail, bool(progress["on_board_held"])) == (False, False, False)


@pytest.mark.parametrize(
    "steps, expected",
    [
        ([(ON_BOARD, 0)], False),  # on the board but still held
        ([(ON_BOARD, 0), (ON_BOARD, None)], True),  # held there, then released there
        ([(ON_BOARD, None)], False),  # on the board, never held there: wrong order
        ([(ON_BOARD + [0, 0, 0.04], 0), (ON_BOARD, None)], True),  # held 4 cm above it (inside the region)
        ([(ON_BOARD + [0, 0, 0.12], 0), (ON_BOARD, None)], False),  # held too high: never "on" the board
        ([(ON_BOARD, 0), (OFF_BOARD, None)], False),  # carried over the board, dropped elsewhere
        ([(ON_BOARD + [0.2, 0, 0], 0), (ON_BOARD + [0.2, 0, 0], None)], False),  # beside the board
    ],
)
def test_truth_table(env, scene, steps, expected):
    progress, ok = None, False
    for pos, attached in steps:
        ok, fail, progress = judge(env, scene, state(env, scene, pos), grasping(env, attached), progress)
        assert not fail
    assert ok == expected


def test_block_sampling(env):
    keys = jax.vmap(jax.random.key)(np.arange(64))
    scenes = jax.vmap(env.sample_scene)(keys)
    block = np.asarray(scenes.params["block"])
    assert np.all(block[:, :2] >= BLOCK_LOW) and np.all(block[:, :2] <= BLOCK_HIGH)
    assert np.ptp(block[:, 0]) > 0.15 and np.ptp(block[:, 1]) > 0.15


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("put_knife")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released at the end
