"""READ-O's task-space samplers: cold diffusion step by step, reverse Euler–Maruyama with the
exact eps of a Gaussian data set, determinism and N = 0."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import SDEConfig
from readjax.diffusion import irsde, taskspace

CFG = SDEConfig()


def key(seed):
    return jax.random.key(seed, impl="rbg")


def test_cold_diffusion_by_hand():
    x_r = jnp.linspace(-1, 1, 12).reshape(3, 4)
    x0_fn = lambda x, t: 0.5 * x + t  # noqa: E731  (any function of (x, t))
    final, hist = taskspace.cold_diffusion(x0_fn, key(0), x_r, CFG, 3, return_history=True)
    ts = np.linspace(1.0, taskspace.DEFAULT_T_END, 4)
    keys = jax.random.split(key(0), 3)
    x = x_r
    for k in range(3):
        x0 = x0_fn(x, ts[k])
        np.testing.assert_allclose(hist[k], x0, rtol=1e-5, atol=1e-6)
        x = irsde.marginal_sample(keys[k], x0, x_r, ts[k + 1], CFG)
    np.testing.assert_array_equal(final, hist[-1])
    # a perfect x0 predictor returns the truth at once
    truth = jnp.ones_like(x_r) * 3.0
    np.testing.assert_allclose(taskspace.cold_diffusion(lambda x, t: truth, key(1), x_r, CFG, 4), truth)


def test_n_zero_returns_retrieved():
    x_r = jnp.ones((2, 3))
    for fn in (taskspace.cold_diffusion, taskspace.reverse_em):
        np.testing.assert_array_equal(fn(lambda x, t: x, key(0), x_r, CFG, 0), x_r)
        with pytest.raises(ValueError):
            fn(lambda x, t: x, key(0), x_r, CFG, -1)


MU, SD = 0.4, 0.2  # data ~ N(MU, SD^2); the retrieved value is MU


def exact_eps(x, t):
    """eps = -std(t) * score of x_t ~ N(x_R + (MU - x_R) a, a^2 SD^2 + std^2) with x_R = MU."""
    a, s = irsde.mean_coef(t, CFG), irsde.marginal_std(t, CFG)
    return s * (x - MU) / (a**2 * SD**2 + s**2)


def test_reverse_em_recovers_gaussian_data():
    x_r = jnp.full((8000, 2), MU)
    x = np.asarray(jax.jit(lambda k: taskspace.reverse_em(exact_eps, k, x_r, CFG, 400))(key(2)))
    assert abs(x.mean() - MU) < 0.01
    assert abs(x.std() - SD) < 0.03  # x(1) starts at x_R + std(1) eps, slightly narrower than the marginal


def test_samplers_deterministic_in_the_key():
    x_r = jnp.linspace(-1, 1, 12).reshape(3, 4)
    f = jax.jit(lambda k: jnp.stack([taskspace.cold_diffusion(lambda x, t: 0.9 * x, k, x_r, CFG, 5),
                                     taskspace.reverse_em(exact_eps, k, x_r, CFG, 5)]))
    a, b, c = f(key(3)), f(key(3)), f(key(4))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a[0], c[0]) and not np.allclose(a[1], c[1])


@pytest.mark.parametrize("update", ["cold", "cold_anchor"])
def test_cold_diffusion_runs_the_sdes_update_as_reads_loop_does(update):
    """READ-O's CD (and READ-L's latent CD) follow ``sde.update`` like READ's refinement: the cold
    update moves x by the change of the degradation; cold_anchor's first step is the degraded
    prediction without noise. Neither draws noise: the key does not matter."""
    import dataclasses

    cfg = dataclasses.replace(CFG, update=update)
    x_r = jnp.linspace(-1, 1, 12).reshape(3, 4)
    x0_fn = lambda x, t: 0.5 * x + t  # noqa: E731
    final, hist = taskspace.cold_diffusion(x0_fn, key(0), x_r, cfg, 3, return_history=True)
    ts = np.linspace(1.0, taskspace.DEFAULT_T_END, 4)
    a = [float(irsde.mean_coef(t, cfg)) for t in ts]
    x = x_r
    for k in range(3):
        x0 = x0_fn(x, ts[k])
        np.testing.assert_allclose(hist[k], x0, rtol=1e-5, atol=1e-6)
        x = x_r + (x0 - x_r) * a[1] if (k == 0 and update == "cold_anchor") else x + (x0 - x_r) * (a[k + 1] - a[k])
    np.testing.assert_array_equal(final, hist[-1])
    np.testing.assert_array_equal(final, taskspace.cold_diffusion(x0_fn, key(9), x_r, cfg, 3))
    truth = jnp.full_like(x_r, 3.0)
    np.testing.assert_allclose(taskspace.cold_diffusion(lambda x, t: truth, key(1), x_r, cfg, 4), truth)
