"""SS: cube in the region above the blade AND spatula grasped; rigid placement (the stop with it);
blade-table contact; the stop meets only the cube; expert."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.sim import placement
from readjax.tasks import scoop_with_spatula as ss
from readjax.tasks.scoop_with_spatula import BLADE_HALF, CUBE_HALF
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

LIFTED_BLADE = np.array([0.6, -0.1, 0.1])
ON_BLADE = BLADE_HALF[2] + CUBE_HALF + 0.001  # cube centre above the blade centre when resting on it


@pytest.fixture(scope="module")
def env():
    return tasks.make("scoop_with_spatula")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(1))


def state(env, scene, blade, cube_local, yaw=0.0):
    qpos = np.array(scene.qpos)
    quat = np.asarray(geo.yaw_quat(np.float32(yaw)))
    rot = np.asarray(geo.quat_to_mat(quat))
    s, c = env.spatula_qadr, env.cube_qadr
    qpos[s:s + 3], qpos[s + 3:s + 7] = blade, quat
    qpos[c:c + 3], qpos[c + 3:c + 7] = blade + rot @ np.asarray(cube_local), quat
    return hand_built(env, qpos)


@pytest.mark.parametrize(
    "blade, cube_local, yaw, attached, expected",
    [
        (LIFTED_BLADE, (0.0, 0.0, ON_BLADE), 0.0, 0, True),  # scooped and lifted, spatula held
        (LIFTED_BLADE, (0.0, 0.0, ON_BLADE), 0.0, None, False),  # spatula not grasped
        (LIFTED_BLADE, (0.03, -0.02, ON_BLADE), 1.2, 0, True),  # off-centre, turned spatula
        (LIFTED_BLADE, (0.0, 0.06, ON_BLADE), 1.2, 0, False),  # beside the blade
        (LIFTED_BLADE, (0.07, 0.0, ON_BLADE), 0.0, 0, False),  # past the tip
        (LIFTED_BLADE, (0.0, 0.0, 0.09), 0.0, 0, False),  # far above the blade (e.g. thrown)
        (LIFTED_BLADE, (0.0, 0.0, -0.03), 0.0, 0, False),  # under the blade
        # on the blade lying on the table, held: RLBench's two terms hold (it has no "lifted" term)
        (np.array([0.6, -0.1, BLADE_HALF[2]]), (0.0, 0.0, ON_BLADE), 0.0, 0, True),
    ],
)
def test_truth_table(env, scene, blade, cube_local, yaw, attached, expected):
    ok, fail, _ = judge(env, scene, state(env, scene, blade, cube_local, yaw), grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_start_state_is_not_success(env, scene):
    ok, fail, _ = judge(env, scene, hand_built(env, np.array(scene.qpos)), grasping(env, 0))
    assert not ok and not fail


def test_rigid_template_placed_with_full_yaw(env):
    scenes = jax.jit(jax.vmap(env.sample_scene))(jax.vmap(jax.random.key)(jnp.arange(32)))
    assert np.all(np.asarray(scenes.params["feasible"]))
    yaw = np.asarray(scenes.params["yaw"])
    sp = np.asarray(scenes.qpos[:, env.spatula_qadr:env.spatula_qadr + 7])
    cube = np.asarray(scenes.qpos[:, env.cube_qadr:env.cube_qadr + 7])
    stop = np.asarray(scenes.mocap_pos[:, env.stop_mocap])
    stop_quat = np.asarray(scenes.mocap_quat[:, env.stop_mocap])
    for i in range(len(yaw)):
        rot = np.asarray(placement.rot2(yaw[i]))
        # the cube and the stop keep their offsets and turn in the spatula's frame (one rigid model)
        np.testing.assert_allclose((cube[i, :2] - sp[i, :2]) @ rot, [ss.CUBE_X, 0.0], atol=1e-5)
        np.testing.assert_allclose(cube[i, 3:], sp[i, 3:], atol=1e-6)
        np.testing.assert_allclose((stop[i, :2] - sp[i, :2]) @ rot, [ss.STOP_X, 0.0], atol=1e-5)
        np.testing.assert_allclose(stop_quat[i], sp[i, 3:], atol=1e-6)
        lo, hi = placement.turned_extent(ss.FOOTPRINT_MIN, ss.FOOTPRINT_MAX, yaw[i])
        assert np.all(sp[i, :2] + np.asarray(lo) >= placement.WORKSPACE_LOW - 1e-5)
        assert np.all(sp[i, :2] + np.asarray(hi) <= placement.WORKSPACE_HIGH + 1e-5)
    assert np.allclose(cube[:, 2], CUBE_HALF) and np.allclose(sp[:, 2], BLADE_HALF[2])
    # the whole turn is drawn: the spatula points every way (towards the robot too)
    assert np.ptp(np.cos(yaw)) > 1.5 and np.ptp(np.sin(yaw)) > 1.5


def test_blade_rests_on_the_table(env, scene):
    """The blade collides with the table: the spatula at rest stays on it, not in it."""
    m = env.mj_model
    d = mujoco.MjData(m)
    d.qpos[:] = np.asarray(scene.qpos)
    blade = m.geom("blade").id
    for _ in range(200):
        mujoco.mj_step(m, d)
    local = np.array([[sx, sy, -1] for sx in (-1, 1) for sy in (-1, 1)]) * BLADE_HALF
    corners = d.geom_xpos[blade] + local @ d.geom_xmat[blade].reshape(3, 3).T
    assert corners[:, 2].min() > -0.001
    table = m.geom("table_col").id
    touching = {frozenset((c.geom1, c.geom2)) for c in d.contact[:d.ncon]}
    assert frozenset((blade, table)) in touching


def test_the_stop_meets_only_the_cube_just_beyond_it(env):
    """The stop holds the cube while the blade slides under it: its near face a few mm beyond the
    cube's far face, as tall as the cube, touching nothing else (the blade's edge may end under it)."""
    m = env.mj_model
    stop = m.geom("stop")
    assert stop.contype[0] == 0 and stop.conaffinity[0] == 0
    pairs = {frozenset((int(a), int(b))) for a, b in zip(m.pair_geom1, m.pair_geom2)}
    assert frozenset((stop.id, m.geom("cube").id)) in pairs
    assert sum(stop.id in p for p in pairs) == 1
    near_face = ss.STOP_X - stop.size[0]
    assert 0.0 < near_face - (ss.CUBE_X + CUBE_HALF) <= 0.005
    assert stop.size[0] == pytest.approx(ss.STOP_HALF_X)
    assert stop.pos[2] - stop.size[2] == pytest.approx(0.0) and stop.size[2] >= CUBE_HALF


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("scoop_with_spatula")
    assert ok.all()
    assert trace.attached[:, -1, 0].all()  # still holding the spatula
