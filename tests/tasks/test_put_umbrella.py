"""PU: truth table (umbrella in the lower half of the stand, released), the rigid placement, expert."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.sim import placement
from readjax.tasks import put_umbrella as pu
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


def upright(tilt=0.0):
    """Umbrella orientation with the handle up (tip down), leaning by ``tilt`` about world y."""
    r = np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])
    c, s = np.cos(tilt), np.sin(tilt)
    lean = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.asarray(geo.mat_to_quat(jnp.asarray(lean @ r, jnp.float32)))


@pytest.fixture(scope="module")
def env():
    return tasks.make("put_umbrella")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(11))


def umbrella_tip_at(env, scene, tip, quat):
    qpos = np.array(scene.qpos)
    a = env.umbrella_qadr
    rot = np.asarray(geo.quat_to_mat(jnp.asarray(quat)))
    qpos[a:a + 3] = np.asarray(tip) - rot @ np.array([pu.TIP_X, 0.0, 0.0])
    qpos[a + 3:a + 7] = quat
    data = hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)
    np.testing.assert_allclose(np.asarray(env.tip(data)), tip, atol=1e-5)
    return data


@pytest.mark.parametrize(
    "offset, tilt, attached, expected",
    [
        ((0.0, 0.0, 0.01), 0.0, None, True),  # standing in the stand, let go
        ((0.04, 0.0, 0.01), 0.25, None, True),  # leaning on a wall, tip off centre
        ((0.0, 0.0, 0.10), 0.0, None, True),  # tip just inside the sensor (lower half)
        ((0.0, 0.0, 0.01), 0.0, 0, False),  # in the stand but still held
        ((0.0, 0.0, 0.13), 0.0, None, False),  # tip past the rim but above the sensor (upper half)
        ((0.0, 0.0, 0.25), 0.0, None, False),  # above the rim
        ((0.09, 0.0, 0.01), 0.0, None, False),  # beside the stand
    ],
)
def test_truth_table(env, scene, offset, tilt, attached, expected):
    # offsets in the stand's own frame (the task's yaw turns the stand)
    rot = np.asarray(geo.rot_z(scene.params["yaw"]))
    tip = np.asarray(scene.params["stand"]) + rot @ np.asarray(offset)
    data = umbrella_tip_at(env, scene, tip, upright(tilt))
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_rigid_template_placed_with_full_yaw(env):
    scenes = jax.jit(jax.vmap(env.sample_scene))(jax.vmap(jax.random.key)(jnp.arange(32)))
    yaw = np.asarray(scenes.params["yaw"])
    assert np.all(np.asarray(scenes.params["feasible"]))
    crate = np.asarray(scenes.mocap_pos[:, env.crate_mocap])
    stand = np.asarray(scenes.mocap_pos[:, env.stand_mocap])
    origin = np.asarray(scenes.qpos[:, env.umbrella_qadr:env.umbrella_qadr + 3])
    for i in range(len(yaw)):
        rot = np.asarray(placement.rot2(yaw[i]))
        # crate, umbrella and stand keep their offsets in the task frame (one rigid model)
        np.testing.assert_allclose((stand[i, :2] - crate[i, :2]) @ rot, pu.STAND_XY, atol=1e-5)
        np.testing.assert_allclose((origin[i, :2] - crate[i, :2]) @ rot, [pu.GRASP_X, 0.0], atol=1e-5)
        # the turned footprint lies in the workspace
        lo, hi = placement.turned_extent(pu.FOOTPRINT_MIN, pu.FOOTPRINT_MAX, yaw[i])
        assert np.all(crate[i, :2] + np.asarray(lo) >= placement.WORKSPACE_LOW - 1e-5)
        assert np.all(crate[i, :2] + np.asarray(hi) <= placement.WORKSPACE_HIGH + 1e-5)
        # nothing starts detected: the umbrella lies on the crate
        data = hand_built(env, np.asarray(scenes.qpos[i]), scenes.mocap_pos[i], scenes.mocap_quat[i])
        scene_i = jax.tree.map(lambda x: x[i], scenes)
        assert judge(env, scene_i, data, grasping(env, None))[:2] == (False, False)
    # the task turns both ways (the long model fits the workspace only near +-pi/2 and 0, pi)
    assert yaw.min() < -1.0 and yaw.max() > 1.0


def test_umbrella_sizes():
    assert -pu.TIP_X + 0.05 >= 0.5  # a real (child's) stick umbrella, handle end to tip
    assert pu.REGION_CENTRE[2] + pu.REGION_HALF[2] <= pu.RIM / 2 + 1e-6  # the sensor: lower half


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("put_umbrella")
    assert ok.all()
    assert np.all(trace.grip[:, -1] > 0.9)  # let go
    assert not trace.attached[:, -1].any()
