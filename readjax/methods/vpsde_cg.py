"""The VPSDE+CG baseline (METHOD.md section 10, supplement section 7): VPSDE whose denoiser also
sees the retrieved motion M_R (``Denoiser(use_cond=True)``: M_R embedded by its own MLP and
appended as 101 tokens), masked out of attention with probability ``vpsde.cond_drop`` (0.1) in
training so the same network also learns the unconditional eps. Sampling uses classifier-free
guidance eps = w eps(I, M_t, M_R, t) - (w - 1) eps(I, M_t, t), w = ``vpsde.guidance`` (1.0); the
image tokens are kept in both branches (the released code drops them in one, a bug).

Training pairs are READ's (M_R drawn uniformly from the top-K ground-truth neighbours among the
other demos); at test time M_R is retrieved by SPE with this run's own image features, as READ
does. One resumable stage ``vpsde_cg/``; everything else is :mod:`readjax.methods.vpsde`.
N = 0 returns the retrieved motion.
"""

from __future__ import annotations

from pathlib import Path

from readjax.methods import vpsde

METHOD = "vpsde_cg"
STAGES = ("vpsde_cg",)


def train(task: str, data_root: str | Path, run_dir: str | Path, configs: dict, preset: str,
          stages=STAGES, progress: bool = True, stop_at: int | None = None) -> dict:
    """Train VPSDE+CG for a task (resumes from the latest checkpoint)."""
    return vpsde.train_vpsde(METHOD, task, data_root, run_dir, configs, preset, stages, progress, stop_at,
                             cond=True)


class VPSDECGModel(vpsde.VPSDEModel):
    """A trained VPSDE+CG run; ``guidance`` (w) and ``sampler`` may be changed on the instance."""

    uses_retrieval = True
    method = METHOD
    cond = True
