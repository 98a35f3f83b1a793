"""PH: truth table (hook on the rail, released) and expert success; the rack never moves."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.place_hanger import PEG_Z, RAIL
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("place_hanger")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(4))


def hanger_at(env, scene, hook, yaw=0.0):
    """Hand-built data with the hanger's hook opening centre at ``hook`` (its plane across x at yaw 0)."""
    qpos = np.array(scene.qpos)
    a = env.hanger_qadr
    qpos[a:a + 3] = hook
    qpos[a + 3:a + 7] = [np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


@pytest.mark.parametrize(
    "offset, attached, expected",
    [
        ((0.0, 0.0, 0.0), None, True),  # hanging on the rail, released
        ((0.08, 0.0, 0.003), None, True),  # further along the rail
        ((0.0, 0.0, 0.0), 0, False),  # on the rail but still held
        ((0.0, 0.0, 0.05), None, False),  # above the rail (hook not over it)
        ((0.0, 0.05, 0.0), None, False),  # beside the rail
        ((0.14, 0.0, 0.0), None, False),  # past the end of the hook region
        ((0.0, 0.0, -0.2), None, False),  # fallen below the rail
    ],
)
def test_truth_table(env, scene, offset, attached, expected):
    data = hanger_at(env, scene, RAIL + np.asarray(offset))
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_start_on_holder_is_not_success(env):
    for seed in range(8):
        scene = env.sample_scene(jax.random.key(seed))
        data = hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat)
        assert judge(env, scene, data, grasping(env, None))[:2] == (False, False)


def test_holder_random_rack_fixed(env):
    scenes = [env.sample_scene(jax.random.key(s)) for s in range(6)]
    holders = np.array([np.asarray(s.mocap_pos[env.holder_mocap]) for s in scenes])
    assert np.ptp(holders[:, :2], axis=0).min() > 0.02  # the holder moves between episodes
    m = env.mj_model
    rail = m.geom("rail")
    assert m.geom_bodyid[rail.id] == 0  # the rack is part of the static world
    # the hanger hangs on the peg: its hook opening centre at the peg's height, above the holder
    for s in scenes:
        hook = np.asarray(s.qpos[env.hanger_qadr:env.hanger_qadr + 3])
        holder = np.asarray(s.mocap_pos[env.holder_mocap])
        np.testing.assert_allclose(hook[:2], holder[:2], atol=1e-6)
        assert hook[2] == pytest.approx(PEG_Z, abs=1e-3)


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("place_hanger")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released
