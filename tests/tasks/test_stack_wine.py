"""SW: slot-region truth table (target slot, other slots, upright, shifted; in the turned rack's frame),
RLBench's rigid placement (yaw +-pi/4), expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.sim import placement
from readjax.tasks.stack_wine import BOTTLE, CENTRE, FOOT_MAX, FOOT_MIN, SLOT
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

# a bottle lying along the rack's y axis (turned 90 degrees about the rack's x), base towards +y
LYING = np.asarray(geo.axis_angle_to_quat(jnp.array([1.0, 0.0, 0.0]), jnp.pi / 2))


@pytest.fixture(scope="module")
def env():
    return tasks.make("stack_wine")


@pytest.fixture(scope="module", params=[6, 11])
def scene(env, request):
    return env.sample_scene(jax.random.key(request.param))


def _bottle_at(env, scene, centre=None, lying=True):
    """State with the bottle's body centre at ``centre`` (rack frame); None: where it was placed."""
    qpos = np.array(scene.qpos)
    if centre is not None:
        yaw = scene.params["yaw"]
        world = np.asarray(placement.to_world(scene.params["rack"][:2], yaw, jnp.asarray(centre)))
        local = LYING if lying else np.array([1.0, 0, 0, 0])
        quat = np.asarray(geo.quat_mul(geo.yaw_quat(yaw), jnp.asarray(local)))
        rot = np.asarray(geo.quat_to_mat(jnp.asarray(quat)))
        qpos[env.bottle_qadr:env.bottle_qadr + 3] = world - rot @ np.array([0.0, 0.0, CENTRE])
        qpos[env.bottle_qadr + 3:env.bottle_qadr + 7] = quat
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


@pytest.mark.parametrize(
    "centre, lying, attached, expected",
    [
        (None, True, None, False),  # standing where it was placed
        (SLOT, True, None, True),  # lying in the target slot
        (SLOT, True, 0, True),  # still held there (RLBench does not require a release)
        (SLOT + [0.0, 0.04, 0.0], True, None, True),  # a bit along the slot
        (SLOT + [0.0, -0.04, 0.0], True, None, True),  # a bit along the slot, the other way
        (SLOT + [0.0, 0.08, 0.0], True, None, False),  # too far along the slot
        (SLOT + [0.1, 0.0, 0.0], True, None, False),  # lying in the middle slot
        (SLOT + [0.2, 0.0, 0.0], True, None, False),  # lying in the far slot
        (SLOT + [0.0, 0.0, 0.06], True, 0, False),  # held above the slot
        ((SLOT[0], SLOT[1], CENTRE), False, None, False),  # standing upright on the slot
    ],
)
def test_truth_table(env, scene, centre, lying, attached, expected):
    centre = None if centre is None else np.asarray(centre, np.float32)
    ok, fail, _ = judge(env, scene, _bottle_at(env, scene, centre, lying), grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_centre_site_is_the_body_middle(env, scene):
    data = _bottle_at(env, scene)
    b = np.asarray(scene.params["bottle"])
    assert np.allclose(np.asarray(data.site_xpos[env.centre_site]), b + [0, 0, CENTRE], atol=1e-5)


def test_placement_is_rlbench_rigid_placement(env):
    """Rack and bottle move as one model, turned by a yaw in [-pi/4, pi/4], its footprint in the
    workspace."""
    keys = jax.vmap(lambda i: jax.random.fold_in(jax.random.key(0), i))(jnp.arange(256))
    s = jax.jit(jax.vmap(env.draw_scene))(keys)
    fits = np.asarray(s.params["fits"])
    assert fits.mean() > 0.99
    yaw, rack = np.asarray(s.params["yaw"]), np.asarray(s.params["rack"])
    assert np.all(np.abs(yaw) <= np.pi / 4 + 1e-6) and yaw.min() < -0.7 and yaw.max() > 0.7
    np.testing.assert_allclose(np.asarray(s.mocap_pos[:, env.rack_mocap]), rack, atol=1e-6)
    c, sn = np.cos(yaw)[:, None], np.sin(yaw)[:, None]

    def world(p):
        return rack[:, :2] + np.concatenate([c * p[0] - sn * p[1], sn * p[0] + c * p[1]], -1)

    bottle = np.asarray(s.qpos[:, env.bottle_qadr:env.bottle_qadr + 3])
    np.testing.assert_allclose(bottle[:, :2], world(BOTTLE), atol=1e-5)
    for corner in ((FOOT_MIN[0], FOOT_MIN[1]), (FOOT_MIN[0], FOOT_MAX[1]), (FOOT_MAX[0], FOOT_MIN[1]),
                   (FOOT_MAX[0], FOOT_MAX[1])):
        w = world(np.asarray(corner))[fits]
        assert np.all((w >= placement.WORKSPACE_LOW - 1e-5) & (w <= placement.WORKSPACE_HIGH + 1e-5))


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("stack_wine")
    assert scenes.params["feasible"].all() and ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # the bottle was let go
