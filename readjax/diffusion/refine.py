"""READ's refinement at inference (METHOD.md section 8): cold diffusion in latent space.

    t_k = linspace(1, t_end, N + 1);  zR = Enc(M_R);  x = M_R
    for k in 0 .. N-1:
        M_t  = Dec(Enc(x))
        M̂0  = D(F, M_t, t_k)                         (the denoiser, image features F fixed)
        z'   = zR + (Enc(M̂0) - zR) a(t_{k+1}) + lam sqrt(1 - a(t_{k+1})^2) eps
        x    = Dec(z')
    return the last M̂0        (N = 0: M_R unchanged)

That is the paper's loop (``sde.update = "renoise"``). Measured on reach_target it walks away
from a correct answer as N grows: at small t the re-noised latent is the denoiser's own
prediction, so any bias of the delta is added again at every step. ``sde.update = "cold"`` is the
improved cold-diffusion update (Bansal et al. 2022, Algorithm 2) on the same degradation
D(z0, t) = zR + (z0 - zR) a(t)::

    z = zR
    for k in 0 .. N-1:
        M̂0 = D(F, Dec(z), t_k)
        z  = z - D(Enc(M̂0), t_k) + D(Enc(M̂0), t_{k+1}) = z + (Enc(M̂0) - zR) (a(t_{k+1}) - a(t_k))
    return the last M̂0

Each step moves z only by the change of the degradation, so a biased prediction shifts the latent
by that bias times a small weight instead of replacing it; the first step is the same in both.
Started at zR, the steps add up to (Enc(M̂0) - zR)(a(t_end) - a(1)): the part a(1) of the
correction (exp(-1.25) = 0.29 at the default SDE) is never applied, because zR is not the
degradation of the answer at t = 1 (a(1) > 0). ``sde.update = "cold_anchor"`` removes that gap:
its first step sets z = D(Enc(M̂0), t_1) (the paper's first step without noise), the later steps
are the cold update.

Enc is the autoencoder's posterior mean, standardised per dimension when the run's SDE uses
``sde.latent_norm`` (``latent``: :mod:`readjax.diffusion.latent`; None = the paper's raw code,
and Dec undoes the standardisation). One jitted ``lax.scan`` over the N steps (N static),
batched over B; the image feature map F is computed once beforehand by
``Denoiser.encode_image`` and reused at every step. The modules are static arguments (Flax
modules and configs hash by value); parameters, features, M_R and the key are traced.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from readjax.config import SDEConfig
from readjax.diffusion import irsde
from readjax.diffusion.latent import LatentStats, codec
from readjax.motion import check_motion_shape

DEFAULT_T_END = 1e-3


def time_grid(n_steps: int, t_end: float = DEFAULT_T_END) -> jax.Array:
    """The N + 1 refinement times from 1 down to ``t_end``."""
    return jnp.linspace(1.0, t_end, n_steps + 1, dtype=jnp.float32)


@functools.partial(jax.jit, static_argnames=("ae", "denoiser", "n_steps", "sde", "t_end", "return_history"))
def refine(ae, ae_params, denoiser, den_params, features: jax.Array, m_r: jax.Array, key: jax.Array,
           n_steps: int, sde: SDEConfig, t_end: float = DEFAULT_T_END, return_history: bool = False,
           latent: LatentStats | None = None):
    """Refine retrieved motions M_R (B, 101, 10) into M̂0 (B, 101, 10) with ``n_steps`` steps.

    Args:
      ae, ae_params: an autoencoder from ``make_autoencoder`` and its variables.
      denoiser, den_params: a :class:`readjax.models.denoiser.Denoiser` (``output="delta"``) and
        its variables.
      features: the image feature maps (B, H, W, C) from ``Denoiser.encode_image``.
      m_r: the retrieved motions.
      key: PRNG key; the same key gives the same result.
      n_steps: N (static). 0 returns ``m_r`` unchanged.
      sde: the SDE the denoiser was trained with.
      return_history: also return every step's M̂0, shape (N, B, 101, 10).
      latent: the run's latent statistics (``latent.for_run``); None = the raw code.
    """
    check_motion_shape(m_r, "m_r")
    if not isinstance(n_steps, int) or n_steps < 0:
        raise ValueError(f"n_steps must be a non-negative int, got {n_steps!r}")
    if getattr(denoiser, "output", "delta") != "delta":
        raise ValueError("refine needs a Denoiser with output='delta' (it predicts M̂0)")
    if features.ndim != 4 or features.shape[0] != m_r.shape[0]:
        raise ValueError(f"features must have shape (B={m_r.shape[0]}, H, W, C), got {features.shape}")

    if n_steps == 0:
        hist = jnp.zeros((0,) + m_r.shape, m_r.dtype)
        return (m_r, hist) if return_history else m_r

    enc, dec = codec(ae, ae_params, latent)
    ts = time_grid(n_steps, t_end)
    z_r = enc(m_r)

    if sde.update in ("cold", "cold_anchor"):

        def cold_step(z, inp):
            t, t_next, k = inp
            m0 = denoiser.apply(den_params, features, dec(z), t, method="denoise")
            return irsde.cold_update(z, enc(m0), z_r, t, t_next, k, sde), m0

        _, hist = jax.lax.scan(cold_step, z_r, (ts[:-1], ts[1:], jnp.arange(n_steps)))
        return (hist[-1], hist) if return_history else hist[-1]

    def step(x, inp):
        t, t_next, k = inp
        m_t = dec(enc(x))
        m0 = denoiser.apply(den_params, features, m_t, t, method="denoise")
        z = irsde.marginal_sample(k, enc(m0), z_r, t_next, sde)
        return dec(z), m0

    _, hist = jax.lax.scan(step, m_r, (ts[:-1], ts[1:], jax.random.split(key, n_steps)))
    return (hist[-1], hist) if return_history else hist[-1]
