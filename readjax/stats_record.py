"""Per-dimension (mean, std) statistics recorded in a run folder as JSON: the motion normaliser of
the task-space diffusion models (``normalizer.json``) and the latent statistics of READ's
standardised latent (``latent_stats.json``).

Both are a deterministic function of the training data (and, for the latent, of the trained
autoencoder), written when their stage starts; a resumed run recomputes them and must find the
same values, so a folder holding different ones is refused instead of silently mixing two runs.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from readjax import atomic_write, distributed
from readjax.training import CheckpointError


def write(path: Path, mean, std, what: str, atol: float, **extra) -> None:
    """Record ``mean``/``std`` (plus ``extra`` JSON fields) at ``path``; if the file exists, it must
    hold the same values within ``atol`` (``what`` names them in the error). In a multi-process
    training every process checks a recorded file and the primary writes a new one."""
    mean, std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
    if path.exists():
        old_mean, old_std = read(path, what, hint="")
        if not (np.allclose(old_mean, mean, atol=atol) and np.allclose(old_std, std, atol=atol)):
            raise CheckpointError(f"{path} holds other {what}; use a new --out/--name or --restart")
        return
    if distributed.is_primary():
        atomic_write.write_text(path, json.dumps({"mean": mean.tolist(), "std": std.tolist(), **extra}, indent=1))


def read(path: Path, what: str, hint: str) -> tuple[np.ndarray, np.ndarray]:
    """(mean, std) float32 from ``path``; a missing or unreadable file is a one-line error
    (``hint`` says how to make it)."""
    if not path.exists():
        raise CheckpointError(f"{path.parent} has no {path.name}{hint}")
    try:
        d = json.loads(path.read_text())
        return np.asarray(d["mean"], np.float32), np.asarray(d["std"], np.float32)
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
        raise CheckpointError(f"{path} is not a record of {what} ({type(e).__name__}: {e})") from e
