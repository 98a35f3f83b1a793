"""What every method's training shares: the shape of a method (:class:`Method`, :class:`MethodModel`),
the run folder (``run.json``), dataset preparation, the stage specs and host-side batch sampling
that is a pure function of the step (so resuming is exact). The training configuration and presets
live with the other configs in ``readjax.config``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Protocol, runtime_checkable

import numpy as np

from readjax import atomic_write, distributed, provenance
from readjax.config import TrainConfig
from readjax.data import store
from readjax.training import (CheckpointError, Stage, StageSpec, TrainState, batch_indices, make_optimizer,
                              with_new_defaults)


@runtime_checkable
class Method(Protocol):
    """A method module of ``readjax.methods.METHODS``: its training stages (``STAGES``, the folders of
    a run, trained in this order) and ``train``, which prepares the run (``common.prepare``: dataset,
    ``run.json``) and then fits each stage named in ``stages`` (resuming from its latest checkpoint),
    returning run.json. Its trained model is the registry's class (a :class:`MethodModel`)."""

    STAGES: tuple[str, ...]

    def train(self, task: str, data_root, run_dir, configs: dict, preset: str, stages=...,
              progress: bool = True, stop_at: int | None = None) -> dict: ...


@runtime_checkable
class MethodModel(Protocol):
    """The trained model of a run, as the planner uses it (``common.RunModel`` and subclasses).

    ``encode(images)`` -> per-image features (computed once); ``generate(features, retrieved, key,
    n_steps)`` -> motions (B, 101, 10), ``retrieved`` the retrieved motions (the start of refinement,
    the condition, or only the batch shape), ``n_steps`` N (checked with ``common.check_n_steps``;
    ignored when ``iterative`` is False). Retrieval-based methods (``uses_retrieval``) also offer
    ``database_tokens(images, motions)`` and ``spe_distances(features, db_uv, db_tokens)``."""

    uses_retrieval: bool
    iterative: bool
    run_dir: Any
    spec: dict
    image_size: int

    def encode(self, images): ...

    def generate(self, features, retrieved, key, n_steps: int): ...


def write_run(run_dir: Path, spec: dict) -> None:
    """Record what a run is (method, task, configs, dataset); refuse to mix two runs in one folder.
    (In a multi-process training every process checks a recorded run, the primary writes a new one.)"""
    run_dir.mkdir(parents=True, exist_ok=True)
    f = run_dir / "run.json"
    spec = json.loads(json.dumps(spec))  # as it will read back (tuples -> lists)
    if f.exists():
        old = read_run(run_dir)
        old["configs"] = with_new_defaults(old.get("configs", {}), spec.get("configs", {}))
        for key in ("method", "task", "configs", "dataset_fingerprint"):
            if old.get(key) != spec.get(key):
                raise CheckpointError(f"{run_dir} holds a run with another {key}; use a new --out/--name "
                                      f"or --restart")
        return
    if distributed.is_primary():
        atomic_write.write_text(f, json.dumps(dict(spec, versions=provenance.versions()), indent=2, sort_keys=True))


def read_run(run_dir: str | Path) -> dict:
    f = Path(run_dir) / "run.json"
    if not f.exists():
        raise FileNotFoundError(f"{run_dir} is not a training run (no run.json); train one with "
                                f"`python -m experiments.train`")
    try:
        return json.loads(f.read_text())
    except json.JSONDecodeError as e:
        raise CheckpointError(f"{f} is corrupted ({e})") from e


def load_train_data(data_root: str | Path, task: str, train_cfg: TrainConfig, image_size: int) -> store.Dataset:
    ds = store.load_dataset(store.split_dir(data_root, task, "train"),
                            limit=train_cfg.episodes if train_cfg.episodes else None)
    if ds.image_size % image_size:
        raise ValueError(f"the dataset's images are {ds.image_size}px; the model needs {image_size}px, which "
                         f"must divide it (generate with --image-size {image_size} or a multiple)")
    return ds.resized(image_size)


def _convergence(train: TrainConfig) -> dict:
    return {"val_every": train.val_every, "stop_patience": train.stop_patience,
            "stop_min_delta": train.stop_min_delta}


def autoencoder_stage_spec(train: TrainConfig) -> StageSpec:
    """The ``vae/`` stage (READ's and READ-L's motion autoencoder): the ``train.vae_*`` settings."""
    return StageSpec(steps=train.vae_steps, batch_size=train.vae_batch, lr=train.vae_lr, schedule=train.schedule,
                     ckpt_every=train.ckpt_every, log_every=train.log_every, seed=train.seed, **_convergence(train))


