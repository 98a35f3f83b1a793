"""What the baselines and variants of METHOD.md section 10 share: run preparation, the motion
normaliser of the task-space diffusion models, per-key losses and the model-side plumbing the
planner needs (run folder, camera, image encoding, SPE retrieval features).

Motion normalisation (VPSDE, VPSDE+CG, READ-O): per-dimension mean and std of the 10 motion
channels over every frame of every training demo (std floored at ``STD_FLOOR`` so constant channels
stay finite), written to ``RUN/normalizer.json`` when training starts and read back by the model.
The diffusion state lives in normalised units and the denoiser embeds it as such (a channel
with a tiny spread, e.g. a fixed orientation, would otherwise hide its noise from the network),
but its image tokens are sampled along the state's real, denormalised track (:func:`denormalize`,
the Denoiser's ``track`` argument); its eps output is in normalised units.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from readjax import config, retrieval, stats_record, tasks
from readjax import motion as motion_lib
from readjax.methods import base
from readjax.models.denoiser import Denoiser
from readjax.models.vae import motion_mse
from readjax.sim.camera import CameraParams

NORMALIZER_FILE = "normalizer.json"
STD_FLOOR = 1e-2


# ------------------------------------------------------------------ normaliser

def motion_stats(motions) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel (mean, std) over demos and frames, each (10,) float32 (std >= STD_FLOOR)."""
    m = np.asarray(motions, np.float64).reshape(-1, motion_lib.DIM)
    return m.mean(0).astype(np.float32), np.maximum(m.std(0), STD_FLOOR).astype(np.float32)


def write_normalizer(run_dir: Path, stats) -> None:
    """Record the stats; a run folder that already holds different ones is refused."""
    stats_record.write(Path(run_dir) / NORMALIZER_FILE, *stats, what="normalisation stats", atol=1e-6,
                       std_floor=STD_FLOOR, channels=list(motion_lib.KEYS))


def fit_normalizer(run_dir: Path, motions) -> tuple[np.ndarray, np.ndarray]:
    """The training motions' stats (:func:`motion_stats`), recorded in the run (:func:`write_normalizer`)."""
    stats = motion_stats(motions)
    write_normalizer(run_dir, stats)
    return stats


def read_normalizer(run_dir) -> tuple[np.ndarray, np.ndarray]:
    return stats_record.read(Path(run_dir) / NORMALIZER_FILE, "normalisation stats", "; train the run first")


def batch_stats(stats, batch_size: int) -> np.ndarray:
    """The stats as a per-sample batch entry (B, 2, 10), so that a train step takes them as an
    argument (sharded like the rest of the batch) instead of baking them into the program."""
    return np.broadcast_to(np.stack([np.asarray(s, np.float32) for s in stats])[None],
                           (batch_size, 2, motion_lib.DIM)).copy()


def stats_from_batch(batch) -> tuple[jax.Array, jax.Array]:
    """(mean, std) shaped (B, 1, 10), broadcasting against motions (B, 101, 10)."""
    s = batch["norm"]
    return s[:, 0:1, :], s[:, 1:2, :]


def normalize(m: jax.Array, stats) -> jax.Array:
    mean, std = stats
    return (m - mean) / std


def denormalize(x: jax.Array, stats) -> jax.Array:
    mean, std = stats
    return x * std + mean


# ------------------------------------------------------------------ training helpers

@dataclass(frozen=True)
class PreparedRun:
    """A run folder ready to train (from :func:`prepare`): its task, folder, training set, the
    configs (after ``adjust``) and what run.json records of them (``cfg_dict``)."""

    task: str
    run_dir: Path
    ds: Any
    configs: dict
    cfg_dict: dict
    image_size: int

    @property
    def train_cfg(self):
        return self.configs["train"]

    @property
    def n_train(self) -> int:
        """The demos the networks train on: the first ``n_train`` of ``ds``; the rest (``train.val_episodes``)
        are the held-out validation slice (the retrieval database at inference still holds all)."""
        return base.train_size(len(self.ds), self.train_cfg)

    @property
    def train_motions(self):
        return self.ds.motion[:self.n_train]

    def batches(self, spec: base.StageSpec, make) -> base.Batches:
        """A stage's :class:`base.Batches` over this run's split from ``make(idx, step, rows)``."""
        return base.Batches(make, self.n_train, len(self.ds), spec.batch_size, spec.seed)

    def pairs(self):
        """Each demo's K nearest training demos (self excluded): a stage's retrieval pairs."""
        return retrieval.training_pairs(self.ds.camera, self.ds.motion, self.train_cfg.K, clamp=True,
                                        pool=self.n_train)

    def fit(self, stage: str, spec: base.StageSpec, params, loss_fn, batches: base.Batches, progress: bool,
            stop_at) -> None:
        """Train (or resume) one stage of this run that records the run's configs."""
        base.fit_stage(self.run_dir, stage, spec, self.cfg_dict, self.ds, params, loss_fn, batches, progress,
                       stop_at)

    def result(self) -> dict:
        """run.json, as every method's ``train`` returns it."""
        return base.read_run(self.run_dir)


