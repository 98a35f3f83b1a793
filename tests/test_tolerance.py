"""The tolerance replay's perturbation: a known shift and turn of every waypoint, per episode a
function of its seed alone (the replay through MJX is tested on a real split in tests/data)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.lab import tolerance
from readjax import motion as motion_lib
from readjax.sim.camera import camera_from_model


@pytest.fixture(scope="module")
def cam():
    return camera_from_model(tasks.make("reach_target").mj_model, "front", 64, 64)


def _motions(cam, n=5, seed=0):
    """Plausible motions: a path in front of the robot, orientations turning, the gripper closing."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, motion_lib.FRAMES)[None, :, None]
    start, end = rng.uniform([0.3, -0.3, 0.1], [0.6, 0.3, 0.4], (2, n, 1, 3))
    pos = start + t * (end - start)
    yaw = rng.uniform(-1, 1, (n, 1)) * np.linspace(0, 1, motion_lib.FRAMES)
    rot = geo.quat_to_mat(geo.quat_mul(geo.yaw_quat(jnp.asarray(yaw)), jnp.array([0.0, 1.0, 0.0, 0.0])))
    grip = (t[..., 0] < 0.5).astype(np.float32) * np.ones((n, 1))
    return np.asarray(motion_lib.encode(cam, jnp.asarray(pos, jnp.float32), rot, jnp.asarray(grip)), np.float32)


def test_no_error_is_the_identity(cam):
    m = _motions(cam)
    np.testing.assert_allclose(tolerance.perturb(cam, m, np.arange(5)), m, atol=2e-5)


def test_every_waypoint_moves_by_the_shift_and_turns_by_the_angle(cam):
    m, seeds = _motions(cam), np.arange(100, 105)
    pos, rot, grip = motion_lib.decode(cam, jnp.asarray(m))
    p2, r2, g2 = motion_lib.decode(cam, jnp.asarray(tolerance.perturb(cam, m, seeds, shift_m=0.02)))
    d = np.asarray(p2 - pos)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 0.02, atol=2e-5)
    np.testing.assert_allclose(d, d[:, :1].repeat(d.shape[1], 1), atol=2e-5)  # one direction per episode
    np.testing.assert_allclose(np.asarray(r2), np.asarray(rot), atol=2e-5)
    np.testing.assert_array_equal(np.asarray(g2), np.asarray(grip))
    p3, r3, _ = motion_lib.decode(cam, jnp.asarray(tolerance.perturb(cam, m, seeds, turn_deg=10.0)))
    np.testing.assert_allclose(np.rad2deg(np.asarray(geo.rotation_angle(r3, rot))), 10.0, atol=1e-2)
    np.testing.assert_allclose(np.asarray(p3), np.asarray(pos), atol=2e-5)  # turned about the tool point


def test_an_episodes_error_is_a_function_of_its_seed_alone(cam):
    m, seeds = _motions(cam, n=6), np.array([7, 3, 9, 1, 4, 8])
    together = tolerance.perturb(cam, m, seeds, shift_m=0.03, turn_deg=5.0)
    alone = tolerance.perturb(cam, m[[4]], seeds[[4]], shift_m=0.03, turn_deg=5.0)
    np.testing.assert_allclose(alone[0], together[4], atol=1e-6)
    directions = {tuple(np.round(tolerance.unit_vector(s, 0), 6)) for s in seeds}
    assert len(directions) == len(seeds)  # different seeds, different directions
    assert not np.allclose(tolerance.unit_vector(3, 0), tolerance.unit_vector(3, 1))  # shift and turn apart
