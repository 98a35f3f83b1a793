"""READ-O's samplers (METHOD.md section 10): READ's mean-reverting SDE run on motions themselves.

The forward process is :mod:`readjax.diffusion.irsde` applied to (normalised) task-space motions,
x_t = x_R + (x0 - x_R) a(t) + lam sqrt(1 - a(t)^2) eps. On the grid t_k = linspace(1, t_end, N + 1):

* ``cold_diffusion`` (CD, predict x0; READ's refinement, section 8, without Enc/Dec), with the
  SDE's ``update`` as READ's loop (:mod:`readjax.diffusion.refine`) so an ablation differs from READ
  only where it says:
      "renoise" (the paper):  x = x_R;  for k: x0_hat = x0_fn(x, t_k);
                              x = x_R + (x0_hat - x_R) a(t_{k+1}) + lam sqrt(1 - a^2) eps
      "cold":                 x <- x + (x0_hat - x_R) (a(t_{k+1}) - a(t_k))   (Bansal et al., Alg. 2)
      "cold_anchor":          the first step x = x_R + (x0_hat - x_R) a(t_1), then "cold"
      return the last x0_hat                                   (N = 0: x_R)
* ``reverse_em`` (Euler-Maruyama on the reverse-time SDE with a noise-predicting model):
      dx = [theta(t) (x_R - x) - sigma(t)^2 score] dt + sigma(t) dw_bar,  score = -eps_hat / std(t)
      x(1) = x_R + std(1) eps (the t = 1 marginal with x0 replaced by x_R);  step h = t_k - t_{k+1}:
      x <- x - [theta (x_R - x) - sigma^2 score] h + sigma sqrt(h) z      (no noise on the last step)
      return x                                                 (N = 0: x_R)

``x0_fn`` / ``eps_fn`` are ``(x, t) -> array`` closures over traced parameters, called inside the
caller's jit; each sampler is one ``lax.scan`` (N static). Shapes are arbitrary (the state has x_R's
shape).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp

from readjax.config import SDEConfig
from readjax.diffusion import irsde

DEFAULT_T_END = 1e-3


def time_grid(n_steps: int, t_end: float = DEFAULT_T_END) -> jax.Array:
    return jnp.linspace(1.0, t_end, n_steps + 1, dtype=jnp.float32)


def _check_steps(n_steps) -> None:
    if not isinstance(n_steps, int) or n_steps < 0:
        raise ValueError(f"n_steps must be a non-negative int, got {n_steps!r}")


def cold_diffusion(x0_fn: Callable, key: jax.Array, x_r: jax.Array, cfg: SDEConfig, n_steps: int,
                   t_end: float = DEFAULT_T_END, return_history: bool = False):
    """CD refinement of x_R: returns the last x0 estimate (and every step's, with ``return_history``)."""
    _check_steps(n_steps)
    if n_steps == 0:
        hist = jnp.zeros((0,) + x_r.shape, x_r.dtype)
        return (x_r, hist) if return_history else x_r
    ts = time_grid(n_steps, t_end)

    if cfg.update in ("cold", "cold_anchor"):

        def cold_step(x, inp):
            t, t_next, k = inp
            x0 = x0_fn(x, t)
            return irsde.cold_update(x, x0, x_r, t, t_next, k, cfg), x0

        _, hist = jax.lax.scan(cold_step, x_r, (ts[:-1], ts[1:], jnp.arange(n_steps)))
        return (hist[-1], hist) if return_history else hist[-1]

    def step(x, inp):
        t, t_next, k = inp
        x0 = x0_fn(x, t)
        return irsde.marginal_sample(k, x0, x_r, t_next, cfg), x0

    _, hist = jax.lax.scan(step, x_r, (ts[:-1], ts[1:], jax.random.split(key, n_steps)))
    return (hist[-1], hist) if return_history else hist[-1]


def reverse_em(eps_fn: Callable, key: jax.Array, x_r: jax.Array, cfg: SDEConfig, n_steps: int,
               t_end: float = DEFAULT_T_END, return_history: bool = False):
    """Euler-Maruyama on the reverse mean-reverting SDE from x(1) = x_R + std(1) eps."""
    _check_steps(n_steps)
    if n_steps == 0:
        hist = jnp.zeros((0,) + x_r.shape, x_r.dtype)
        return (x_r, hist) if return_history else x_r
    k_init, k_steps = jax.random.split(key)
    x = x_r + irsde.marginal_std(1.0, cfg) * jax.random.normal(k_init, x_r.shape, x_r.dtype)
    ts = time_grid(n_steps, t_end)
    last = jnp.arange(n_steps) == n_steps - 1

    def step(x, inp):
        t, t_next, k, is_last = inp
        h = t - t_next
        score = -eps_fn(x, t) / irsde.marginal_std(t, cfg)
        g = irsde.sigma(t, cfg)
        drift = irsde.theta(t, cfg) * (x_r - x) - g**2 * score
        noise = g * jnp.sqrt(h) * jax.random.normal(k, x.shape, x.dtype)
        x = x - drift * h + jnp.where(is_last, 0.0, 1.0) * noise
        return x, x

    x, hist = jax.lax.scan(step, x, (ts[:-1], ts[1:], jax.random.split(k_steps, n_steps), last))
    return (x, hist) if return_history else x
