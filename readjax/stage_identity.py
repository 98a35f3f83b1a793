"""What a training stage is (its ``stage.json``: config and dataset fingerprint) and who may resume or
share it: a stage is resumed only under the config and dataset it was trained with (inference-only
fields aside, fields it predates at their defaults), and a finished stage may be copied into another
run trained with the same (READ variants share the autoencoder). :mod:`readjax.training` re-exports
these names."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from readjax import distributed, stage_folder
from readjax.config import field_defaults, without_inference_only

_MISSING = object()


class CheckpointError(RuntimeError):
    """A checkpoint is missing, corrupted, or belongs to another config/dataset."""


def _field_default(section: str, name: str):
    """The dataclass default of a config field (``missing`` if unknown)."""
    return field_defaults(section).get(name, _MISSING)


def with_new_defaults(old: dict, new: dict) -> dict:
    """A stage recorded by an older readjax lacks config fields added since; such a field counts as
    unchanged when the new config holds its default (new fields default to the old behaviour)."""
    out = {}
    for section, values in old.items():
        if isinstance(values, dict) and isinstance(new.get(section), dict):
            values = dict(values)
            for k, v in new[section].items():
                if k not in values and _field_default(section, k) == v:
                    values[k] = v
        out[section] = values
    return out


def identity_mismatch(stage_json: Path, config: dict, fingerprint: str) -> str | None:
    """Why a stage recorded in ``stage_json`` is not one trained with ``config`` on the dataset
    ``fingerprint`` (None: it is). Inference-only fields are not compared; fields the record
    predates count at their defaults."""
    try:
        old = json.loads(Path(stage_json).read_text())
    except json.JSONDecodeError as e:
        raise CheckpointError(f"{stage_json} is corrupted ({e}); move the run away or use a new --out") from e
    if old.get("dataset_fingerprint") != fingerprint:
        return f"was trained on dataset {old.get('dataset_fingerprint')}, not {fingerprint}"
    config = json.loads(json.dumps(config))
    old_config = without_inference_only(with_new_defaults(old.get("config", {}), config))
    new_config = without_inference_only(config)
    if old_config != new_config:
        diff = sorted(k for k in set(old_config) | set(new_config) if old_config.get(k) != new_config.get(k))
        return f"was trained with another config (differs in {diff})"
    return None


def check_shareable_stage(source_run: str | Path, name: str, config: dict, fingerprint: str) -> None:
    """Raise CheckpointError unless ``source_run`` has a finished stage ``name`` trained with
    ``config`` on the dataset ``fingerprint`` (what :func:`copy_finished_stage` may copy). Writes
    nothing: callers run it before they create a run folder, so a refusal leaves no trace."""
    src = Path(source_run) / name
    if not (src / stage_folder.STAGE_FILE).exists() or not stage_folder.is_finished(src):
        raise CheckpointError(f"{src} is not a finished {name!r} stage (no stage.json / stop.json); "
                              "train it first or drop the option")
    why = identity_mismatch(src / stage_folder.STAGE_FILE, config, fingerprint)
    if why:
        raise CheckpointError(f"{src} cannot be shared: it {why}")


def copy_finished_stage(source_run: str | Path, run_dir: str | Path, name: str, config: dict,
                        fingerprint: str) -> bool:
    """Start ``run_dir``'s stage ``name`` as a copy of the same, finished stage of ``source_run``
    (runs that differ only in what later stages read share it: READ variants share the autoencoder).
    Refused, with nothing written, when the source stage is unfinished or was trained with another
    config or dataset. Returns False (nothing done) when ``run_dir`` already has the stage. In a
    multi-process training every process checks, the primary copies, the others wait for it."""
    src, dst = Path(source_run) / name, Path(run_dir) / name
    existed = dst.exists()
    distributed.barrier("copy_finished_stage:looked")  # nobody sees the primary's copy as "already there"
    if existed:
        return False
    check_shareable_stage(source_run, name, config, fingerprint)
    if distributed.is_primary():
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(src, dst)
    distributed.barrier("copy_finished_stage:copied")
    return True
