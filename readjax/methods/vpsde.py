"""The VPSDE baseline (METHOD.md section 10, supplement section 7): READ's denoiser network with
``output="eps"`` trained on the VP SDE (beta linear 1 -> 20) with the eps-prediction loss, no
autoencoder, no retrieval; sampled from N(0, I) with the probability-flow ODE or the reverse SDE
(:mod:`readjax.diffusion.vpsde`). One resumable stage ``vpsde/``.

Motions are normalised per channel for the diffusion (:mod:`readjax.methods.common`; the stats are
in ``RUN/normalizer.json``): x0 = (M - mean) / std is noised, the denoiser's motion tokens embed
the normalised x_t while its image tokens are sampled at x_t's real (denormalised) uv, it predicts
eps in normalised units, and samples are denormalised at the end. The loss is the sum of per-key MSEs between the predicted
and the true noise (the released code's reduction). Time enters the denoiser as the raw t in [0, 1]
(READ's time features).

:mod:`readjax.methods.vpsde_cg` reuses everything here with the retrieved motion as condition.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jax
import jax.numpy as jnp

from readjax.config import VPSDEConfig
from readjax import motion as motion_lib
from readjax.diffusion import vpsde as vp
from readjax.methods import base, common
from readjax.methods.augment import augment_rgb
from readjax.models.denoiser import Denoiser

METHOD = "vpsde"
SECTIONS = ("denoiser", "vpsde")
STAGES = ("vpsde",)


def build_denoiser(configs: dict, cond: bool) -> Denoiser:
    return Denoiser(configs["denoiser"], use_cond=cond, output="eps")


def init_denoiser(den: Denoiser, image_size: int, key):
    k1, k2 = jax.random.split(key)
    m = jnp.zeros((1, motion_lib.FRAMES, motion_lib.DIM))
    kw = {"cond": m, "cond_keep": jnp.ones((1,), bool)} if den.use_cond else {}
    return den.init({"params": k1, "dropout": k2}, jnp.zeros((1, image_size, image_size, 4)), m, jnp.zeros((1,)),
                    **kw)


def eps_loss(den: Denoiser, cfg: VPSDEConfig, augment: bool):
    """E ||eps - eps_theta(I, M_t, t[, M_R])||^2 (per-key MSEs summed); with a conditional denoiser
    the retrieved motion is masked out with probability ``cfg.cond_drop``. The batch carries the
    normaliser (``common.batch_stats``)."""

    def loss_fn(params, batch, rng):
        k_t, k_n, k_aug, k_drop, k_keep = jax.random.split(rng, 5)
        image, m = batch["image"], batch["motion"]
        stats = common.stats_from_batch(batch)
        if augment:
            image = augment_rgb(k_aug, image)
        b = m.shape[0]
        t = vp.sample_time(k_t, (b,), cfg)
        x_t, eps = vp.marginal_sample(k_n, common.normalize(m, stats), t, cfg)
        kw = {}
        if den.use_cond:
            kw = {"cond": common.normalize(batch["retrieved"], stats),
                  "cond_keep": jax.random.uniform(k_keep, (b,)) >= cfg.cond_drop}
        pred = den.apply(params, image, x_t, t, train=True, rngs={"dropout": k_drop},
                         track=common.denormalize(x_t, stats), **kw)
        return common.per_key_mse(pred, eps)

    return loss_fn


def train_vpsde(method: str, task, data_root, run_dir, configs: dict, preset: str, stages, progress, stop_at,
                cond: bool) -> dict:
    run = common.prepare(method, task, data_root, run_dir, configs, preset, SECTIONS, configs["denoiser"].image_size)
    stats = common.fit_normalizer(run.run_dir, run.train_motions)
    den = build_denoiser(run.configs, cond)
    if method in stages:
        ds, train_cfg = run.ds, run.train_cfg
        spec = base.network_stage_spec(train_cfg)
        pairs = run.pairs() if cond else None
        norm = common.batch_stats(stats, spec.batch_size)

        def batch(idx, step, rows):
            out = {"image": ds.rgbd[idx[rows]], "motion": ds.motion[idx[rows]], "norm": norm[rows]}
            if cond:
                out["retrieved"] = ds.motion[base.neighbour_choice(pairs, idx, spec.seed, step)[rows]]
            return out

        run.fit(method, spec, init_denoiser(den, run.image_size, jax.random.key(train_cfg.seed + 1)),
                eps_loss(den, run.configs["vpsde"], train_cfg.augment), run.batches(spec, batch), progress, stop_at)
    return run.result()


def train(task: str, data_root: str | Path, run_dir: str | Path, configs: dict, preset: str,
          stages=STAGES, progress: bool = True, stop_at: int | None = None) -> dict:
    """Train the VPSDE baseline for a task (resumes from the latest checkpoint)."""
    return train_vpsde(METHOD, task, data_root, run_dir, configs, preset, stages, progress, stop_at, cond=False)


@functools.partial(jax.jit, static_argnames=("den", "n_steps", "cfg", "sampler", "guidance", "return_history"))
def sample(den: Denoiser, den_params, features, stats, m_r, key, n_steps: int, cfg: VPSDEConfig,
           sampler: str, guidance: float = 1.0, return_history: bool = False):
    """Motions (B, 101, 10) sampled from N(0, I) with ``n_steps`` steps of ``sampler``.

    With a conditional denoiser, M_R (``m_r``, raw units, normalised here) conditions the eps prediction with
    classifier-free guidance eps = w eps(cond) - (w - 1) eps(uncond) (w = ``guidance``; at w = 1 only
    the conditional branch is evaluated); the image tokens are in both branches. ``stats`` are the
    normaliser's (mean, std). ``m_r`` only fixes the batch shape for an unconditional denoiser.
    """
    b = m_r.shape[0]
    x_r = common.normalize(m_r, stats)

    def eps_fn(x, t):
        track = common.denormalize(x, stats)
        if not den.use_cond:
            return den.apply(den_params, features, x, t, track=track, method="denoise")

        def branch(keep):
            return den.apply(den_params, features, x, t, cond=x_r, cond_keep=jnp.full((b,), keep), track=track,
                             method="denoise")

        eps_c = branch(True)
        if guidance == 1.0:
            return eps_c
        return guidance * eps_c - (guidance - 1.0) * branch(False)

    out = vp.sample(eps_fn, key, m_r.shape, cfg, n_steps, sampler, return_history=return_history)
    if return_history:
        return common.denormalize(out[0], stats), common.denormalize(out[1], stats)
    return common.denormalize(out, stats)


class VPSDEModel(common.DenoiserRunModel):
    """A trained VPSDE run. ``sampler`` ("ode"/"sde") may be changed on the instance."""

    uses_retrieval = False
    method = METHOD
    cond = False

    def __init__(self, run_dir):
        super().__init__(run_dir)
        cfg = self.configs["vpsde"]
        self.vp_cfg = cfg
        self.sampler = cfg.sampler
        self.guidance = cfg.guidance
        self.den = build_denoiser(self.configs, self.cond)
        key = jax.random.key(self.configs["train"].seed + 1)
        self.den_params = self.network_params(self.method, init_denoiser(self.den, self.image_size, key))
        self.stats = tuple(jnp.asarray(s) for s in common.read_normalizer(self.run_dir))
        self._setup_encoder()

    def generate(self, features, retrieved, key, n_steps: int) -> jax.Array:
        n = common.check_n_steps(n_steps, allow_zero=self.cond, method=self.method)
        m_r = jnp.asarray(retrieved)
        if n == 0:
            return m_r
        return sample(self.den, self.den_params, features, self.stats, m_r, key, n, self.vp_cfg, self.sampler,
                      float(self.guidance) if self.cond else 1.0)
