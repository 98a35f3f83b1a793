"""READ-L (METHOD.md section 10): forward AND reverse process in the autoencoder's latent space;
the output is Dec(ẑ0). Two resumable stages: ``vae/`` (READ's autoencoder stage, identical, so a
sweep can share it) and ``read_l/``.

Training (autoencoder frozen, carried in the train state under stop_gradient): z0 = Enc(M),
zR = Enc(M_R) with M_R drawn uniformly from the top-K ground-truth neighbours among the other
demos, t ~ U(t_min, 1), z_t from the latent IR-SDE marginal (section 5); the
:class:`~readjax.models.latent_denoiser.LatentDenoiser` reads the image features along Dec(z_t)'s
uv and predicts ẑ0; loss = MSE(ẑ0, z0) over the latent dims.

Inference: cold diffusion in latent space from zR (:func:`readjax.diffusion.taskspace.cold_diffusion`
on latents): ẑ0 = LD(F, z, Dec(z).uv, t_k), then the SDE's update as READ's loop runs it
(``sde.update``; the paper's "renoise": z = zR + (ẑ0 - zR) a(t_{k+1}) + lam sqrt(1 - a^2) eps);
return Dec(last ẑ0). N = 0 returns M_R. Retrieval is SPE on this run's own UNet features.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jax
import jax.numpy as jnp

from readjax import tasks
from readjax.config import SDEConfig
from readjax import motion as motion_lib
from readjax.diffusion import irsde, taskspace
from readjax.diffusion import latent as latent_lib
from readjax.methods import base, common
from readjax.methods import read as read_lib
from readjax.methods.augment import augment_rgb
from readjax.models.kinematic_vae import make_autoencoder
from readjax.models.latent_denoiser import LatentDenoiser

METHOD = "read_l"
SECTIONS = ("vae", "denoiser", "sde")
STAGES = ("vae", "read_l")


def build_modules(configs: dict, chain, camera):
    ae = make_autoencoder(configs["vae"], chain=chain, camera=camera)
    return ae, LatentDenoiser(configs["denoiser"], latent_dim=configs["vae"].latent_dim)


def init_latent_denoiser(lden: LatentDenoiser, image_size: int, key):
    k1, k2 = jax.random.split(key)
    return lden.init({"params": k1, "dropout": k2}, jnp.zeros((1, image_size, image_size, 4)),
                     jnp.zeros((1, lden.latent_dim)), jnp.zeros((1, motion_lib.FRAMES, 2)), jnp.zeros((1,)))


def read_l_loss(ae, lden: LatentDenoiser, sde: SDEConfig, augment: bool, latent=None):
    """MSE(ẑ0, z0) over the latent dims. ``params`` = {"denoiser": trained, "ae": frozen}: the frozen
    autoencoder rides in the train state under ``stop_gradient`` (zero gradients, so Adam leaves it
    exactly unchanged) — an argument of the jitted step, not a constant baked into it. With
    ``latent`` stats the latents are standardised (:mod:`readjax.diffusion.latent`). z0 and zR come
    precomputed in the batch (``code``, ``code_r``, as in READ's loss)."""

    def loss_fn(params, batch, rng):
        ae_params = jax.lax.stop_gradient(params["ae"])
        k_t, k_n, k_aug, k_drop = jax.random.split(rng, 4)
        image, z0, z_r = batch["image"], batch["code"], batch["code_r"]
        if augment:
            image = augment_rgb(k_aug, image)
        _, dec = latent_lib.codec(ae, ae_params, latent)
        t = irsde.sample_time(k_t, (z0.shape[0],), sde)
        z_t = irsde.marginal_sample(k_n, z0, z_r, t, sde)
        uv = motion_lib.uv(dec(z_t))
        pred = lden.apply(params["denoiser"], image, z_t, uv, t, train=True, rngs={"dropout": k_drop})
        mse = jnp.mean((pred - z0) ** 2)
        return mse, {"latent_mse": mse}

    return loss_fn


def train(task: str, data_root: str | Path, run_dir: str | Path, configs: dict, preset: str,
          stages=STAGES, progress: bool = True, stop_at: int | None = None, vae_from=None) -> dict:
    """Train READ-L for a task: the autoencoder (as READ's; ``vae_from`` as READ's), then the latent
    denoiser."""
    run = common.prepare(METHOD, task, data_root, run_dir, configs, preset, SECTIONS, configs["denoiser"].image_size,
                         check=read_lib.autoencoder_source_check(vae_from, run_dir))
    ae, lden, k_ae, k_den = read_lib.prepare_autoencoder(run, stages, progress, stop_at, build=build_modules,
                                                          vae_from=vae_from)
    if "read_l" in stages:
        ds, train_cfg, sde = run.ds, run.train_cfg, run.configs["sde"]
        ae_params = read_lib.autoencoder_params(run.run_dir, ae, k_ae, train_cfg, run.cfg_dict, ds.fingerprint)
        latent = read_lib.fit_latent_stats(run.run_dir, ae, ae_params, run.train_motions, sde)
        spec = base.network_stage_spec(train_cfg)
        params = {"denoiser": init_latent_denoiser(lden, run.image_size, k_den), "ae": ae_params}
        codes = latent_lib.codes(ae, ae_params, ds.motion, latent)
        run.fit("read_l", spec, params, read_l_loss(ae, lden, sde, train_cfg.augment, latent),
                base.paired_batch(ds, spec, run.pairs(), run.n_train, codes=codes), progress, stop_at)
    return run.result()


@functools.partial(jax.jit, static_argnames=("ae", "lden", "n_steps", "sde", "t_end", "return_history"))
def refine(ae, ae_params, lden: LatentDenoiser, lden_params, features, m_r, key, n_steps: int, sde: SDEConfig,
           t_end: float = taskspace.DEFAULT_T_END, return_history: bool = False, latent=None):
    """READ-L's latent cold diffusion from Enc(M_R); returns Dec(last ẑ0) (and every step's decoded
    ẑ0 with ``return_history``). N = 0 returns M_R. ``latent``: the run's latent statistics."""
    if n_steps == 0:
        hist = jnp.zeros((0,) + m_r.shape, m_r.dtype)
        return (m_r, hist) if return_history else m_r

    enc, dec = latent_lib.codec(ae, ae_params, latent)

    def x0_fn(z, t):
        return lden.apply(lden_params, features, z, motion_lib.uv(dec(z)), t, method="denoise")

    z_r = enc(m_r)
    _, hist = taskspace.cold_diffusion(x0_fn, key, z_r, sde, n_steps, t_end, return_history=True)
    if return_history:
        return dec(hist[-1]), jax.vmap(dec)(hist)
    return dec(hist[-1])


class ReadLModel(common.DenoiserRunModel):
    """A trained READ-L run."""

    uses_retrieval = True
    has_refine_update = True  # its latent CD loop runs sde.update

    def __init__(self, run_dir):
        super().__init__(run_dir)
        env = tasks.make(self.spec["task"])
        self.ae, self.den = build_modules(self.configs, env.chain, self.camera)
        train_cfg = self.configs["train"]
        k_ae, k_den = jax.random.split(jax.random.key(train_cfg.seed))
        template = {"denoiser": init_latent_denoiser(self.den, self.image_size, k_den),
                    "ae": read_lib.init_ae(self.ae, k_ae)}
        # the read_l checkpoint holds the (frozen) autoencoder it was trained with
        params = self.network_params("read_l", template)
        self.den_params, self.ae_params = params["denoiser"], params["ae"]
        self.latent = latent_lib.for_run(self.run_dir, self.configs["sde"])
        self._setup_encoder()

    def generate(self, features, retrieved, key, n_steps: int) -> jax.Array:
        n = common.check_n_steps(n_steps, allow_zero=True, method=METHOD)
        m_r = jnp.asarray(retrieved)
        if n == 0:
            return m_r
        return refine(self.ae, self.ae_params, self.den, self.den_params, features, m_r, key, n,
                      self.configs["sde"], latent=self.latent)