def network_stage_spec(train: TrainConfig) -> StageSpec:
    """Every method's main network stage (READ's, READ-O's and the VPSDEs' denoiser, READ-L's latent
    denoiser, Deterministic's ResNet): ``train.steps``/``batch``/``lr``..., seed ``train.seed + 1``."""
    return StageSpec(steps=train.steps, batch_size=train.batch, lr=train.lr, lr_decay=train.lr_decay,
                     lr_decay_every=train.lr_decay_every, schedule=train.schedule, ckpt_every=train.ckpt_every,
                     log_every=train.log_every, seed=train.seed + 1, **_convergence(train))


def train_size(n: int, train: TrainConfig) -> int:
    """How many of the ``n`` demos a stage trains on: all but the last ``train.val_episodes`` (the
    held-out validation slice of the training seeds)."""
    n_train = n - train.val_episodes
    if n_train < 2:
        raise ValueError(f"train.val_episodes = {train.val_episodes} leaves {n_train} of the {n} training demos "
                         f"to train on; hold out fewer")
    return n_train


@dataclass(frozen=True)
class Batches:
    """A stage's data. ``make(idx, step, rows)`` builds the rows ``rows`` (a slice) of the batch of
    demos ``idx`` (``step`` seeds any other per-batch choice, e.g. the neighbour, drawn for the whole
    batch so that a part equals the same rows of the whole). Training batches (``batches(step)``)
    draw from the first ``n_train`` demos, a pure function of the step (exact resume);
    ``batches.rows(step, rows)`` is a part of one (a process's share in a multi-process training);
    ``validation()`` covers the held-out rest in fixed batches of the same size (None without a
    validation split)."""

    make: Callable[[np.ndarray, int, slice], Any]
    n_train: int
    n: int
    batch_size: int
    seed: int

    def __call__(self, step: int):
        return self.rows(step, slice(None))

    def rows(self, step: int, rows: slice):
        return self.make(sample_indices(self.n_train, self.batch_size, self.seed, step), step, rows)

    def validation(self) -> list | None:
        val = np.arange(self.n_train, self.n)
        if not len(val):
            return None
        count = -(-len(val) // self.batch_size)
        return [self.make(val[np.arange(k * self.batch_size, (k + 1) * self.batch_size) % len(val)], k, slice(None))
                for k in range(count)]


def fit_stage(run_dir: Path, name: str, spec: StageSpec, config: dict, ds, params, loss_fn, batches: Batches,
              progress: bool, stop_at) -> None:
    """Train (or resume) one stage of a run on the dataset ``ds`` (validating on its held-out demos)."""
    Stage(run_dir, name, spec, config, ds.fingerprint).fit(params, loss_fn, batches, progress=progress,
                                                           stop_at=stop_at, val_batches=batches.validation())


def stage_params(run_dir: Path, name: str, spec: StageSpec, params_template, config: dict, fingerprint: str):
    """The final parameters of a finished stage (restored from its latest checkpoint)."""
    stage = Stage(run_dir, name, spec, config, fingerprint)
    if stage.latest_step() is None:
        raise CheckpointError(f"stage {name!r} of {run_dir} has no checkpoint; train it first")
    template = TrainState(step=np.zeros((), np.int32), params=params_template,
                          opt_state=make_optimizer(spec).init(params_template))
    return stage.restore(template).params


def sample_indices(n: int, batch: int, seed: int, step: int) -> np.ndarray:
    return batch_indices(n, batch, seed, step)


def paired_batch(ds, spec: StageSpec, pairs: np.ndarray, n_train: int, codes: np.ndarray | None = None,
                 **extra) -> Batches:
    """The batches of a retrieval-conditioned stage: images and motions of sampled demos and, for
    each, one of its K ground-truth neighbours (``pairs``, among the first ``n_train`` demos); pure
    in the step (exact resume). The neighbour comes as its motion (``retrieved``) or, given
    ``codes`` (N, D), every demo's precomputed latent (a frozen autoencoder's), as its latent
    (``code_r``, with the sampled demos' own as ``code``): a latent-space loss reads no neighbour
    motion. ``extra`` entries, per-sample arrays of the batch's length, are added to every batch
    (their ``rows`` in a part of one)."""

    def batch(idx, step, rows):
        j = neighbour_choice(pairs, idx, spec.seed, step)[rows]
        idx = idx[rows]
        out = {"image": ds.rgbd[idx], "motion": ds.motion[idx], **{k: v[rows] for k, v in extra.items()}}
        if codes is None:
            out["retrieved"] = ds.motion[j]
        else:
            out.update(code=codes[idx], code_r=codes[j])
        return out

    return Batches(batch, n_train, len(ds), spec.batch_size, spec.seed)


def neighbour_choice(pairs: np.ndarray, idx: np.ndarray, seed: int, step: int) -> np.ndarray:
    """For each sampled demo, one of its K neighbours uniformly (pure in (seed, step))."""
    col = np.random.default_rng([seed, step, 1]).integers(0, pairs.shape[1], size=len(idx))
    return pairs[idx, col]
