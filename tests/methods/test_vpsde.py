"""VPSDE and VPSDE+CG: the normaliser, fitting a fixed batch, sampler determinism and the
classifier-free guidance formula."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import VPSDEConfig
from readjax.diffusion import vpsde as vp
from readjax.methods import common, vpsde
from readjax.models.denoiser import Denoiser
from readjax.training import CheckpointError

from tests.methods.helpers import B, fit, stats_of, tiny_batch
from tests.models.helpers import TINY_DENOISER, key

CFG = VPSDEConfig()


def test_normalizer(tmp_path):
    batch = tiny_batch()
    mean, std = common.motion_stats(batch["motion"])
    assert mean.shape == std.shape == (10,) and np.all(std >= common.STD_FLOOR)
    x = common.normalize(jnp.asarray(batch["motion"]), (mean, std))
    np.testing.assert_allclose(np.asarray(x).reshape(-1, 10).mean(0), 0, atol=1e-4)
    np.testing.assert_allclose(common.denormalize(x, (mean, std)), batch["motion"], atol=1e-5)
    common.write_normalizer(tmp_path, (mean, std))
    common.write_normalizer(tmp_path, (mean, std))  # same stats: fine
    back = common.read_normalizer(tmp_path)
    np.testing.assert_array_equal(back[0], mean)
    assert json.loads((tmp_path / common.NORMALIZER_FILE).read_text())["channels"][0] == "uv"
    with pytest.raises(CheckpointError):
        common.write_normalizer(tmp_path, (mean + 1, std))


@pytest.fixture(scope="module")
def cg_setup():
    batch = tiny_batch()
    den = Denoiser(TINY_DENOISER, use_cond=True, output="eps")
    params = jax.jit(lambda k: vpsde.init_denoiser(den, 32, k))(key(0))
    feats = jax.jit(lambda p, i: den.apply(p, i, method="encode_image"))(params, jnp.asarray(batch["image"]))
    return den, params, feats, batch, stats_of(batch)


@pytest.mark.parametrize("cond", [False, True])
def test_eps_loss_fits_a_fixed_batch(cond):
    den = Denoiser(TINY_DENOISER, use_cond=cond, output="eps")
    batch = tiny_batch()
    params = jax.jit(lambda k: vpsde.init_denoiser(den, 32, k))(key(0))
    batch["norm"] = common.batch_stats(stats_of(batch), B)
    first, final = fit(vpsde.eps_loss(den, CFG, augment=False), params, batch, steps=8)
    assert final < 0.8 * first


def test_sampler_determinism_and_shapes(cg_setup):
    den, params, feats, batch, stats = cg_setup
    m_r = jnp.asarray(batch["retrieved"])
    for sampler in ("ode", "sde"):
        a = vpsde.sample(den, params, feats, stats, m_r, key(1), 3, CFG, sampler)
        b = vpsde.sample(den, params, feats, stats, m_r, key(1), 3, CFG, sampler)
        c = vpsde.sample(den, params, feats, stats, m_r, key(2), 3, CFG, sampler)
        assert a.shape == (B, 101, 10) and np.all(np.isfinite(a))
        np.testing.assert_array_equal(a, b)
        assert not np.allclose(a, c)


def test_guidance_formula(cg_setup):
    """One ODE step with w = 2 written out: eps = 2 eps(cond) - eps(uncond), image tokens in both."""
    den, params, feats, batch, stats = cg_setup
    m_r = jnp.asarray(batch["retrieved"])
    out = vpsde.sample(den, params, feats, stats, m_r, key(3), 1, CFG, "ode", 2.0)
    x = jax.random.normal(jax.random.split(key(3))[0], m_r.shape)
    ones, zeros = jnp.ones((B,), bool), jnp.zeros((B,), bool)
    # the denoiser embeds normalised motions (state and M_R) and samples the image at the real uv
    eps = jax.jit(lambda p, keep: den.apply(p, feats, x, 1.0, cond=common.normalize(m_r, stats), cond_keep=keep,
                                            track=common.denormalize(x, stats), method="denoise"))
    e_c, e_u = eps(params, ones), eps(params, zeros)
    assert not np.allclose(e_c, e_u)
    h = 1.0 - CFG.sample_eps
    score = -(2 * e_c - e_u) / vp.marginal_std(1.0, CFG)
    expect = common.denormalize(x + 0.5 * vp.beta(1.0, CFG) * (x + score) * h, stats)
    np.testing.assert_allclose(out, expect, rtol=1e-4, atol=1e-4)
    # w = 1 is the conditional branch alone
    out1 = vpsde.sample(den, params, feats, stats, m_r, key(3), 1, CFG, "ode", 1.0)
    expect1 = common.denormalize(x + 0.5 * vp.beta(1.0, CFG) * (x - e_c / vp.marginal_std(1.0, CFG)) * h, stats)
    np.testing.assert_allclose(out1, expect1, rtol=1e-4, atol=1e-4)


def test_denoiser_track_argument(cg_setup):
    """``track`` moves where the image tokens are sampled; None (READ) samples along the motion itself."""
    den, params, feats, batch, stats = cg_setup
    m = jnp.asarray(batch["motion"])
    f = jax.jit(lambda p, track: den.apply(p, feats, m, 0.5, track=track, method="denoise"))
    base = jax.jit(lambda p: den.apply(p, feats, m, 0.5, method="denoise"))(params)
    np.testing.assert_allclose(f(params, m), base, rtol=1e-5, atol=1e-5)
    assert not np.allclose(f(params, m.at[..., :2].multiply(-1)), base)
    with pytest.raises(ValueError, match="track"):
        den.apply(params, feats, m, 0.5, track=m[:, :5], method="denoise")
