"""READ-O (METHOD.md section 10): READ's mean-reverting SDE and refinement entirely in task space,
without the autoencoder. One resumable stage ``read_o/``.

Forward: on per-channel normalised motions (:mod:`readjax.methods.common`),
x_t = x_R + (x0 - x_R) a(t) + lam sqrt(1 - a(t)^2) eps with the ``sde`` section's schedule; M_R
drawn uniformly from the top-K ground-truth neighbours among the other demos, t ~ U(t_min, 1).
The denoiser (READ's network) embeds the normalised x_t and samples its image tokens at x_t's real
uv. ``read_o.sampler`` picks the training target and the sampler (:mod:`readjax.diffusion.taskspace`):

* ``cd``: ``output="delta"``, x̂0 = x_t + heads (normalised); loss = sum of per-key MSE between the
  denormalised x̂0 and M, in raw units (READ's loss); cold-diffusion refinement from x_R (section 8
  without Enc/Dec, with READ's inference update ``sde.update``);
* ``em``: ``output="eps"``; loss = sum of per-key MSE(eps_hat, eps) (normalised units);
  Euler-Maruyama on the reverse SDE from x_R + std(1) eps.

Test-time retrieval is SPE with this run's denoiser features, as READ's; N = 0 returns M_R.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jax
import jax.numpy as jnp

from readjax.config import SDEConfig
from readjax import motion as motion_lib
from readjax.diffusion import irsde, taskspace
from readjax.methods import base, common
from readjax.methods.augment import augment_rgb
from readjax.models.denoiser import Denoiser

METHOD = "read_o"
SECTIONS = ("denoiser", "sde", "read_o")
STAGES = ("read_o",)


def build_denoiser(configs: dict) -> Denoiser:
    return Denoiser(configs["denoiser"], output="delta" if configs["read_o"].sampler == "cd" else "eps")


def init_denoiser(den: Denoiser, image_size: int, key):
    k1, k2 = jax.random.split(key)
    return den.init({"params": k1, "dropout": k2}, jnp.zeros((1, image_size, image_size, 4)),
                    jnp.zeros((1, motion_lib.FRAMES, motion_lib.DIM)), jnp.zeros((1,)))


def read_o_loss(den: Denoiser, sde: SDEConfig, augment: bool):
    """The ``read_o.sampler``'s loss (see the module docstring); the batch carries the normaliser."""

    def loss_fn(params, batch, rng):
        k_t, k_n, k_aug, k_drop = jax.random.split(rng, 4)
        image, m = batch["image"], batch["motion"]
        stats = common.stats_from_batch(batch)
        if augment:
            image = augment_rgb(k_aug, image)
        x0, x_r = common.normalize(m, stats), common.normalize(batch["retrieved"], stats)
        t = irsde.sample_time(k_t, (m.shape[0],), sde)
        mean, std = irsde.marginal_mean_std(x0, x_r, t, sde)
        eps = jax.random.normal(k_n, x0.shape, x0.dtype)
        x_t = mean + std * eps
        pred = den.apply(params, image, x_t, t, train=True, rngs={"dropout": k_drop},
                         track=common.denormalize(x_t, stats))
        if den.output == "delta":
            return common.per_key_mse(common.denormalize(pred, stats), m)
        return common.per_key_mse(pred, eps)

    return loss_fn


def train(task: str, data_root: str | Path, run_dir: str | Path, configs: dict, preset: str,
          stages=STAGES, progress: bool = True, stop_at: int | None = None) -> dict:
    """Train READ-O (the ``read_o.sampler``'s target) for a task; resumes from the latest checkpoint."""
    run = common.prepare(METHOD, task, data_root, run_dir, configs, preset, SECTIONS, configs["denoiser"].image_size)
    stats = common.fit_normalizer(run.run_dir, run.train_motions)
    den = build_denoiser(run.configs)
    if "read_o" in stages:
        ds, train_cfg = run.ds, run.train_cfg
        spec = base.network_stage_spec(train_cfg)
        batch = base.paired_batch(ds, spec, run.pairs(), run.n_train, norm=common.batch_stats(stats, spec.batch_size))
        run.fit("read_o", spec, init_denoiser(den, run.image_size, jax.random.key(train_cfg.seed + 1)),
                read_o_loss(den, run.configs["sde"], train_cfg.augment), batch, progress, stop_at)
    return run.result()


@functools.partial(jax.jit, static_argnames=("den", "n_steps", "sde", "t_end", "return_history"))
def refine(den: Denoiser, den_params, features, stats, m_r, key, n_steps: int, sde: SDEConfig,
           t_end: float = taskspace.DEFAULT_T_END, return_history: bool = False):
    """READ-O's sampler for M_R (B, 101, 10), raw units in and out: CD for a delta denoiser, reverse
    Euler-Maruyama for an eps denoiser. N = 0 returns M_R."""
    x_r = common.normalize(m_r, stats)

    def net(x, t):  # x̂0 (delta denoiser) or eps, normalised units
        return den.apply(den_params, features, x, t, track=common.denormalize(x, stats), method="denoise")

    if den.output == "delta":
        out = taskspace.cold_diffusion(net, key, x_r, sde, n_steps, t_end, return_history)
    else:
        out = taskspace.reverse_em(net, key, x_r, sde, n_steps, t_end, return_history)
    if return_history:
        return common.denormalize(out[0], stats), common.denormalize(out[1], stats)
    return common.denormalize(out, stats)


class ReadOModel(common.DenoiserRunModel):
    """A trained READ-O run (sampler fixed at training: ``read_o.sampler``)."""

    uses_retrieval = True

    def __init__(self, run_dir):
        super().__init__(run_dir)
        self.sampler = self.configs["read_o"].sampler
        self.has_refine_update = self.sampler == "cd"  # CD runs sde.update; EM samples the reverse SDE
        self.den = build_denoiser(self.configs)
        key = jax.random.key(self.configs["train"].seed + 1)
        self.den_params = self.network_params("read_o", init_denoiser(self.den, self.image_size, key))
        self.stats = tuple(jnp.asarray(s) for s in common.read_normalizer(self.run_dir))
        self._setup_encoder()

    def generate(self, features, retrieved, key, n_steps: int) -> jax.Array:
        n = common.check_n_steps(n_steps, allow_zero=True, method=METHOD)
        m_r = jnp.asarray(retrieved)
        if n == 0:
            return m_r
        return refine(self.den, self.den_params, features, self.stats, m_r, key, n, self.configs["sde"])
