"""TP: plate out of the rack AND on the blue cube AND released; the rack, its sensor, the guard rails
and the cube placed together as one rigid task model (yaw +-pi); the slot variation; the expert."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import placement
from readjax.tasks.take_plate import (CUBE, CUBE_LOCAL, FOOTPRINT_MAX, FOOTPRINT_MIN, PLATE_UP_Z, RACK_LOCAL,
                                      SLOTS)
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

FLAT = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def env():
    return tasks.make("take_plate")


@pytest.fixture(scope="module")
def scenes(env):
    keys = jax.vmap(jax.random.key)(jnp.arange(48, dtype=jnp.int32))
    return jax.tree.map(np.asarray, jax.jit(jax.vmap(env.sample_scene))(keys))


@pytest.fixture(scope="module")
def scene(scenes):
    return jax.tree.map(lambda x: x[4], scenes)


def rot2(yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def state(env, scene, pos, quat=FLAT):
    qpos = np.array(scene.qpos)
    a = env.plate_qadr
    qpos[a:a + 3], qpos[a + 3:a + 7] = pos, quat
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


def cube_top(scene, env):
    return scene.mocap_pos[env.cube_mocap] + np.array([0.0, 0.0, CUBE])


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
    start = hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat)
    assert bool(env.in_rack(start))
    ok, _, _ = judge(env, scene, start, grasping(env, None))
    assert not ok
    on_table = cube_top(scene, env) + np.array([0.0, 0.0, -CUBE + 0.004])
    on_table[:2] += rot2(float(scene.params["yaw"])) @ np.array([0.0, 0.15])  # beside the cube, off the rack
    ok, _, _ = judge(env, scene, state(env, scene, on_table), grasping(env, None))
    assert not ok


def test_rack_sensor_turns_with_the_rack(env, scene):
    """success_source is the rack's volume in the rack's frame: a point 9 cm along the rack's y from
    its centre is inside (the rack is 0.2 m along y), the same distance along its x is not (0.16 m)."""
    yaw = float(scene.params["yaw"])
    rack = scene.mocap_pos[env.rack_mocap]
    for local, inside in (((0.0, 0.09), True), ((0.09, 0.0), False)):
        p = rack + np.concatenate([rot2(yaw) @ np.array(local), [0.1]])
        assert bool(env.in_rack(state(env, scene, p))) == inside


def test_rigid_task_model(env, scenes):
    """Rack, cube, guard rails and plate keep their relative layout, turned by the task yaw (+-pi)."""
    p = scenes.params
    assert p["feasible"].mean() > 0.9
    yaw = p["yaw"]
    assert yaw.min() < -2.5 and yaw.max() > 2.5
    assert set(p["slot"].tolist()) == {0, 1, 2}  # all 3 variations in one split
    for i in range(len(yaw)):
        r = rot2(yaw[i])
        origin = scenes.mocap_pos[i, env.rack_mocap, :2] - r @ RACK_LOCAL
        np.testing.assert_allclose(scenes.mocap_pos[i, env.cube_mocap, :2], origin + r @ CUBE_LOCAL, atol=1e-5)
        slot = origin + r @ (RACK_LOCAL + np.array([SLOTS[p["slot"][i]], 0.0]))
        plate = scenes.qpos[i, env.plate_qadr:env.plate_qadr + 3]
        np.testing.assert_allclose(plate[:2], slot, atol=1e-5)
        assert plate[2] == pytest.approx(PLATE_UP_Z)
        np.testing.assert_allclose(scenes.mocap_pos[i, env.guard_mocap, :2], slot, atol=1e-5)
        q = [np.cos(yaw[i] / 2), 0, 0, np.sin(yaw[i] / 2)]
        for body in (env.rack_mocap, env.cube_mocap, env.guard_mocap):
            np.testing.assert_allclose(scenes.mocap_quat[i, body], q, atol=1e-5)
        lo, hi = (np.asarray(v) for v in placement.turned_extent(FOOTPRINT_MIN, FOOTPRINT_MAX, yaw[i]))
        assert np.all(origin + lo >= placement.WORKSPACE_LOW - 1e-5) and np.all(origin + hi <= placement.WORKSPACE_HIGH + 1e-5)


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("take_plate")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released at the end
