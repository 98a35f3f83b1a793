"""The mean-reverting SDE: schedule, closed-form marginal, and agreement with Euler–Maruyama."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import SDEConfig
from readjax.diffusion import irsde

CFG = SDEConfig()  # lam 0.5, theta1 2, theta0 = lam


def key(seed):
    return jax.random.key(seed, impl="rbg")  # cheap to compile on the CPU (see tests/models/helpers.py)


def test_schedule():
    assert CFG.theta_start == 0.5
    assert SDEConfig(theta0=0.1).theta_start == 0.1
    np.testing.assert_allclose(irsde.theta(0.0, CFG), 0.5)
    np.testing.assert_allclose(irsde.theta(1.0, CFG), 2.0)
    # theta_bar is the integral of theta (trapezoid rule on a fine grid)
    ts = np.linspace(0, 0.7, 7001)
    np.testing.assert_allclose(irsde.theta_bar(0.7, CFG), np.trapezoid(np.asarray(irsde.theta(ts, CFG)), ts),
                               rtol=1e-6)
    np.testing.assert_allclose(irsde.mean_coef(0.0, CFG), 1.0)
    np.testing.assert_allclose(irsde.mean_coef(1.0, CFG), np.exp(-(0.5 + 0.75)), rtol=1e-6)
    np.testing.assert_allclose(irsde.sigma(0.3, CFG) ** 2, 2 * 0.25 * irsde.theta(0.3, CFG), rtol=1e-6)
    np.testing.assert_allclose(irsde.marginal_std(0.0, CFG), 0.0, atol=1e-7)


def test_marginal_sample_formula_and_broadcasting():
    z0 = jnp.arange(6.0).reshape(2, 3)
    zr = -jnp.ones((2, 3))
    t = jnp.array([0.25, 1.0])
    k = key(0)
    eps = jax.random.normal(k, z0.shape)
    a = irsde.mean_coef(t, CFG)[:, None]
    expect = zr + (z0 - zr) * a + 0.5 * jnp.sqrt(1 - a**2) * eps
    np.testing.assert_allclose(irsde.marginal_sample(k, z0, zr, t, CFG), expect, rtol=1e-6)
    # scalar t, and task-space shaped tensors (B, 101, 10)
    m = irsde.marginal_sample(k, jnp.zeros((2, 101, 10)), jnp.ones((2, 101, 10)), 0.5, CFG)
    assert m.shape == (2, 101, 10)
    with pytest.raises(ValueError):
        irsde.marginal_sample(k, z0, zr, jnp.ones(3), CFG)
    with pytest.raises(ValueError):
        irsde.marginal_sample(k, z0, zr[:1], 0.5, CFG)


def test_sample_time_range():
    t = irsde.sample_time(key(1), (10000,), CFG)
    assert float(t.min()) >= CFG.t_min and float(t.max()) <= 1.0
    assert abs(float(t.mean()) - 0.5) < 0.02


@pytest.mark.parametrize("cfg", [CFG, SDEConfig(lam=0.3, theta1=4.0, theta0=0.2)])
def test_marginal_agrees_with_euler_maruyama(cfg):
    """Simulate dz = theta (zR - z) dt + sigma dw from z0 and compare mean and std with the closed form."""
    n, steps = 20000, 400
    z0 = jnp.broadcast_to(jnp.array([1.0, -2.0, 0.5]), (n, 3))
    zr = jnp.broadcast_to(jnp.array([0.0, 1.0, 0.5]), (n, 3))
    simulate = jax.jit(lambda k: irsde.euler_maruyama(k, z0, zr, cfg, steps, return_path=True))
    path = simulate(key(2))  # (steps, n, 3)
    for t in (0.25, 1.0):
        z = path[int(round(t * steps)) - 1]
        mean, std = irsde.marginal_mean_std(z0[:1], zr[:1], t, cfg)
        # sampling error of the mean is std / sqrt(n) <= 0.0036; Euler's bias is O(dt)
        np.testing.assert_allclose(z.mean(0), mean[0], atol=0.015)
        np.testing.assert_allclose(z.std(0), np.broadcast_to(std[0], (3,)), rtol=0.03)
    # and the closed-form sampler reproduces the same statistics
    zs = irsde.marginal_sample(key(3), z0, zr, 1.0, cfg)
    np.testing.assert_allclose(zs.mean(0), path[-1].mean(0), atol=0.02)
    np.testing.assert_allclose(zs.std(0), path[-1].std(0), rtol=0.04)


def test_euler_maruyama_checks():
    with pytest.raises(ValueError):
        irsde.euler_maruyama(key(0), jnp.zeros(3), jnp.zeros(3), CFG, 0)
    z = irsde.euler_maruyama(key(0), jnp.zeros((4, 3)), jnp.zeros((4, 3)), CFG, 5)
    assert z.shape == (4, 3)


def test_config_validation():
    with pytest.raises(ValueError):
        SDEConfig(lam=0.0)
    with pytest.raises(ValueError):
        SDEConfig(t_min=1.5)
