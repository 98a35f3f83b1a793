"""Autoencoder evaluation: the IK reachability check separates reachable from unreachable motions,
and reconstruction errors are zero for a perfect reconstruction and in the right units otherwise."""

import jax
import jax.numpy as jnp
import numpy as np

from readjax.lab import ae_eval
from readjax import motion as mo
from readjax.sim import kinematics as kin

from tests.models.helpers import chain_and_camera


def _fk_motions(chain, cam, n: int, seed: int = 0) -> np.ndarray:
    """Smooth joint paths near the home posture, through FK: reachable by construction."""
    rng = np.random.default_rng(seed)
    a, b = (kin.HOME_Q + rng.uniform(-0.4, 0.4, (2, n, 7))).astype(np.float32)
    s = np.linspace(0, 1, mo.FRAMES, dtype=np.float32)[None, :, None]
    q = np.clip(a[:, None] * (1 - s) + b[:, None] * s, np.asarray(chain.lower) + 0.02, np.asarray(chain.upper) - 0.02)
    pos, rot = jax.vmap(jax.vmap(lambda qq: kin.fk(chain, qq)))(jnp.asarray(q))
    return np.asarray(mo.encode(cam, pos, rot, jnp.ones(q.shape[:2])))


def test_reachability_separates_reachable_from_unreachable():
    chain, cam = chain_and_camera(64)
    good = _fk_motions(chain, cam, 3)
    bad = good.copy()
    bad[1, 50:, 2] += 3.0  # half the motion 3 m further along the optical axis: out of the arm's reach
    res = ae_eval.reachability(chain, cam, np.concatenate([good, bad[1:2]]))
    assert res["motions_reachable"] == 0.75
    assert 0.85 < res["poses_reachable"] < 0.95  # 51 of 404 poses are out of reach
    assert res["ik_pos_err_mm_median"] < 1.0 and res["ik_pos_err_mm_max"] > 500


def test_reconstruction_errors_units():
    chain, cam = chain_and_camera(64)
    m = _fk_motions(chain, cam, 2, seed=1)
    zero = ae_eval.reconstruction_errors(cam, m, m, 64)
    assert zero["pos_err_mm_mean"] < 1e-3 and zero["rot_err_rad_mean"] < 2e-3 and zero["uv_err_px_mean"] == 0
    shifted = m.copy()
    shifted[..., 0] += 2.0 / 64  # one pixel to the right at 64 px
    e = ae_eval.reconstruction_errors(cam, shifted, m, 64)
    np.testing.assert_allclose(e["uv_err_px_mean"], 1.0, rtol=1e-4)
    assert e["pos_err_mm_mean"] > 1.0
    assert zero["end_pos_err_mm_median"] < 1e-3 and e["end_pos_err_mm_median"] > 1.0