def prepare(method: str, task: str, data_root, run_dir, configs: dict, preset: str, sections, image_size: int,
            adjust=None, check=None) -> PreparedRun:
    """Load the training set and write run.json (recording only ``sections`` + train; None: READ's
    sections). ``adjust(configs, ds) -> configs`` fills data-dependent config values before they
    are recorded; ``check(cfg_dict, ds)`` may raise to refuse the run before anything is written."""
    task = tasks.canonical_name(task)
    run_dir = Path(run_dir)
    ds = base.load_train_data(data_root, task, configs["train"], image_size)
    if adjust is not None:  # from the demos trained on, not the validation slice (no copy without one)
        n_train = base.train_size(len(ds), configs["train"])
        configs = adjust(configs, ds if n_train == len(ds) else ds.subset(np.arange(n_train)))
    cfg_dict = config.configs_to_dict(configs, sections)
    if check is not None:
        check(cfg_dict, ds)
    spec = {"method": method, "task": task, "preset": preset, "configs": cfg_dict,
            "data_root": str(Path(data_root).resolve()), "dataset_fingerprint": ds.fingerprint,
            "episodes": len(ds), "image_size": image_size, "camera": ds.camera.to_dict(),
            "suite": tasks.suite_of(ds.meta)}
    base.write_run(run_dir, spec)
    return PreparedRun(task, run_dir, ds, configs, cfg_dict, image_size)


def per_key_mse(pred: jax.Array, target: jax.Array) -> tuple[jax.Array, dict]:
    """Sum over the motion keys of each key's MSE (READ's and the released baselines' reduction)."""
    per_key = motion_mse(pred, target)
    return sum(per_key.values()), per_key


def check_n_steps(n_steps, allow_zero: bool = True, method: str = "this method",
                  name: str = "n_steps") -> int:
    """The one check of N (sampler / refinement steps): a non-negative int, and >= 1 for a method that
    samples from noise (``allow_zero=False``). Returns it as an int. ``name``: what the caller calls it."""
    if isinstance(n_steps, (bool, np.bool_)) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
        raise ValueError(f"{name} must be a non-negative int, got {n_steps!r}")
    if n_steps == 0 and not allow_zero:
        raise ValueError(f"{method} samples from noise: it needs N >= 1 sampler steps (N = 0 means 'execute the "
                         f"retrieved motion', which only retrieval-based methods have)")
    return int(n_steps)


# ------------------------------------------------------------------ models

class RunModel:
    """The planner-facing basics of a trained run: spec, configs, camera, image size."""

    uses_retrieval = False
    iterative = True  # generate() runs n_steps of a sampler (False: one forward pass, N is ignored)

    def __init__(self, run_dir):
        self.run_dir = Path(run_dir)
        self.spec = base.read_run(self.run_dir)
        self.configs = config.configs_from_dict(self.spec["configs"])
        self.cfg_dict = self.spec["configs"]
        self.camera = CameraParams.from_dict(self.spec["camera"])
        self.image_size = int(self.spec["image_size"])
        self.fingerprint = self.spec["dataset_fingerprint"]

    @property
    def refine_rounds(self) -> int:
        """Refinement rounds the run's configs ask for at inference (``sde.rounds``; 1 without an SDE)."""
        sde = self.configs.get("sde")
        return 1 if sde is None else sde.rounds

    # READ's refinement loop, and the ablations' loops built on it (READ-O's CD sampler, READ-L), run
    # the SDE's inference update (``sde.update``, :mod:`readjax.diffusion.refine`); other samplers have none
    has_refine_update = False

    @property
    def refine_update(self) -> str | None:
        """The inference update (``sde.update``) generate() runs; None for a method without one."""
        return self.configs["sde"].update if self.has_refine_update else None

    def set_refine_update(self, update: str) -> None:
        """Refine with another inference update ("renoise": the paper, "cold", "cold_anchor";
        ``SDEConfig.update``). The trained weights do not depend on it."""
        if not self.has_refine_update:
            raise ValueError(f"{self.spec.get('method')} has no refinement update to choose (one is run by "
                             "read, read_l and read_o with the cd sampler)")
        self.configs = dict(self.configs, sde=dataclasses.replace(self.configs["sde"], update=update))

    def network_params(self, stage: str, template):
        """The trained parameters of this run's network stage ``stage`` (``base.network_stage_spec``)."""
        spec = base.network_stage_spec(self.configs["train"])
        return base.stage_params(self.run_dir, stage, spec, template, self.cfg_dict, self.fingerprint)


class DenoiserRunModel(RunModel):
    """A run whose image encoder is a READ-style denoiser ``self.den`` with params ``self.den_params``
    (``encode_image`` / ``retrieval_tokens``): image encoding and SPE retrieval features."""

    den = None
    den_params = None

    def _setup_encoder(self):
        den = self.den
        self._encode = jax.jit(lambda p, x: den.apply(p, x, method="encode_image"))

    def encode(self, images: jax.Array) -> jax.Array:
        return self._encode(self.den_params, images)

    def database_tokens(self, images: np.ndarray, motions: np.ndarray) -> np.ndarray:
        return database_features(self.den, self.den_params, images, motions)

    def spe_distances(self, features, db_uv, db_tokens) -> jax.Array:
        return retrieval.spe_distances(self.den, self.den_params, features, db_uv, db_tokens)


@partial(jax.jit, static_argnums=(0,))
def database_tokens(den: Denoiser, den_params, images: jax.Array, motions: jax.Array) -> jax.Array:
    """Each database image's features sampled along its own motion (N, 101, C), for SPE retrieval."""
    feats = den.apply(den_params, images, method="encode_image")
    return den.apply(den_params, feats, motion_lib.uv(motions), method="retrieval_tokens")


def database_features(den, den_params, images: np.ndarray, motions: np.ndarray, chunk: int = 64) -> np.ndarray:
    """database_tokens in fixed-size chunks (the last one padded: one compile)."""
    n, out = len(images), []
    chunk = min(chunk, n)
    for s in range(0, n, chunk):
        idx = np.arange(s, s + chunk) % n
        tok = database_tokens(den, den_params, jnp.asarray(images[idx]), jnp.asarray(motions[idx]))
        out.append(np.asarray(tok)[: min(chunk, n - s)])
    return np.concatenate(out)
