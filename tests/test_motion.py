"""The motion format: encode/decode round trip, accessors, input checks."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from readjax import tasks
from readjax import motion as mo
from readjax.sim.camera import camera_from_model


def test_encode_decode_round_trip():
    env = tasks.make("reach_target")
    cam = camera_from_model(env.mj_model, "front", 64, 64)
    rng = np.random.default_rng(0)
    pos = rng.uniform([0.3, -0.3, 0.0], [0.7, 0.3, 0.5], size=(4, 101, 3)).astype(np.float32)
    rot = Rotation.random(404, random_state=1).as_matrix().reshape(4, 101, 3, 3).astype(np.float32)
    grip = rng.uniform(size=(4, 101)).astype(np.float32)
    m = mo.encode(cam, jnp.asarray(pos), jnp.asarray(rot), jnp.asarray(grip))
    assert m.shape == (4, 101, 10)
    p2, r2, g2 = mo.decode(cam, m)
    np.testing.assert_allclose(np.asarray(p2), pos, atol=1e-5)
    np.testing.assert_allclose(np.asarray(r2), rot, atol=1e-5)
    np.testing.assert_allclose(np.asarray(g2), grip)
    parts = mo.split_keys(m)
    assert [v.shape[-1] for v in parts.values()] == [2, 1, 6, 1]
    np.testing.assert_array_equal(np.asarray(mo.join_keys(parts)), np.asarray(m))


def test_check_motion_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(\.\.\., 101, 10\)"):
        mo.check_motion(np.zeros((2, 100, 10)))
    bad = np.zeros((1, 101, 10))
    bad[0, 3, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        mo.check_motion(bad)
