"""READ's training objective: the paper's loss, and ``sde.self_feed`` (the denoiser trained on the
degradation of its own first prediction) — what it feeds, that no gradient crosses the first
pass, and that it fits."""

import dataclasses
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import config
from readjax.config import SDEConfig
from readjax.diffusion import irsde, latent
from readjax.methods import read as read_lib
from readjax.models import make_autoencoder
from readjax.models.denoiser import Denoiser
from readjax.models.vae import weighted_motion_loss
from readjax.training import CheckpointError

from tests.methods.helpers import fit, stats_of, tiny_batch
from tests.models.helpers import TINY_DENOISER, TINY_VAE, key

WEIGHTS = TINY_VAE.loss_weights


def tiny_read():
    """A tiny autoencoder and denoiser (random parameters) and a batch carrying its codes."""
    batch = tiny_batch()
    ae = make_autoencoder(TINY_VAE)
    ae_params = jax.jit(lambda k: read_lib.init_ae(ae, k))(key(0))
    mean, std = stats_of(batch)
    cfg = dataclasses.replace(TINY_DENOISER, normalize_motion=True, motion_mean=tuple(map(float, mean)),
                              motion_std=tuple(map(float, std)), drop_path=0.0)
    den = Denoiser(cfg, output="delta")
    params = jax.jit(lambda k: read_lib.init_denoiser(den, 32, k))(key(1))
    batch.update(code=latent.codes(ae, ae_params, batch["motion"], None),
                 code_r=latent.codes(ae, ae_params, batch["retrieved"], None))
    return ae, ae_params, den, params, {k: jnp.asarray(v) for k, v in batch.items()}


@pytest.fixture(scope="module")
def setup():
    return tiny_read()


def by_hand(ae, ae_params, den, params, batch, rng, sde, fed_input: bool):
    """The loss written out: the paper's input, or (``fed_input``) the degradation at the same t and
    noise of Enc of the first prediction, which enters as a constant."""
    enc, dec = latent.codec(ae, ae_params, None)
    k_t, k_n, _, _ = jax.random.split(rng, 4)
    m = batch["motion"]
    t = irsde.sample_time(k_t, (m.shape[0],), sde)
    m_t = dec(irsde.marginal_sample(k_n, batch["code"], batch["code_r"], t, sde))
    if fed_input:
        first = jax.lax.stop_gradient(den.apply(params, batch["image"], m_t, t))
        m_t = dec(irsde.marginal_sample(k_n, enc(first), batch["code_r"], t, sde))
    return weighted_motion_loss(den.apply(params, batch["image"], m_t, t), m, WEIGHTS)


@pytest.mark.parametrize("self_feed", [0.0, 1.0])
def test_the_loss_and_its_gradient_are_the_objective_written_out(setup, self_feed):
    ae, ae_params, den, params, batch = setup
    sde = SDEConfig(self_feed=self_feed)
    rng = key(5)
    loss = read_lib.read_loss(ae, ae_params, den, sde, augment=False, weights=WEIGHTS)
    got, got_grad = jax.jit(jax.value_and_grad(lambda p: loss(p, batch, rng)[0]))(params)
    want, want_grad = jax.jit(jax.value_and_grad(
        lambda p: by_hand(ae, ae_params, den, p, batch, rng, sde, self_feed == 1.0)[0]))(params)
    np.testing.assert_allclose(got, want, rtol=1e-5)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6), got_grad, want_grad)


def test_self_feed_changes_the_input_and_a_fraction_mixes_both(setup):
    ae, ae_params, den, params, batch = setup
    rng = key(5)
    losses = {f: float(jax.jit(lambda p, f=f: read_lib.read_loss(ae, ae_params, den, SDEConfig(self_feed=f), False,
                                                                 WEIGHTS)(p, batch, rng)[0])(params))
              for f in (0.0, 1.0)}
    assert losses[0.0] != losses[1.0]
    first, final = fit(read_lib.read_loss(ae, ae_params, den, SDEConfig(self_feed=0.5), False, WEIGHTS),
                       params, batch, steps=20, lr=1e-2)
    assert final < 0.5 * first


@pytest.mark.parametrize("bad", [-0.1, 1.5])
def test_self_feed_outside_zero_one_is_refused(bad):
    with pytest.raises(ValueError, match="self_feed"):
        SDEConfig(self_feed=bad)


def test_the_autoencoder_source_is_checked_only_before_the_run_has_its_copy(tmp_path):
    """--vae-from is checked before run.json is written; a run that already holds its copied
    autoencoder resumes without its source (which may since have been moved or retrained)."""
    source, run = tmp_path / "source", tmp_path / "run"
    check = read_lib.autoencoder_source_check(source, run)
    cfg_dict = config.configs_to_dict(config.presets("cpu"))
    with pytest.raises(CheckpointError, match="not a finished 'vae' stage"):
        check(cfg_dict, types.SimpleNamespace(fingerprint="fp"))
    assert read_lib.autoencoder_source_check(None, run) is None
    (run / "vae").mkdir(parents=True)
    assert read_lib.autoencoder_source_check(source, run) is None
