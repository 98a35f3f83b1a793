"""Resampling demonstrations of any length to 101 frames and back."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from readjax.data import resample as rs


def _smooth_demo(n):
    t = np.linspace(0, 1, n)
    uvz = np.stack([np.sin(2 * t), np.cos(3 * t) * 0.5, 1.2 + 0.3 * t**2], 1)
    rot = Rotation.from_rotvec(np.stack([0.5 * t, np.sin(t), 0.2 * t], 1)).as_matrix()
    grip = (t < 0.5).astype(float)
    joints = np.stack([np.sin(t * k) for k in range(1, 8)], 1)
    return uvz, rot, grip, joints


@pytest.mark.parametrize("n_raw", [37, 250, 700])
def test_round_trip_through_101_frames(n_raw):
    uvz, rot, grip, joints = _smooth_demo(n_raw)
    u101, r101, g101, q101 = rs.resample_demo(uvz, rot, grip, joints)
    assert u101.shape == (101, 3) and r101.shape == (101, 3, 3) and g101.shape == (101,) and q101.shape == (101, 7)
    back = rs.resample_cubic(u101, n_raw)
    assert np.abs(back - uvz).max() < 1e-4
    rb = rs.resample_rotations(r101, n_raw)
    ang = Rotation.from_matrix(rb).inv() * Rotation.from_matrix(rot)
    assert ang.magnitude().max() < 1e-3
    assert np.abs(rs.resample_cubic(q101, n_raw) - joints).max() < 1e-3
    # endpoints are kept exactly, grip stays in [0, 1]
    np.testing.assert_allclose(u101[[0, -1]], uvz[[0, -1]], atol=1e-6)
    assert g101.min() >= 0 and g101.max() <= 1


def test_too_short():
    with pytest.raises(ValueError, match="at least 2"):
        rs.resample_cubic(np.zeros((1, 3)))
