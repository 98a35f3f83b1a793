"""READ-O: both training targets fit a fixed batch; the task-space samplers are deterministic in
the key and start from the retrieved motion."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import ReadOConfig, SDEConfig
from readjax.methods import common, read_o

from tests.methods.helpers import B, fit, stats_of, tiny_batch
from tests.models.helpers import TINY_DENOISER, key

SDE = SDEConfig()


@pytest.mark.parametrize("sampler", ["cd", "em"])
def test_fit_and_sample(sampler):
    den = read_o.build_denoiser({"denoiser": TINY_DENOISER, "read_o": ReadOConfig(sampler=sampler)})
    assert den.output == ("delta" if sampler == "cd" else "eps")
    batch = tiny_batch()
    stats = stats_of(batch)
    params = jax.jit(lambda k: read_o.init_denoiser(den, 32, k))(key(0))
    batch["norm"] = common.batch_stats(stats, B)
    first, final = fit(read_o.read_o_loss(den, SDE, augment=False), params, batch, steps=8)
    assert final < 0.8 * first

    feats = jax.jit(lambda p, i: den.apply(p, i, method="encode_image"))(params, jnp.asarray(batch["image"]))
    m_r = jnp.asarray(batch["retrieved"])
    a, hist = read_o.refine(den, params, feats, stats, m_r, key(1), 3, SDE, return_history=True)
    b = read_o.refine(den, params, feats, stats, m_r, key(1), 3, SDE)
    c = read_o.refine(den, params, feats, stats, m_r, key(2), 3, SDE)
    assert a.shape == (B, 101, 10) and hist.shape == (3, B, 101, 10) and np.all(np.isfinite(a))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a, hist[-1], atol=1e-5)
    assert not np.allclose(a, c)
    if sampler == "cd":  # the first step denoises M_R itself at t = 1 (like READ's refinement)
        x_r = common.normalize(m_r, stats)
        first_step = jax.jit(lambda p: den.apply(p, feats, x_r, 1.0, track=m_r, method="denoise"))(params)
        np.testing.assert_allclose(hist[0], common.denormalize(first_step, stats), rtol=1e-4, atol=1e-4)

