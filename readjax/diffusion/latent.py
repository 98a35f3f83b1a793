"""The latent space READ's SDE runs in (METHOD.md section 5): the autoencoder's code, standardised.

    z = (code(M) - mean) / std          M = decode(z * std + mean)

``mean`` and ``std`` are per latent dimension, measured on the training set's motions once the
autoencoder is trained (``RUN/latent_stats.json``), with ``sde.latent_norm``; without it they are
0 and 1 and z is the paper's raw code.

Why: the SDE adds isotropic noise of level lam (0.5) to z. A raw 32-d code is far from isotropic:
on reach_target (cpu preset, 1000 demos) three dimensions spread by 1.0-1.3, the other 29 by
0.03-0.1, and a demo's nearest neighbour differs from it by 0.045 (RMS per dimension). lam = 0.5
then buries 29 of 32 dimensions under noise 5-15 times their whole range at every training time
t > 0.1, so the denoiser trains on decoded motions that are mostly noise, samples its image
features at meaningless points, and at inference meets clean latents it has hardly seen. On the
standardised latent, lam = 0.5 means half the data's spread in every dimension — what the paper's
Table 7 values (0.1, 0.5, 1.0) assume. This is the scale factor of latent diffusion models
(Rombach et al. 2022), per dimension.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from readjax import stats_record

STATS_FILE = "latent_stats.json"
STD_FLOOR = 1e-3  # a collapsed dimension (constant code) stays finite; its noise in raw units is tiny


@struct.dataclass
class LatentStats:
    """Per-dimension mean and std (D,) of the autoencoder's code (a pytree: traced under jit)."""

    mean: jax.Array
    std: jax.Array

    @classmethod
    def identity(cls, dim: int) -> "LatentStats":
        """The paper's raw code."""
        return cls(jnp.zeros((dim,), jnp.float32), jnp.ones((dim,), jnp.float32))


def codec(ae, ae_params, stats: LatentStats | None):
    """(encode, decode) between motions (B, 101, 10) and SDE latents (B, D); ``stats=None`` is the
    raw code."""

    def encode(m):
        z = ae.apply(ae_params, m, method="code")
        return z if stats is None else (z - stats.mean) / stats.std

    def decode(z):
        return ae.apply(ae_params, z if stats is None else z * stats.std + stats.mean, method="decode")

    return encode, decode


def raw_codes(ae, ae_params, motions: np.ndarray, chunk: int = 256) -> np.ndarray:
    """The autoencoder's code (its posterior mean, deterministic) of every motion (N, D) float32,
    in fixed-size chunks."""
    code = jax.jit(lambda m: ae.apply(ae_params, m, method="code"))
    motions = np.asarray(motions, np.float32)
    return np.concatenate([np.asarray(code(jnp.asarray(motions[s:s + chunk])))
                           for s in range(0, len(motions), chunk)])


def measure(ae, ae_params, motions: np.ndarray, chunk: int = 256) -> LatentStats:
    """The training motions' code statistics (std floored at ``STD_FLOOR``)."""
    z = raw_codes(ae, ae_params, motions, chunk).astype(np.float64)
    return LatentStats(jnp.asarray(z.mean(0), jnp.float32),
                       jnp.asarray(np.maximum(z.std(0), STD_FLOOR), jnp.float32))


def codes(ae, ae_params, motions: np.ndarray, stats: LatentStats | None, chunk: int = 256) -> np.ndarray:
    """The SDE latents of every motion (N, D), as ``codec``'s encode returns them (``stats=None``:
    the raw code). Training stages whose autoencoder is frozen compute them once instead of
    encoding each sampled motion at every step (same values up to float rounding)."""
    z = raw_codes(ae, ae_params, motions, chunk)
    if stats is None:
        return z
    return ((z - np.asarray(stats.mean)) / np.asarray(stats.std)).astype(np.float32)


def write(run_dir: str | Path, stats: LatentStats) -> None:
    """Record the stats in the run; a run that already holds different ones is refused (they are a
    deterministic function of the trained autoencoder and the data, so a resumed run matches; other
    ones mean the autoencoder was retrained)."""
    stats_record.write(Path(run_dir) / STATS_FILE, stats.mean, stats.std, what="latent statistics", atol=1e-5,
                       std_floor=STD_FLOOR)


def read(run_dir: str | Path) -> LatentStats:
    mean, std = stats_record.read(Path(run_dir) / STATS_FILE, "latent statistics",
                                  " (its SDE runs on the standardised latent, sde.latent_norm); train the "
                                  "run's diffusion stage first")
    return LatentStats(jnp.asarray(mean), jnp.asarray(std))


def for_run(run_dir: str | Path, sde) -> LatentStats | None:
    """The stats a run's SDE uses: its recorded ones with ``sde.latent_norm``, else None (raw)."""
    return read(run_dir) if sde.latent_norm else None
