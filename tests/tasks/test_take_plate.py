"""TP: plate out of the rack AND on the blue cube AND released; slot sampling; expert."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.take_plate import CUBE, CUBE_HIGH, CUBE_LOW, PLATE_UP_Z, SLOTS
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

FLAT = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def env():
    return tasks.make("take_plate")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(4))


def state(env, scene, pos, quat=FLAT):
    qpos = np.array(scene.qpos)
    a = env.plate_qadr
    qpos[a:a + 3], qpos[a + 3:a + 7] = pos, quat
    return hand_built(env, qpos, np.asarray(scene.mocap_pos), np.asarray(scene.mocap_quat))


def cube_top(scene, env):
    c = np.asarray(scene.mocap_pos[env.cube_mocap])
    return c + np.array([0.0, 0.0, CUBE])


@pytest.mark.parametrize(
    "offset, attached, expected",
    [
        ((0.0, 0.0, 0.004), None, True),  # lying on the cube, released
        ((0.0, 0.0, 0.004), 0, False),  # on the cube but still held
        ((0.03, -0.02, 0.004), None, True),  # off-centre but within 0.045 m
        ((0.06, 0.0, 0.004), None, False),  # too far off the cube's axis
        ((0.0, 0.0, 0.08), None, False),  # hovering well above the cube
        ((0.0, 0.0, -0.02), None, False),  # below the top face (beside/inside the cube)
    ],
)
def test_truth_table_on_cube(env, scene, offset, attached, expected):
    pos = cube_top(scene, env) + np.array(offset)
    ok, fail, _ = judge(env, scene, state(env, scene, pos), grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_plate_in_rack_or_on_table_is_not_success(env, scene):
    start = hand_built(env, np.array(scene.qpos), np.asarray(scene.mocap_pos), np.asarray(scene.mocap_quat))
    assert bool(env.in_rack(start))
    ok, _, _ = judge(env, scene, start, grasping(env, None))
    assert not ok
    on_table = cube_top(scene, env) + np.array([0.0, -0.15, -CUBE + 0.004])
    ok, _, _ = judge(env, scene, state(env, scene, on_table), grasping(env, None))
    assert not ok


def test_scene_sampling(env):
    keys = jax.vmap(jax.random.key)(np.arange(64))
    scenes = jax.vmap(env.sample_scene)(keys)
    slots = np.asarray(scenes.params["slot"])
    assert set(slots.tolist()) == {0, 1, 2}
    plate = np.asarray(scenes.qpos[:, env.plate_qadr:env.plate_qadr + 3])
    assert np.allclose(plate[:, 0], env.rack_pos[0] + SLOTS[slots]) and np.allclose(plate[:, 2], PLATE_UP_Z)
    # the invisible guard rails follow the plate's slot
    assert np.allclose(np.asarray(scenes.mocap_pos[:, env.guard_mocap, 0]), plate[:, 0])
    cube = np.asarray(scenes.mocap_pos[:, env.cube_mocap])
    assert np.all(cube[:, :2] >= CUBE_LOW) and np.all(cube[:, :2] <= CUBE_HIGH)


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("take_plate")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released at the end
