"""READ: train the motion autoencoder, then the latent-noised task-space denoiser (METHOD.md
sections 4-6), in two resumable stages of one run folder (``vae/``, ``read/``)."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import jax
import jax.numpy as jnp

from readjax import config, tasks, training
from readjax import motion as motion_lib
from readjax.diffusion import irsde
from readjax.diffusion import latent as latent_lib
from readjax.diffusion.refine import refine
from readjax.methods import base, common
from readjax.methods.augment import augment_rgb
from readjax.models.denoiser import Denoiser
from readjax.models.kinematic_vae import make_autoencoder
from readjax.models.vae import weighted_motion_loss

STAGES = ("vae", "read")


@functools.cache
def task_chain(task: str):
    """The arm's kinematic chain of ``task`` (what the autoencoder needs) from its MuJoCo model alone:
    training builds no simulator (a task's MJX environment is placed on ``jax.devices()[0]``, another
    process's device in a multi-process training)."""
    from readjax.sim.kinematics import chain_from_model
    from readjax.sim.scene import load_model

    return chain_from_model(load_model(tasks.task_class(task).xml))


def build_modules(configs: dict, chain, camera):
    ae = make_autoencoder(configs["vae"], chain=chain, camera=camera)
    return ae, Denoiser(configs["denoiser"], output="delta")


def init_ae(ae, key):
    return ae.init(key, jnp.zeros((1, motion_lib.FRAMES, motion_lib.DIM)))


def init_denoiser(den, image_size: int, key):
    k1, k2 = jax.random.split(key)
    return den.init({"params": k1, "dropout": k2}, jnp.zeros((1, image_size, image_size, 4)),
                    jnp.zeros((1, motion_lib.FRAMES, motion_lib.DIM)), jnp.zeros((1,)))


VAE_TRAIN_FIELDS = ("episodes", "vae_steps", "vae_batch", "vae_lr", "schedule", "seed", "ckpt_every", "log_every")


def vae_stage_config(cfg_dict: dict) -> dict:
    """What the autoencoder stage depends on: runs differing only in K, L, T, ... share it."""
    defaults = config.field_defaults("train")  # what a run recorded before a field existed ran with
    return {"vae": cfg_dict["vae"], "train": {k: cfg_dict["train"].get(k, defaults[k]) for k in VAE_TRAIN_FIELDS}}


def ae_loss(ae):
    def loss_fn(params, batch, rng):
        return ae.apply(params, batch, rng, method="loss")

    return loss_fn


def read_loss(ae, ae_params, den: Denoiser, sde, augment: bool, weights: dict, latent=None):
    """M̂0 = D(I, Dec(z_t), t) with z_t from the latent IR-SDE marginal (on the standardised latent
    with ``latent`` stats, :mod:`readjax.diffusion.latent`); per-key MSEs summed with the
    autoencoder's key weights (METHOD.md sums them unweighted; our z is in metres, so an
    unweighted sum ignores depth errors of several centimetres).

    The batch carries z0 = Enc(M) and zR = Enc(M_R) (``code``, ``code_r``: the frozen autoencoder's
    deterministic codes, computed once per training set by :func:`latent_lib.codes`; encoding them
    at every step cost 2 of the step's 3 autoencoder passes).

    With ``sde.self_feed`` > 0 that fraction of the batch is trained on the degradation of the
    denoiser's own gradient-free first prediction instead (``SDEConfig``); 0 is the paper's loss."""
    enc, dec = latent_lib.codec(ae, ae_params, latent)

    def loss_fn(params, batch, rng):
        k_t, k_n, k_aug, k_drop = jax.random.split(rng, 4)
        image, m = batch["image"], batch["motion"]
        if augment:
            image = augment_rgb(k_aug, image)
        z0, z_r = batch["code"], batch["code_r"]
        t = irsde.sample_time(k_t, (m.shape[0],), sde)
        m_t = dec(irsde.marginal_sample(k_n, z0, z_r, t, sde))
        if not sde.self_feed:
            pred = den.apply(params, image, m_t, t, train=True, rngs={"dropout": k_drop})
            return weighted_motion_loss(pred, m, weights)
        features = den.apply(params, image, True, method="encode_image", rngs={"dropout": k_drop})
        first = den.apply(params, jax.lax.stop_gradient(features), m_t, t, method="denoise")
        fed = dec(irsde.marginal_sample(k_n, enc(jax.lax.stop_gradient(first)), z_r, t, sde))
        use = jax.random.bernoulli(jax.random.fold_in(rng, 4), sde.self_feed, (m.shape[0],))[:, None, None]
        pred = den.apply(params, features, jnp.where(use, fed, m_t), t, method="denoise")
        return weighted_motion_loss(pred, m, weights)

    return loss_fn


def with_motion_stats(configs: dict, motions) -> dict:
    """Fill the denoiser's per-channel motion statistics from the training set when
    ``denoiser.normalize_motion`` asks for them (a deterministic function of the data, so a resumed
    or shared run computes the same values)."""
    den = configs["denoiser"]
    if not den.normalize_motion or den.motion_std:
        return configs
    mean, std = common.motion_stats(motions)
    return dict(configs, denoiser=dataclasses.replace(den, motion_mean=tuple(round(float(v), 6) for v in mean),
                                                      motion_std=tuple(round(float(v), 6) for v in std)))


def fit_autoencoder(run_dir: Path, ds, ae, key, train_cfg, cfg_dict: dict, progress: bool, stop_at) -> None:
    """The ``vae/`` stage (shared by READ and READ-L, and by runs differing only in K, L, T)."""
    vspec = base.autoencoder_stage_spec(train_cfg)

    def vae_batch(idx, step, rows):
        idx = idx[rows]
        return {"motion": ds.motion[idx], "joints": ds.joints[idx]}

    batches = base.Batches(vae_batch, base.train_size(len(ds), train_cfg), len(ds), vspec.batch_size, vspec.seed)
    base.fit_stage(run_dir, "vae", vspec, vae_stage_config(cfg_dict), ds, init_ae(ae, key), ae_loss(ae),
                   batches, progress, stop_at)


def autoencoder_params(run_dir: Path, ae, key, train_cfg, cfg_dict: dict, fingerprint: str):
    """The trained autoencoder of a run's ``vae/`` stage (READ and READ-L)."""
    return base.stage_params(run_dir, "vae", base.autoencoder_stage_spec(train_cfg), init_ae(ae, key),
                             vae_stage_config(cfg_dict), fingerprint)


def fit_latent_stats(run_dir: Path, ae, ae_params, motions, sde):
    """With ``sde.latent_norm``: measure the trained autoencoder's code statistics on the training
    motions and record them in the run (READ and READ-L); else None (the raw code)."""
    if not sde.latent_norm:
        return None
    stats = latent_lib.measure(ae, ae_params, motions)
    latent_lib.write(run_dir, stats)
    return stats


def autoencoder_source_check(vae_from, run_dir):
    """``common.prepare``'s ``check`` for a run that starts from ``vae_from``'s finished autoencoder:
    refuse (before run.json is written) a source trained with another autoencoder config or dataset.
    None (nothing to check) without a source, or once ``run_dir`` holds its copy: a resumed run
    does not depend on its source any more, as in ``training.copy_finished_stage``."""
    if vae_from is None or (Path(run_dir) / "vae").exists():
        return None
    return lambda cfg_dict, ds: training.check_shareable_stage(vae_from, "vae", vae_stage_config(cfg_dict),
                                                              ds.fingerprint)


def prepare_autoencoder(run: common.PreparedRun, stages, progress: bool, stop_at, build=None, vae_from=None):
    """The first stage READ and READ-L share: build the modules (``build``, default READ's
    :func:`build_modules`) and fit the autoencoder if ``"vae"`` is among ``stages``. ``vae_from``:
    another run folder whose finished autoencoder stage this run starts from (same stage config and
    dataset, else refused: ``training.copy_finished_stage``). Returns (autoencoder, denoiser,
    autoencoder key, denoiser key)."""
    ae, den = (build or build_modules)(run.configs, task_chain(run.task), run.ds.camera)
    k_ae, k_den = jax.random.split(jax.random.key(run.train_cfg.seed))
    if vae_from is not None:
        training.copy_finished_stage(vae_from, run.run_dir, "vae", vae_stage_config(run.cfg_dict), run.ds.fingerprint)
    if "vae" in stages:
        fit_autoencoder(run.run_dir, run.ds, ae, k_ae, run.train_cfg, run.cfg_dict, progress, stop_at)
    return ae, den, k_ae, k_den


def train(task: str, data_root: str | Path, run_dir: str | Path, configs: dict, preset: str,
          stages=STAGES, progress: bool = True, stop_at: int | None = None, vae_from=None) -> dict:
    """Train READ for a task; each stage resumes from its latest checkpoint (``vae_from``: start
    from another run's finished autoencoder, :func:`prepare_autoencoder`). Returns run.json."""
    run = common.prepare("read", task, data_root, run_dir, configs, preset, None, configs["denoiser"].image_size,
                         adjust=lambda c, ds: with_motion_stats(c, ds.motion), check=autoencoder_source_check(vae_from, run_dir))
    ae, den, k_ae, k_den = prepare_autoencoder(run, stages, progress, stop_at, vae_from=vae_from)
    if "read" in stages:
        ds, configs, train_cfg = run.ds, run.configs, run.train_cfg
        ae_params = autoencoder_params(run.run_dir, ae, k_ae, train_cfg, run.cfg_dict, ds.fingerprint)
        latent = fit_latent_stats(run.run_dir, ae, ae_params, run.train_motions, configs["sde"])
        dspec = base.network_stage_spec(train_cfg)
        loss = read_loss(ae, ae_params, den, configs["sde"], train_cfg.augment, configs["vae"].loss_weights, latent)
        codes = latent_lib.codes(ae, ae_params, ds.motion, latent)
        run.fit("read", dspec, init_denoiser(den, run.image_size, k_den), loss,
                base.paired_batch(ds, dspec, run.pairs(), run.n_train, codes=codes), progress, stop_at)
    return run.result()


class ReadModel(common.DenoiserRunModel):
    """A trained READ run, behind the interface every method's model offers the planner:

    ``encode(images)`` -> per-image features (computed once), ``tokens(features, uv)`` -> image
    features along motions (SPE retrieval), ``generate(features, retrieved, key, n_steps)`` -> motions.
    """

    uses_retrieval = True
    has_refine_update = True

    def __init__(self, run_dir: str | Path):
        super().__init__(run_dir)
        configs = self.configs
        self.ae, self.den = build_modules(configs, tasks.make(self.spec["task"]).chain, self.camera)
        train_cfg = configs["train"]
        k_ae, k_den = jax.random.split(jax.random.key(train_cfg.seed))
        cfg_dict = config.configs_to_dict(configs)
        self.ae_params = autoencoder_params(self.run_dir, self.ae, k_ae, train_cfg, cfg_dict,
                                            self.fingerprint)
        self.den_params = base.stage_params(self.run_dir, "read", base.network_stage_spec(train_cfg),
                                            init_denoiser(self.den, self.image_size, k_den), cfg_dict,
                                            self.fingerprint)
        self.latent = latent_lib.for_run(self.run_dir, configs["sde"])
        self._setup_encoder()

    @classmethod
    def random(cls, task: str, configs: dict, camera, key: jax.Array) -> "ReadModel":
        """An untrained model with random parameters (benchmarks and tests; no run folder)."""
        self = cls.__new__(cls)
        self.run_dir, self.configs, self.camera = None, configs, camera
        self.image_size = configs["denoiser"].image_size
        self.spec = {"task": task, "method": "read", "image_size": self.image_size, "camera": camera.to_dict()}
        self.ae, self.den = build_modules(configs, tasks.make(task).chain, camera)
        k_ae, k_den = jax.random.split(key)
        self.ae_params, self.den_params = init_ae(self.ae, k_ae), init_denoiser(self.den, self.image_size, k_den)
        self.latent = (latent_lib.LatentStats.identity(configs["vae"].latent_dim)
                       if configs["sde"].latent_norm else None)
        self._setup_encoder()
        return self

    def generate(self, features, retrieved, key, n_steps: int) -> jax.Array:
        n = common.check_n_steps(n_steps, allow_zero=True, method="read")
        return refine(self.ae, self.ae_params, self.den, self.den_params, features, jnp.asarray(retrieved),
                      key, n, self.configs["sde"], latent=self.latent)
