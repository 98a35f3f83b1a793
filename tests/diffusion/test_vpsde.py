"""The VP SDE of the VPSDE baselines: schedule, closed-form marginal against Euler–Maruyama, and
both samplers (probability-flow ODE, reverse SDE) with the exact eps of a Gaussian data set."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import VPSDEConfig
from readjax.diffusion import vpsde as vp

CFG = VPSDEConfig()  # beta 1 -> 20


def key(seed):
    return jax.random.key(seed, impl="rbg")


def test_schedule():
    np.testing.assert_allclose(vp.beta(0.0, CFG), 1.0)
    np.testing.assert_allclose(vp.beta(1.0, CFG), 20.0)
    ts = np.linspace(0, 0.6, 6001)
    np.testing.assert_allclose(vp.beta_integral(0.6, CFG), np.trapezoid(np.asarray(vp.beta(ts, CFG)), ts), rtol=1e-6)
    np.testing.assert_allclose(vp.mean_coef(1.0, CFG), np.exp(-0.5 * 10.5), rtol=1e-6)
    np.testing.assert_allclose(vp.marginal_std(0.0, CFG), 0.0, atol=1e-7)
    # variance preserving: alpha^2 + s^2 = 1
    t = jnp.linspace(0, 1, 11)
    np.testing.assert_allclose(vp.mean_coef(t, CFG) ** 2 + vp.marginal_std(t, CFG) ** 2, 1.0, rtol=1e-6)
    with pytest.raises(ValueError):
        VPSDEConfig(sampler="ddim")
    with pytest.raises(ValueError):
        VPSDEConfig(beta_min=2.0, beta_max=1.0)


def test_marginal_sample_formula():
    x0 = jnp.arange(6.0).reshape(2, 3)
    t = jnp.array([0.1, 0.9])
    x_t, eps = vp.marginal_sample(key(0), x0, t, CFG)
    a, s = vp.mean_coef(t, CFG)[:, None], vp.marginal_std(t, CFG)[:, None]
    np.testing.assert_allclose(x_t, a * x0 + s * eps, rtol=1e-6)
    np.testing.assert_array_equal(eps, jax.random.normal(key(0), x0.shape))
    t = vp.sample_time(key(1), (10000,), CFG)
    assert float(t.min()) >= CFG.train_eps and float(t.max()) <= 1.0


@pytest.mark.parametrize("t_end", [0.3, 1.0])
def test_marginal_agrees_with_euler_maruyama(t_end):
    n, steps = 20000, 400
    x0 = jnp.broadcast_to(jnp.array([1.5, -0.5]), (n, 2))
    x = vp.euler_maruyama(key(2), x0, CFG, steps, t_end=t_end)
    mean, std = vp.marginal_mean_std(x0[:1], t_end, CFG)
    se = float(np.ravel(std)[0]) / np.sqrt(n)
    np.testing.assert_allclose(np.mean(np.asarray(x), 0), np.asarray(mean[0]), atol=4 * se + 0.01)
    np.testing.assert_allclose(np.std(np.asarray(x), 0), float(np.ravel(std)[0]), rtol=0.03)


MU, SD = 0.7, 0.3  # data ~ N(MU, SD^2) per dimension


def exact_eps(x, t):
    """eps = -s(t) * score of x_t ~ N(alpha MU, alpha^2 SD^2 + s^2) for Gaussian data."""
    a, s = vp.mean_coef(t, CFG), vp.marginal_std(t, CFG)
    var = a**2 * SD**2 + s**2
    return s * (x - a * MU) / var


@pytest.mark.parametrize("sampler", ["ode", "sde"])
def test_samplers_recover_gaussian_data(sampler):
    """With the exact eps, both samplers turn N(0, I) into the data distribution."""
    x = jax.jit(lambda k: vp.sample(exact_eps, k, (8000, 2), CFG, 400, sampler))(key(3))
    x = np.asarray(x)
    assert abs(x.mean() - MU) < 0.02
    assert abs(x.std() - SD) < 0.03


def test_samplers_deterministic_in_the_key():
    f = jax.jit(lambda k: jnp.stack([vp.sample(exact_eps, k, (3, 5), CFG, 6, s) for s in ("ode", "sde")]))
    a, b, c = f(key(4)), f(key(4)), f(key(5))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a[0], c[0]) and not np.allclose(a[1], c[1])
    x, hist = vp.sample(exact_eps, key(4), (3, 5), CFG, 6, "ode", return_history=True)
    assert hist.shape == (6, 3, 5)
    np.testing.assert_array_equal(x, hist[-1])
    with pytest.raises(ValueError):
        vp.sample(exact_eps, key(4), (3, 5), CFG, 0)
    with pytest.raises(ValueError):
        vp.sample(exact_eps, key(4), (3, 5), CFG, 2, "heun")


def test_ode_step_by_hand():
    """One probability-flow step written out: x + beta/2 (x + score) h."""
    x1, hist = vp.sample(exact_eps, key(6), (4,), CFG, 2, "ode", return_history=True)
    x = jax.random.normal(jax.random.split(key(6))[0], (4,))
    ts = np.linspace(1.0, CFG.sample_eps, 3)
    for k in range(2):
        t, h = ts[k], ts[k] - ts[k + 1]
        score = -exact_eps(x, t) / vp.marginal_std(t, CFG)
        x = x + 0.5 * vp.beta(t, CFG) * (x + score) * h
        np.testing.assert_allclose(hist[k], x, rtol=1e-5, atol=1e-6)
