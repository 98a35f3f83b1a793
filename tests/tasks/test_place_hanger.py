"""PH: truth table (hook on the rail, released), holder placement (whole workspace, yaw +-pi, clear
of the fixed rack), the expert's turn choice, and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import placement
from readjax.tasks.place_hanger import HOLDER_MAX, HOLDER_MIN, PEG_Z, RACK_MAX, RACK_MIN, RAIL, choose_turn
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("place_hanger")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(4))


@pytest.fixture(scope="module")
def scenes(env):
    keys = jax.vmap(jax.random.key)(jnp.arange(48, dtype=jnp.int32))
    return jax.tree.map(np.asarray, jax.jit(jax.vmap(env.sample_scene))(keys))


def hanger_at(env, scene, hook, yaw=0.0):
    """Hand-built data with the hanger's hook opening centre at ``hook`` (its plane across x at yaw 0)."""
    qpos = np.array(scene.qpos)
    a = env.hanger_qadr
    qpos[a:a + 3] = hook
    qpos[a + 3:a + 7] = [np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


@pytest.mark.parametrize(
    "offset, yaw, attached, expected",
    [
        ((0.0, 0.0, 0.0), 0.0, None, True),  # hanging on the rail, released
        ((0.0, 0.0, 0.0), np.pi, None, True),  # hung the other way round
        ((0.08, 0.0, 0.003), 0.0, None, True),  # further along the rail
        ((0.0, 0.0, 0.0), 0.0, 0, False),  # on the rail but still held
        ((0.0, 0.0, 0.05), 0.0, None, False),  # above the rail (hook not over it)
        ((0.0, 0.05, 0.0), 0.0, None, False),  # beside the rail
        ((0.14, 0.0, 0.0), 0.0, None, False),  # past the end of the hook region
        ((0.0, 0.0, -0.2), 0.0, None, False),  # fallen below the rail
    ],
)
def test_truth_table(env, scene, offset, yaw, attached, expected):
    data = hanger_at(env, scene, RAIL + np.asarray(offset), yaw)
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_start_on_holder_is_not_success(env, scenes):
    for i in range(8):
        s = jax.tree.map(lambda x: x[i], scenes)
        data = hand_built(env, np.array(s.qpos), s.mocap_pos, s.mocap_quat)
        assert judge(env, s, data, grasping(env, None))[:2] == (False, False)


def test_holder_over_workspace_full_yaw_rack_fixed(env, scenes):
    assert scenes.params["feasible"].mean() > 0.9
    holders = scenes.mocap_pos[:, env.holder_mocap]
    yaw = scenes.params["yaw"]
    assert np.ptp(holders[:, 0]) > 0.25 and np.ptp(holders[:, 1]) > 0.25  # spread over the workspace
    assert yaw.min() < -2.5 and yaw.max() > 2.5  # RLBench's default +-3.14, not +-pi/6
    for h, a in zip(holders, yaw):
        lo, hi = (np.asarray(v) for v in placement.turned_extent(HOLDER_MIN, HOLDER_MAX, a))
        assert np.all(h[:2] + lo >= placement.WORKSPACE_LOW - 1e-6)
        assert np.all(h[:2] + hi <= placement.WORKSPACE_HIGH + 1e-6)
        assert np.any(h[:2] + hi < RACK_MIN) or np.any(h[:2] + lo > RACK_MAX)  # clear of the rack
    m = env.mj_model
    assert m.geom_bodyid[m.geom("rail").id] == 0  # the rack is part of the static world
    # the hanger hangs on the peg: its hook opening centre at the peg's height, above the holder, same yaw
    hook = scenes.qpos[:, env.hanger_qadr:env.hanger_qadr + 3]
    np.testing.assert_allclose(hook[:, :2], holders[:, :2], atol=1e-6)
    np.testing.assert_allclose(hook[:, 2], PEG_Z, atol=1e-3)
    np.testing.assert_allclose(scenes.qpos[:, env.hanger_qadr + 3:env.hanger_qadr + 7],
                               scenes.mocap_quat[:, env.holder_mocap], atol=1e-6)


@pytest.mark.parametrize("theta", np.linspace(-np.pi, np.pi, 13))
def test_turn_keeps_joint7_in_range(theta):
    """Whatever the hanger's yaw, the chosen pick yaw is across the hanger's plane, the turn ends
    across the rail, and joint 7's estimate stays well inside +-2.9 at both ends."""
    pick, hang = np.array([0.5, 0.2]), RAIL[:2] + [0, 0.07]
    psi, delta = (float(v) for v in choose_turn(jnp.float32(theta), jnp.asarray(pick), jnp.asarray(hang)))
    assert abs(np.cos(psi - theta)) < 1e-4  # fingers along the hanger's normal
    assert abs(np.cos(psi + delta)) < 1e-4  # fingers along the rail at the hang
    assert abs(delta) <= 2.8
    for xy, yaw in ((pick, psi), (hang, psi + delta)):
        assert abs(0.785 + np.arctan2(xy[1], xy[0]) - yaw) < 2.5


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("place_hanger")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released
