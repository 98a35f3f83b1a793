"""The standardised latent of READ's SDE: stats, codec, record, and the refinement loop on it."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import SDEConfig
from readjax.diffusion import latent
from readjax.diffusion.refine import refine
from readjax.models import Denoiser, make_autoencoder
from readjax.training import CheckpointError

from tests.models.helpers import TINY_DENOISER, TINY_VAE, jit_init, key, synthetic_batch


@pytest.fixture(scope="module")
def ae_and_motions():
    motions = synthetic_batch(24, seed=11)["motion"]
    ae = make_autoencoder(TINY_VAE)
    return ae, jit_init(ae, key(1), motions[:2]), motions


def test_measured_stats_standardise_the_training_codes(ae_and_motions):
    ae, params, motions = ae_and_motions
    stats = latent.measure(ae, params, motions, chunk=7)  # chunks of unequal size
    enc, _ = latent.codec(ae, params, stats)
    z = np.asarray(enc(motions))
    raw = np.asarray(ae.apply(params, motions, method="code"))
    assert z.shape == raw.shape == (24, TINY_VAE.latent_dim)
    live = raw.std(0) > latent.STD_FLOOR
    assert live.sum() > 0
    np.testing.assert_allclose(z.mean(0), 0, atol=1e-4)
    np.testing.assert_allclose(z.std(0)[live], 1, rtol=1e-3)


def test_precomputed_codes_are_the_codec_encoding(ae_and_motions):
    """Training stages take z0 and zR from codes computed once per training set: they must be what
    the codec's encode returns for each motion, with and without standardisation."""
    ae, params, motions = ae_and_motions
    stats = latent.measure(ae, params, motions)
    for s in (None, stats):
        enc, _ = latent.codec(ae, params, s)
        z = latent.codes(ae, params, motions, s, chunk=5)
        assert z.shape == (24, TINY_VAE.latent_dim) and z.dtype == np.float32
        np.testing.assert_allclose(z, np.asarray(enc(motions)), rtol=1e-4, atol=1e-4)  # batching: rounding


def test_codec_decodes_what_it_encodes_like_the_raw_code(ae_and_motions):
    """Standardisation is a change of units of the SDE's latent only: Dec(Enc(M)) is unchanged."""
    ae, params, motions = ae_and_motions
    stats = latent.LatentStats(jnp.linspace(-1, 1, TINY_VAE.latent_dim), jnp.linspace(0.1, 2, TINY_VAE.latent_dim))
    enc, dec = latent.codec(ae, params, stats)
    raw_enc, raw_dec = latent.codec(ae, params, None)
    np.testing.assert_allclose(dec(enc(motions)), raw_dec(raw_enc(motions)), atol=1e-5)
    np.testing.assert_allclose(enc(motions) * stats.std + stats.mean, raw_enc(motions), atol=1e-5)


def test_record_round_trip_and_refusal(tmp_path, ae_and_motions):
    ae, params, motions = ae_and_motions
    stats = latent.measure(ae, params, motions)
    sde_on = SDEConfig(latent_norm=True)
    with pytest.raises(CheckpointError, match="latent_stats.json"):
        latent.for_run(tmp_path, sde_on)
    latent.write(tmp_path, stats)
    back = latent.for_run(tmp_path, sde_on)
    np.testing.assert_array_equal(back.mean, stats.mean)
    np.testing.assert_array_equal(back.std, stats.std)
    assert latent.for_run(tmp_path, SDEConfig()) is None  # the paper's raw code ignores the file
    latent.write(tmp_path, stats)  # the same stats again (a resumed run): accepted
    with pytest.raises(CheckpointError, match="other latent statistics"):
        latent.write(tmp_path, latent.LatentStats(stats.mean + 0.1, stats.std))
    (tmp_path / latent.STATS_FILE).write_text('{"mean": [0.0')  # a truncated file: one clear line
    with pytest.raises(CheckpointError, match="is not a record of latent statistics"):
        latent.for_run(tmp_path, sde_on)


def test_refine_on_identity_stats_is_the_paper_loop(ae_and_motions):
    """latent=None (the paper) and identity statistics give the same loop; other statistics change it."""
    ae, ap, motions = ae_and_motions
    m_r = motions[:2]
    image = jax.random.uniform(key(0), (2, 32, 32, 4))
    den = Denoiser(TINY_DENOISER)
    dp = jit_init(den, {"params": key(2)}, image, m_r, jnp.ones(2))
    feats = jax.jit(lambda p, i: den.apply(p, i, method="encode_image"))(dp, image)
    for update in ("renoise", "cold"):
        sde = dataclasses.replace(SDEConfig(), update=update)
        paper = refine(ae, ap, den, dp, feats, m_r, key(3), 3, sde)
        ident = refine(ae, ap, den, dp, feats, m_r, key(3), 3, sde,
                              latent=latent.LatentStats.identity(TINY_VAE.latent_dim))
        np.testing.assert_allclose(ident, paper, atol=1e-5)
    scaled = refine(ae, ap, den, dp, feats, m_r, key(3), 3, SDEConfig(),
                           latent=latent.measure(ae, ap, motions))
    assert np.abs(np.asarray(scaled) - np.asarray(paper)).max() > 1e-4
