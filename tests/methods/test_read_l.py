"""READ-L: the latent denoiser's shapes, fitting a fixed batch in latent space, and the latent
cold-diffusion sampler (determinism, N = 0)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import SDEConfig
from readjax.diffusion import latent
from readjax.methods import read as read_lib
from readjax.methods import read_l
from readjax.models import make_autoencoder
from readjax.models.latent_denoiser import LatentDenoiser

from tests.methods.helpers import B, fit, tiny_batch
from tests.models.helpers import TINY_DENOISER, TINY_VAE, key

SDE = SDEConfig()


def test_latent_denoiser_fit_and_sample():
    batch = tiny_batch()
    ae = make_autoencoder(TINY_VAE)
    ae_params = jax.jit(lambda k: read_lib.init_ae(ae, k))(key(0))
    lden = LatentDenoiser(TINY_DENOISER, latent_dim=TINY_VAE.latent_dim)
    params = jax.jit(lambda k: read_l.init_latent_denoiser(lden, 32, k))(key(1))
    batch.update(code=latent.codes(ae, ae_params, batch["motion"], None),
                 code_r=latent.codes(ae, ae_params, batch["retrieved"], None))
    with pytest.raises(ValueError, match="z_t"):
        lden.apply(params, jnp.asarray(batch["image"]), jnp.zeros((B, 3)), jnp.zeros((B, 101, 2)), 0.5)
    first, final, trained = fit(read_l.read_l_loss(ae, lden, SDE, augment=False),
                                {"denoiser": params, "ae": ae_params}, batch, steps=8, return_params=True)
    assert final < 0.8 * first
    # the autoencoder rides in the train state but stays frozen
    jax.tree.map(np.testing.assert_array_equal, trained["ae"], ae_params)

    feats = jax.jit(lambda p, i: lden.apply(p, i, method="encode_image"))(params, jnp.asarray(batch["image"]))
    m_r = jnp.asarray(batch["retrieved"])
    a, hist = read_l.refine(ae, ae_params, lden, params, feats, m_r, key(2), 2, SDE, return_history=True)
    b = read_l.refine(ae, ae_params, lden, params, feats, m_r, key(2), 2, SDE)
    c = read_l.refine(ae, ae_params, lden, params, feats, m_r, key(3), 2, SDE)
    assert a.shape == (B, 101, 10) and hist.shape == (2, B, 101, 10) and np.all(np.isfinite(a))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a, hist[-1], atol=1e-5)
    assert not np.allclose(a, c)
    np.testing.assert_array_equal(read_l.refine(ae, ae_params, lden, params, feats, m_r, key(2), 0, SDE), m_r)
