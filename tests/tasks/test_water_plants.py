"""WP: RLBench's drop model (the spout tip entering the pour point once releases 5 drops; success = all
5 land in the soil; before that, the can in the success sensor), the rigid can + plant placement with
yaw +-pi, and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.sim import placement
from readjax.tasks.water_plants import (CAN, DROP_OFFSETS, DROPS, FOOT_MAX, FOOT_MIN, PLANT, POUR_R, POUR_Z,
                                        SENSOR_Z, SOIL_R, TIP, rot_y)
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("water_plants")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(3))


def can_at(env, scene, tip, tilt=0.0, heading=None):
    """Hand-built data: the can turned to ``heading`` (default: the scene's yaw, facing the plant),
    tilted ``tilt`` spout-down, spout tip at ``tip`` (world)."""
    heading = float(scene.params["yaw"]) if heading is None else heading
    rot = np.asarray(geo.rot_z(jnp.float32(heading)) @ rot_y(jnp.float32(tilt)))
    qpos = np.array(scene.qpos)
    a = env.can_qadr
    qpos[a:a + 3] = np.asarray(tip) - rot @ TIP
    qpos[a + 3:a + 7] = np.asarray(geo.mat_to_quat(jnp.asarray(rot)))
    data = hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)
    np.testing.assert_allclose(np.asarray(data.site_xpos[env.tip_site]), tip, atol=1e-5)
    return data


def can_origin_at(env, scene, origin):
    qpos = np.array(scene.qpos)
    qpos[env.can_qadr:env.can_qadr + 3] = origin
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


def pour(env, scene, states, attached=0):
    """Judge a sequence of states, carrying the progress; returns the (success, failure) after each."""
    progress, out = None, []
    for data in states:
        ok, fail, progress = judge(env, scene, data, grasping(env, attached), progress)
        out.append((ok, fail))
    return out, progress


def above_pot(scene, z=0.2, dx=0.0, dy=0.0):
    return np.asarray(scene.params["pot"]) + np.array([dx, dy, z])


def test_start_state(env, scene):
    data = hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat)
    (res,), progress = pour(env, scene, [data], attached=None)
    assert res == (False, False) and not bool(progress["released"])


@pytest.mark.parametrize("tilt", [0.0, np.deg2rad(40), -np.deg2rad(20)])
def test_tip_in_pour_point_releases_five_drops_that_land(env, scene, tilt):
    """No tilt term: upright, tilted or tilted back, the tip in the pour point is enough."""
    data = can_at(env, scene, above_pot(scene, dx=0.02), tilt)
    (res,), progress = pour(env, scene, [data])
    assert res == (True, False) and bool(progress["released"]) and int(progress["landed"]) == DROPS


@pytest.mark.parametrize("tip", [
    dict(z=0.35),  # above the pour point
    dict(z=0.11),  # below it (at the rim)
    dict(z=0.2, dx=POUR_R + 0.005),  # beside it, still over the soil
    dict(z=0.2, dx=0.12),  # beside the pot
])
def test_tip_outside_the_pour_point_releases_nothing(env, scene, tip):
    res, progress = pour(env, scene, [can_at(env, scene, above_pot(scene, **tip))] * 3)
    assert res[-1] == (False, False) and not bool(progress["released"])


def test_drops_are_released_once_and_success_latches(env, scene):
    inside = can_at(env, scene, above_pot(scene, dy=-0.03))
    away = can_at(env, scene, above_pot(scene, z=0.3, dx=0.15))
    res, progress = pour(env, scene, [away, inside, away, inside, away])
    assert res == [(False, False)] + [(True, False)] * 4
    assert int(progress["landed"]) == DROPS


def test_every_drop_released_in_the_pour_point_is_over_the_soil():
    assert POUR_R + np.abs(DROP_OFFSETS).max() < SOIL_R and len(DROP_OFFSETS) == DROPS
    assert POUR_Z[0] > 0.10  # above the rim


def test_sensor_sites_match_the_predicate(env):
    m = env.mj_model
    for name, radius, (z0, z1) in (("pour_point", POUR_R, POUR_Z), ("success_sensor", SOIL_R, SENSOR_Z)):
        site = m.site(name)
        assert m.site_bodyid[site.id] == m.body("plant").id
        np.testing.assert_allclose(site.size[:2], [radius, (z1 - z0) / 2], atol=1e-6)
        np.testing.assert_allclose(site.pos, [0.0, 0.0, (z0 + z1) / 2], atol=1e-6)


def test_can_in_success_sensor_before_the_release(env, scene):
    """RLBench's first success condition (waterer detected by the success sensor), met only until the
    drops are released; the pot's collision keeps a real can out of the sensor."""
    pot = np.asarray(scene.params["pot"])
    (res,), _ = pour(env, scene, [can_origin_at(env, scene, pot + [0.0, 0.0, 0.07])])
    assert res == (True, False)
    (res,), _ = pour(env, scene, [can_origin_at(env, scene, pot + [0.0, 0.0, 0.10])])  # on the rim
    assert res == (False, False)


def test_placement_is_rigid_with_full_yaw(env):
    keys = jax.vmap(lambda i: jax.random.fold_in(jax.random.key(0), i))(jnp.arange(256))
    s = jax.jit(jax.vmap(env.draw_scene))(keys)
    fits = np.asarray(s.params["fits"])
    assert fits.mean() > 0.99
    yaw = np.asarray(s.params["yaw"])
    assert np.histogram(yaw, 4, (-np.pi, np.pi))[0].min() > 40
    can, pot = np.asarray(s.params["can"]), np.asarray(s.mocap_pos[:, env.plant_mocap])
    np.testing.assert_allclose(np.linalg.norm(pot[:, :2] - can[:, :2], axis=-1), PLANT[0] - CAN[0], atol=1e-5)
    heading = np.arctan2(pot[:, 1] - can[:, 1], pot[:, 0] - can[:, 0])
    np.testing.assert_allclose(np.cos(heading - yaw), 1.0, atol=1e-5)  # the can faces the plant
    origin = (can[:, :2] + pot[:, :2]) / 2 - ((CAN[0] + PLANT[0]) / 2) * np.stack([np.cos(yaw), np.sin(yaw)], -1)
    c, sn = np.cos(yaw), np.sin(yaw)
    for cx in (FOOT_MIN[0], FOOT_MAX[0]):
        for cy in (FOOT_MIN[1], FOOT_MAX[1]):
            w = origin + np.stack([c * cx - sn * cy, sn * cx + c * cy], -1)
            assert np.all((w[fits] >= placement.WORKSPACE_LOW - 1e-5) & (w[fits] <= placement.WORKSPACE_HIGH + 1e-5))


def test_expert_succeeds(env):
    scenes, ok, _, _ = expert_run("water_plants")
    assert scenes.params["feasible"].all() and ok.sum() >= len(ok) - 1
