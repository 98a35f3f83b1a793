"""The variance-preserving SDE of the VPSDE baselines (METHOD.md section 10; Song et al. 2021).

    dx = -1/2 beta(t) x dt + sqrt(beta(t)) dw,   t in [0, 1]
    beta(t) = beta_min + t (beta_max - beta_min)          (1 -> 20 in the paper)
    B(t) = int_0^t beta = beta_min t + (beta_max - beta_min) t^2 / 2
    x_t | x0 ~ N(alpha(t) x0, s(t)^2 I),   alpha = exp(-B/2),   s = sqrt(1 - exp(-B))

A noise-predicting model eps(x_t, t) gives the score -eps / s(t). Two samplers run from
x(1) ~ N(0, I) down to t = ``sample_eps`` on the grid linspace(1, sample_eps, N + 1), each one
``lax.scan`` (N static), with step h = t_k - t_{k+1} > 0:

* probability-flow ODE (Euler):  x <- x + 1/2 beta(t_k) (x + score) h
* reverse SDE (Euler-Maruyama):  x <- x + beta(t_k) (x / 2 + score) h + sqrt(beta(t_k) h) z
  (the last step adds no noise: it returns the mean, as Song et al.'s samplers do).

Everything is shape-agnostic (``t`` scalar or the batch shape, broadcast over trailing axes). The
samplers take ``eps_fn(x, t) -> eps`` (t a scalar): a closure over traced parameters, called inside
the caller's jit.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp

from readjax.config import VPSDE_SAMPLERS, VPSDEConfig
from readjax.diffusion.irsde import _bcast


def beta(t, cfg: VPSDEConfig) -> jax.Array:
    """beta(t) = beta_min + t (beta_max - beta_min)."""
    t = jnp.asarray(t, jnp.float32)
    return cfg.beta_min + t * (cfg.beta_max - cfg.beta_min)


def beta_integral(t, cfg: VPSDEConfig) -> jax.Array:
    """B(t) = int_0^t beta."""
    t = jnp.asarray(t, jnp.float32)
    return cfg.beta_min * t + 0.5 * (cfg.beta_max - cfg.beta_min) * t**2


def mean_coef(t, cfg: VPSDEConfig) -> jax.Array:
    """alpha(t) = exp(-B(t) / 2)."""
    return jnp.exp(-0.5 * beta_integral(t, cfg))


def marginal_std(t, cfg: VPSDEConfig) -> jax.Array:
    """s(t) = sqrt(1 - exp(-B(t)))."""
    return jnp.sqrt(-jnp.expm1(-beta_integral(t, cfg)))


def marginal_mean_std(x0: jax.Array, t, cfg: VPSDEConfig) -> tuple[jax.Array, jax.Array]:
    """Mean (x0's shape) and std (broadcastable) of x_t given x0."""
    tb = _bcast(t, x0)
    return mean_coef(tb, cfg) * x0, marginal_std(tb, cfg)


def marginal_sample(key: jax.Array, x0: jax.Array, t, cfg: VPSDEConfig) -> tuple[jax.Array, jax.Array]:
    """(x_t, eps) with x_t = alpha(t) x0 + s(t) eps, eps ~ N(0, I)."""
    mean, std = marginal_mean_std(x0, t, cfg)
    eps = jax.random.normal(key, x0.shape, x0.dtype)
    return mean + std * eps, eps


def sample_time(key: jax.Array, shape, cfg: VPSDEConfig) -> jax.Array:
    """Training times t ~ U(train_eps, 1)."""
    return jax.random.uniform(key, shape, jnp.float32, cfg.train_eps, 1.0)


def euler_maruyama(key: jax.Array, x0: jax.Array, cfg: VPSDEConfig, n_steps: int, t_end: float = 1.0,
                   return_path: bool = False):
    """Simulate the FORWARD SDE from x0 at t = 0 to ``t_end`` (tests of the closed form)."""
    if n_steps <= 0:
        raise ValueError(f"n_steps must be positive, got {n_steps}")
    dt = t_end / n_steps
    ts = jnp.arange(n_steps, dtype=jnp.float32) * dt

    def step(x, inp):
        t, k = inp
        b = beta(t, cfg)
        x = x - 0.5 * b * x * dt + jnp.sqrt(b * dt) * jax.random.normal(k, x.shape, x.dtype)
        return x, x

    x, path = jax.lax.scan(step, x0, (ts, jax.random.split(key, n_steps)))
    return path if return_path else x


def time_grid(n_steps: int, t_end: float) -> jax.Array:
    """The N + 1 sampling times from 1 down to ``t_end``."""
    return jnp.linspace(1.0, t_end, n_steps + 1, dtype=jnp.float32)


def sample(eps_fn: Callable[[jax.Array, jax.Array], jax.Array], key: jax.Array, shape, cfg: VPSDEConfig,
           n_steps: int, sampler: str | None = None, return_history: bool = False):
    """Sample from x(1) ~ N(0, I) with ``n_steps`` (static) steps of the ODE or reverse-SDE sampler.

    ``sampler`` defaults to ``cfg.sampler``. With ``return_history`` also returns the state after
    every step (n_steps, *shape). The same key gives the same result; the ODE sampler uses the key
    only for the initial noise.
    """
    sampler = cfg.sampler if sampler is None else sampler
    if sampler not in VPSDE_SAMPLERS:
        raise ValueError(f"sampler must be one of {VPSDE_SAMPLERS}, got {sampler!r}")
    if not isinstance(n_steps, int) or n_steps < 1:
        raise ValueError(f"n_steps must be a positive int, got {n_steps!r}")
    k_init, k_steps = jax.random.split(key)
    x = jax.random.normal(k_init, shape, jnp.float32)
    ts = time_grid(n_steps, cfg.sample_eps)
    last = jnp.arange(n_steps) == n_steps - 1

    def step(x, inp):
        t, t_next, k, is_last = inp
        h = t - t_next
        b = beta(t, cfg)
        score = -eps_fn(x, t) / marginal_std(t, cfg)
        if sampler == "ode":
            x = x + 0.5 * b * (x + score) * h
        else:
            mean = x + b * (0.5 * x + score) * h
            noise = jnp.sqrt(b * h) * jax.random.normal(k, x.shape, x.dtype)
            x = mean + jnp.where(is_last, 0.0, 1.0) * noise
        return x, x

    x, hist = jax.lax.scan(step, x, (ts[:-1], ts[1:], jax.random.split(k_steps, n_steps), last))
    return (x, hist) if return_history else x
