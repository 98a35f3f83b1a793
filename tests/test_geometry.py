"""Rotations: quaternion/matrix conversions, 6D rotations, slerp."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial.transform import Rotation

from readjax import geometry as geo


def _random_rotations(n, seed=0):
    return Rotation.random(n, random_state=seed)


def test_quat_mat_round_trip_and_scipy_agreement():
    r = _random_rotations(200)
    q = r.as_quat(scalar_first=True).astype(np.float32)
    m = np.asarray(geo.quat_to_mat(jnp.asarray(q)))
    np.testing.assert_allclose(m, r.as_matrix(), atol=1e-5)
    q2 = np.asarray(geo.mat_to_quat(jnp.asarray(m)))
    q = q * np.sign(q[:, :1])
    np.testing.assert_allclose(q2, q, atol=1e-5)


def test_rot6d_round_trip_and_gram_schmidt():
    m = _random_rotations(100, 1).as_matrix().astype(np.float32)
    x = geo.rot6d_from_mat(jnp.asarray(m))
    np.testing.assert_allclose(np.asarray(geo.mat_from_rot6d(x)), m, atol=1e-5)
    noisy = x + 0.05 * jax.random.normal(jax.random.key(0), x.shape)
    r = np.asarray(geo.mat_from_rot6d(noisy))
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-5)


def test_slerp_endpoints_and_midpoint():
    r = _random_rotations(2, 3)
    q0, q1 = (jnp.asarray(x, jnp.float32) for x in r.as_quat(scalar_first=True))
    np.testing.assert_allclose(np.abs(np.asarray(geo.slerp(q0, q1, 0.0))), np.abs(np.asarray(q0)), atol=1e-6)
    np.testing.assert_allclose(np.abs(np.asarray(geo.slerp(q0, q1, 1.0))), np.abs(np.asarray(q1)), atol=1e-5)
    mid = geo.quat_to_mat(geo.slerp(q0, q1, 0.5))
    a0 = geo.rotation_angle(mid, geo.quat_to_mat(q0))
    a1 = geo.rotation_angle(mid, geo.quat_to_mat(q1))
    np.testing.assert_allclose(float(a0), float(a1), atol=1e-3)


def test_rotation_error_is_the_rotation_vector():
    r = _random_rotations(50, 4).as_matrix().astype(np.float32)
    rv = (Rotation.random(50, random_state=5).as_rotvec() * 0.5).astype(np.float32)
    target = Rotation.from_rotvec(rv).as_matrix().astype(np.float32) @ r
    np.testing.assert_allclose(np.asarray(geo.rotation_error(jnp.asarray(target), jnp.asarray(r))), rv, atol=1e-4)
