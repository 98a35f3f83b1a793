"""WP: the drop model (5 drops while tilted; all must land in the pot) and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.tasks.water_plants import DROPS, TIP, rot_y
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("water_plants")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(3))


def can_at(env, scene, tip, heading, tilt):
    """Hand-built data: the can turned to ``heading``, tilted ``tilt`` spout-down, spout tip at ``tip``."""
    rot = np.asarray(geo.rot_z(jnp.float32(heading)) @ rot_y(jnp.float32(tilt)))
    qpos = np.array(scene.qpos)
    a = env.can_qadr
    qpos[a:a + 3] = np.asarray(tip) - rot @ TIP
    qpos[a + 3:a + 7] = np.asarray(geo.mat_to_quat(jnp.asarray(rot)))
    data = hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)
    np.testing.assert_allclose(np.asarray(data.site_xpos[env.tip_site]), tip, atol=1e-5)
    return data


def pour(env, scene, states, attached=0):
    """Judge a sequence of states, carrying the progress; returns the (success, failure) after each."""
    progress, out = None, []
    for data in states:
        ok, fail, progress = judge(env, scene, data, grasping(env, attached), progress)
        out.append((ok, fail))
    return out, progress


def over_pot(scene, dz=0.12, dx=0.0):
    return np.asarray(scene.params["pot"]) + np.array([dx, 0.0, 0.10 + dz])


def test_start_state(env, scene):
    data = hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat)
    (res,), progress = pour(env, scene, [data], attached=None)
    assert res == (False, False) and int(progress["released"]) == 0


def test_five_drops_over_the_pot_succeed(env, scene):
    data = can_at(env, scene, over_pot(scene), heading=0.3, tilt=np.deg2rad(50))
    res, progress = pour(env, scene, [data] * (DROPS + 2))
    assert res[:DROPS - 1] == [(False, False)] * (DROPS - 1)  # not before the 5th drop
    assert res[DROPS - 1:] == [(True, False)] * 3
    assert int(progress["released"]) == DROPS and int(progress["landed"]) == DROPS


def test_upright_over_the_pot_pours_nothing(env, scene):
    data = can_at(env, scene, over_pot(scene), heading=0.3, tilt=0.0)
    res, progress = pour(env, scene, [data] * 8)
    assert res[-1] == (False, False) and int(progress["released"]) == 0


def test_slight_or_backward_tilt_pours_nothing(env, scene):
    tilts = (np.deg2rad(20), -np.deg2rad(50))
    states = [can_at(env, scene, over_pot(scene), heading=0.3, tilt=t) for t in tilts]
    res, progress = pour(env, scene, states * 4)
    assert res[-1] == (False, False) and int(progress["released"]) == 0


def test_pouring_beside_the_pot_is_a_failure(env, scene):
    data = can_at(env, scene, over_pot(scene, dx=0.09), heading=0.3, tilt=np.deg2rad(50))
    res, progress = pour(env, scene, [data] * DROPS)
    assert res[-1] == (False, True) and int(progress["landed"]) == 0


def test_spilling_some_drops_is_a_failure(env, scene):
    good = can_at(env, scene, over_pot(scene), heading=0.3, tilt=np.deg2rad(50))
    bad = can_at(env, scene, over_pot(scene, dx=-0.08), heading=0.3, tilt=np.deg2rad(50))
    res, progress = pour(env, scene, [good, good, good, bad, good, good])
    assert res[-1] == (False, True) and int(progress["landed"]) == DROPS - 1


def test_too_high_above_the_pot_spills(env, scene):
    data = can_at(env, scene, over_pot(scene, dz=0.35), heading=0.3, tilt=np.deg2rad(50))
    res, _ = pour(env, scene, [data] * DROPS)
    assert res[-1] == (False, True)


def test_expert_succeeds(env):
    _, ok, _, _ = expert_run("water_plants")
    assert ok.sum() >= len(ok) - 1
