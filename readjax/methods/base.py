"""What every method's training shares: the training configuration and presets, the run folder
(``run.json``), dataset preparation and host-side batch sampling that is a pure function of the
step (so resuming is exact)."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from readjax import config as cfg_lib
from readjax import provenance
from readjax.data import store
from readjax.training import (CheckpointError, Stage, StageSpec, TrainState, batch_indices, make_optimizer,
                              with_new_defaults)


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings (METHOD.md sections 4 and 6). ``K`` is Table 7's neighbour pool."""

    episodes: int = 0  # training demos to use (0 = all in the dataset)
    vae_steps: int = 50_000
    vae_batch: int = 32
    vae_lr: float = 1e-4
    steps: int = 50_000  # the diffusion model / baseline
    batch: int = 64
    lr: float = 1e-4
    lr_decay: float = 0.99  # every lr_decay_every steps (staircase)
    lr_decay_every: int = 5000
    K: int = 3
    augment: bool = True
    ckpt_every: int = 2000
    log_every: int = 50
    seed: int = 0

    def __post_init__(self):
        for n in ("vae_steps", "vae_batch", "steps", "batch", "K", "ckpt_every", "log_every"):
            if not isinstance(getattr(self, n), int) or getattr(self, n) < 1:
                raise ValueError(f"TrainConfig.{n} must be a positive int, got {getattr(self, n)!r}")


TRAIN_PRESETS = {
    "paper": TrainConfig(),
    "cpu": TrainConfig(vae_steps=3000, vae_batch=32, vae_lr=1e-3, steps=3000, batch=32, lr=3e-4,
                       lr_decay=0.5, lr_decay_every=1500, ckpt_every=500, log_every=25),
}


def presets(name: str) -> dict[str, Any]:
    """All configs of a preset: vae, denoiser, sde (READ), resnet, vpsde, read_o (baselines and
    variants, ``config.METHOD_SECTIONS``) and train."""
    if name not in TRAIN_PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(TRAIN_PRESETS)}")
    return dict(cfg_lib.preset(name), train=TRAIN_PRESETS[name])


def override(configs: dict[str, Any], items) -> dict[str, Any]:
    """``key=value`` overrides for every section, train fields included (``train.steps=100``, ``K=5``)."""
    items = list(items)
    train_fields = {f.name for f in dataclasses.fields(TrainConfig)}
    train_kw, rest = {}, []
    for item in items:
        if "=" not in item:
            raise ValueError(f"override {item!r} is not of the form key=value")
        key, value = item.split("=", 1)
        field = key[len("train."):] if key.startswith("train.") else key
        if key.startswith("train.") or (field in train_fields and field not in _model_fields()):
            if field not in train_fields:
                raise ValueError(f"TrainConfig has no field {field!r}")
            tp = type(getattr(TrainConfig(), field))
            train_kw[field] = _parse(value, tp, f"train.{field}")
        else:
            rest.append(item)
    out = cfg_lib.override({k: v for k, v in configs.items() if k != "train"}, rest)
    out["train"] = dataclasses.replace(configs["train"], **train_kw)
    return out


def _model_fields() -> set[str]:
    return {f.name for cls in cfg_lib.SECTIONS.values() for f in dataclasses.fields(cls)}


def _parse(text: str, tp, where: str):
    if tp is bool:
        if text.lower() in ("1", "true", "yes", "on"):
            return True
        if text.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{where}: expected a boolean, got {text!r}")
    try:
        return tp(text)
    except ValueError:
        raise ValueError(f"{where}: expected {tp.__name__}, got {text!r}") from None


def configs_to_dict(configs: dict[str, Any], sections=None) -> dict:
    """JSON-ready configs of a run: ``sections`` (default: every section except the method-specific
    ``config.METHOD_SECTIONS``, i.e. READ's vae/denoiser/sde) plus train."""
    if sections is None:
        keep = [k for k in configs if k != "train" and k not in cfg_lib.METHOD_SECTIONS]
    else:
        missing = [k for k in sections if k not in configs]
        if missing:
            raise ValueError(f"configs have no section(s) {missing}")
        keep = list(sections)
    d = cfg_lib.to_dict({k: configs[k] for k in keep})
    d["train"] = dataclasses.asdict(configs["train"])
    return d


def configs_from_dict(d: dict) -> dict[str, Any]:
    out = cfg_lib.from_dict({k: v for k, v in d.items() if k != "train"})
    out["train"] = TrainConfig(**d["train"])
    return out


# ------------------------------------------------------------------ runs

def write_run(run_dir: Path, spec: dict) -> None:
    """Record what a run is (method, task, configs, dataset); refuse to mix two runs in one folder."""
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
    f.write_text(json.dumps(dict(spec, versions=provenance.versions()), indent=2, sort_keys=True))


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


def paired_batch(ds, spec: StageSpec, pairs: np.ndarray, **extra):
    """The batch function of a retrieval-conditioned stage: images and motions of sampled demos and,
    for each, one of its K ground-truth neighbours (``retrieved``); pure in the step (exact resume).
    ``extra`` entries are added to every batch unchanged."""

    def batch(step):
        idx = sample_indices(len(ds), spec.batch_size, spec.seed, step)
        j = neighbour_choice(pairs, idx, spec.seed, step)
        return {"image": ds.rgbd[idx], "motion": ds.motion[idx], "retrieved": ds.motion[j], **extra}

    return batch


def neighbour_choice(pairs: np.ndarray, idx: np.ndarray, seed: int, step: int) -> np.ndarray:
    """For each sampled demo, one of its K neighbours uniformly (pure in (seed, step))."""
    col = np.random.default_rng([seed, step, 1]).integers(0, pairs.shape[1], size=len(idx))
    return pairs[idx, col]
