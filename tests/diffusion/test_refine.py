"""READ's refinement loop: METHOD.md section 8 step by step, determinism, N = 0, kinematic AE."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import SDEConfig
from readjax.diffusion import irsde, refine
from readjax.diffusion.refine import time_grid
from readjax.models import Denoiser, make_autoencoder

from tests.models.helpers import (TINY_DENOISER, TINY_VAE, chain_and_camera, jit_init, key, synthetic_batch)

B = 2
SDE = SDEConfig()


@pytest.fixture(scope="module")
def setup():
    batch = synthetic_batch(B, seed=5)
    m_r = batch["motion"]
    image = jax.random.uniform(key(0), (B, 32, 32, 4))
    ae = make_autoencoder(TINY_VAE)
    ae_params = jit_init(ae, key(1), m_r)
    den = Denoiser(TINY_DENOISER)
    den_params = jit_init(den, {"params": key(2)}, image, m_r, jnp.ones(B))
    feats = jax.jit(lambda p, i: den.apply(p, i, method="encode_image"))(den_params, image)
    return ae, ae_params, den, den_params, feats, m_r


def test_time_grid():
    np.testing.assert_allclose(time_grid(4), np.linspace(1, 1e-3, 5), rtol=1e-6)


def test_follows_method_section_8(setup):
    """Two steps of the jitted scan equal the loop written out by hand."""
    ae, ap, den, dp, feats, m_r = setup
    final, hist = refine(ae, ap, den, dp, feats, m_r, key(7), 2, SDE, return_history=True)
    assert final.shape == (B, 101, 10) and hist.shape == (2, B, 101, 10)

    enc = jax.jit(lambda m: ae.apply(ap, m, method="code"))
    dec = jax.jit(lambda z: ae.apply(ap, z, method="decode"))
    d = jax.jit(lambda m, t: den.apply(dp, feats, m, t, method="denoise"))
    ts = np.linspace(1.0, 1e-3, 3)
    keys = jax.random.split(key(7), 2)
    z_r = enc(m_r)
    x = m_r
    for k in range(2):
        m0 = d(dec(enc(x)), ts[k])
        np.testing.assert_allclose(hist[k], m0, atol=2e-4)
        x = dec(irsde.marginal_sample(keys[k], enc(m0), z_r, ts[k + 1], SDE))
    np.testing.assert_allclose(final, m0, atol=2e-4)
    np.testing.assert_array_equal(final, hist[-1])


def test_determinism_and_n_zero(setup):
    ae, ap, den, dp, feats, m_r = setup
    # same static arguments as test_follows_method_section_8: one compile for both tests
    a, _ = refine(ae, ap, den, dp, feats, m_r, key(3), 2, SDE, return_history=True)
    b, _ = refine(ae, ap, den, dp, feats, m_r, key(3), 2, SDE, return_history=True)
    c, _ = refine(ae, ap, den, dp, feats, m_r, key(4), 2, SDE, return_history=True)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert bool(jnp.all(jnp.isfinite(a)))
    same, hist = refine(ae, ap, den, dp, feats, m_r, key(3), 0, SDE, return_history=True)
    np.testing.assert_array_equal(same, m_r)
    assert hist.shape == (0, B, 101, 10)


def test_checks(setup):
    ae, ap, den, dp, feats, m_r = setup
    with pytest.raises(ValueError, match="delta"):
        refine(ae, ap, Denoiser(TINY_DENOISER, output="eps"), dp, feats, m_r, key(0), 1, SDE)
    with pytest.raises(ValueError, match="n_steps"):
        refine(ae, ap, den, dp, feats, m_r, key(0), -1, SDE)
    with pytest.raises(ValueError, match="m_r"):
        refine(ae, ap, den, dp, feats, m_r[:, :50], key(0), 1, SDE)
    with pytest.raises(ValueError, match="features"):
        refine(ae, ap, den, dp, feats[:1], m_r, key(0), 1, SDE)


def test_with_the_kinematic_autoencoder(setup):
    _, _, den, dp, feats, m_r = setup
    chain, cam = chain_and_camera()
    kae = make_autoencoder(dataclasses.replace(TINY_VAE, kinematic=True), chain, cam)
    kp = jit_init(kae, key(5), m_r)
    out = refine(kae, kp, den, dp, feats, m_r, key(6), 1, SDE)
    assert out.shape == (B, 101, 10) and bool(jnp.all(jnp.isfinite(out)))


def test_cold_update_follows_its_formula_and_is_deterministic(setup):
    """sde.update="cold": z <- z + (Enc(M̂0) - zR)(a(t_next) - a(t)) from z = zR, written out by hand;
    no noise (any key gives the same plan); its first step is the paper's first step."""
    ae, ap, den, dp, feats, m_r = setup
    cold = dataclasses.replace(SDE, update="cold")
    final, hist = refine(ae, ap, den, dp, feats, m_r, key(7), 3, cold, return_history=True)
    other = refine(ae, ap, den, dp, feats, m_r, key(8), 3, cold)
    np.testing.assert_array_equal(final, other)
    enc = jax.jit(lambda m: ae.apply(ap, m, method="code"))
    dec = jax.jit(lambda z: ae.apply(ap, z, method="decode"))
    d = jax.jit(lambda m, t: den.apply(dp, feats, m, t, method="denoise"))
    ts = np.linspace(1.0, 1e-3, 4)
    z_r = enc(m_r)
    z = z_r
    for k in range(3):
        m0 = d(dec(z), ts[k])
        np.testing.assert_allclose(hist[k], m0, atol=2e-4)
        z = z + (enc(m0) - z_r) * (irsde.mean_coef(ts[k + 1], SDE) - irsde.mean_coef(ts[k], SDE))
    np.testing.assert_array_equal(final, hist[-1])
    paper_first = refine(ae, ap, den, dp, feats, m_r, key(7), 1, SDE)
    np.testing.assert_allclose(refine(ae, ap, den, dp, feats, m_r, key(7), 1, cold), paper_first, atol=1e-5)
    with pytest.raises(ValueError, match="update must be one of"):
        SDEConfig(update="fancy")


def test_cold_anchor_first_step_anchors_at_the_degraded_prediction(setup):
    """sde.update="cold_anchor": step 0 sets z = zR + (Enc(M̂0) - zR) a(t_1), later steps as "cold"."""
    ae, ap, den, dp, feats, m_r = setup
    anchored = dataclasses.replace(SDE, update="cold_anchor")
    final, hist = refine(ae, ap, den, dp, feats, m_r, key(7), 3, anchored, return_history=True)
    enc = jax.jit(lambda m: ae.apply(ap, m, method="code"))
    dec = jax.jit(lambda z: ae.apply(ap, z, method="decode"))
    d = jax.jit(lambda m, t: den.apply(dp, feats, m, t, method="denoise"))
    ts = np.linspace(1.0, 1e-3, 4)
    a = lambda t: irsde.mean_coef(t, SDE)  # noqa: E731
    z_r = enc(m_r)
    z = z_r
    for k in range(3):
        m0 = d(dec(z), ts[k])
        np.testing.assert_allclose(hist[k], m0, atol=2e-4)
        z = z_r + (enc(m0) - z_r) * a(ts[1]) if k == 0 else z + (enc(m0) - z_r) * (a(ts[k + 1]) - a(ts[k]))
    np.testing.assert_array_equal(final, hist[-1])
