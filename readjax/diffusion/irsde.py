"""The mean-reverting SDE of READ (METHOD.md section 5), in closed form and by Euler–Maruyama.

    dz = theta(t) (zR - z) dt + sigma(t) dw,   sigma(t)^2 = 2 lam^2 theta(t),   t in [0, 1]
    theta(t) = theta0 + t (theta1 - theta0)     (theta0 = lam unless set: the released code's quirk)
    theta_bar(t) = int_0^t theta = theta0 t + (theta1 - theta0) t^2 / 2
    a(t) = exp(-theta_bar(t))
    z_t | z0 ~ N(zR + (z0 - zR) a(t), lam^2 (1 - a(t)^2) I)

It drives z0 (the latent of the true motion) towards the retrieved latent zR with stationary
noise level lam. Everything here is shape-agnostic: latents (B, D) or task-space motions
(B, 101, 10) alike; ``t`` is a scalar or has the batch shape and broadcasts over trailing axes.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from readjax.config import SDEConfig


def _bcast(t, x: jax.Array) -> jax.Array:
    """t (scalar or x's leading axes) reshaped to broadcast against x."""
    t = jnp.asarray(t, x.dtype)
    if t.ndim > x.ndim or x.shape[: t.ndim] != t.shape:
        raise ValueError(f"t of shape {t.shape} does not match the leading axes of {x.shape}")
    return t.reshape(t.shape + (1,) * (x.ndim - t.ndim))


def theta(t, cfg: SDEConfig) -> jax.Array:
    """theta(t) = theta0 + t (theta1 - theta0)."""
    t = jnp.asarray(t, jnp.float32)
    return cfg.theta_start + t * (cfg.theta1 - cfg.theta_start)


def theta_bar(t, cfg: SDEConfig) -> jax.Array:
    """Integral of theta from 0 to t."""
    t = jnp.asarray(t, jnp.float32)
    return cfg.theta_start * t + 0.5 * (cfg.theta1 - cfg.theta_start) * t**2


def mean_coef(t, cfg: SDEConfig) -> jax.Array:
    """a(t) = exp(-theta_bar(t)): the weight left on z0 - zR at time t."""
    return jnp.exp(-theta_bar(t, cfg))


def sigma(t, cfg: SDEConfig) -> jax.Array:
    """Diffusion coefficient sqrt(2 lam^2 theta(t))."""
    return jnp.sqrt(2.0 * cfg.lam**2 * theta(t, cfg))


def marginal_std(t, cfg: SDEConfig) -> jax.Array:
    """lam sqrt(1 - a(t)^2)."""
    a = mean_coef(t, cfg)
    return cfg.lam * jnp.sqrt(jnp.maximum(1.0 - a**2, 0.0))


def marginal_mean_std(z0: jax.Array, zR: jax.Array, t, cfg: SDEConfig) -> tuple[jax.Array, jax.Array]:
    """Mean (z0's shape) and std (broadcastable) of z_t given z0 and zR."""
    if z0.shape != zR.shape:
        raise ValueError(f"z0 {z0.shape} and zR {zR.shape} must have the same shape")
    tb = _bcast(t, z0)
    a = mean_coef(tb, cfg)
    return zR + (z0 - zR) * a, marginal_std(tb, cfg)


def marginal_sample(key: jax.Array, z0: jax.Array, zR: jax.Array, t, cfg: SDEConfig) -> jax.Array:
    """z_t = zR + (z0 - zR) a(t) + lam sqrt(1 - a(t)^2) eps,  eps ~ N(0, I)."""
    mean, std = marginal_mean_std(z0, zR, t, cfg)
    return mean + std * jax.random.normal(key, z0.shape, z0.dtype)


def sample_time(key: jax.Array, shape, cfg: SDEConfig) -> jax.Array:
    """Training times t ~ U(t_min, 1)."""
    return jax.random.uniform(key, shape, jnp.float32, cfg.t_min, 1.0)


def euler_maruyama(key: jax.Array, z0: jax.Array, zR: jax.Array, cfg: SDEConfig, n_steps: int,
                   t_end: float = 1.0, return_path: bool = False):
    """Simulate the forward SDE from z0 at t=0 to ``t_end`` with ``n_steps`` Euler–Maruyama steps.

    Returns z(t_end) (z0's shape) or, with ``return_path``, the states after every step
    (n_steps, *z0.shape). ``n_steps`` is static (it sets the scan length).
    """
    if z0.shape != zR.shape:
        raise ValueError(f"z0 {z0.shape} and zR {zR.shape} must have the same shape")
    if n_steps <= 0:
        raise ValueError(f"n_steps must be positive, got {n_steps}")
    dt = t_end / n_steps
    ts = jnp.arange(n_steps, dtype=jnp.float32) * dt
    keys = jax.random.split(key, n_steps)

    def step(z, inp):
        t, k = inp
        dw = jnp.sqrt(dt) * jax.random.normal(k, z.shape, z.dtype)
        z = z + theta(t, cfg) * (zR - z) * dt + sigma(t, cfg) * dw
        return z, z

    z, path = jax.lax.scan(step, z0, (ts, keys))
    return path if return_path else z


def cold_update(x, x0, x_r, t, t_next, k, cfg: SDEConfig):
    """One step of the cold-diffusion updates (``cfg.update`` "cold" or "cold_anchor") on the
    degradation D(x0, t) = x_R + (x0 - x_R) a(t), for a state x (a latent or a motion), the step's
    prediction x0 and its index k: "cold" moves x by the change of the degradation, x + (x0 - x_R)
    (a(t_next) - a(t)) (Bansal et al. 2022, Algorithm 2); "cold_anchor" sets the first step (k = 0)
    to D(x0, t_next) instead. No noise. The one home of the update READ's loop
    (:mod:`readjax.diffusion.refine`) and the ablations' (:mod:`readjax.diffusion.taskspace`) run."""
    a_next = mean_coef(t_next, cfg)
    moved = x + (x0 - x_r) * (a_next - mean_coef(t, cfg))
    if cfg.update == "cold_anchor":
        moved = jnp.where(k == 0, x_r + (x0 - x_r) * a_next, moved)
    return moved
