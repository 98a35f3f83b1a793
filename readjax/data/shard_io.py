"""HDF5 shard I/O of the dataset store (:mod:`readjax.data.store` describes the layout).

Writing shards, meta.json and summary.json atomically, reading a split's progress back, and the
scene and depth encodings a shard holds. :mod:`readjax.data.store` re-exports these names.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

import jax

from readjax import atomic_write
from readjax.sim.env import Scene

# 3: a motion's grip is the commanded gripper state (2 recorded the measured opening, which reads
#    "open" around wide grasped objects); 2: each episode's scene is stored (1 re-sampled it)
FORMAT_VERSION = 3
SHARD_GLOB = "shard_*.h5"


class DatasetError(RuntimeError):
    """A dataset is missing, inconsistent or corrupted."""


def write_meta(path: Path, meta: dict) -> None:
    path.mkdir(parents=True, exist_ok=True)
    atomic_write.write_text(path / "meta.json", json.dumps(meta, indent=2, sort_keys=True))


def read_meta(path: Path) -> dict | None:
    f = Path(path) / "meta.json"
    if not f.exists():
        return None
    try:
        return json.loads(f.read_text())
    except json.JSONDecodeError as e:
        raise DatasetError(f"{f} is not valid JSON ({e}); delete the folder to regenerate it") from e


def write_summary(path: Path, summary: dict) -> None:
    atomic_write.write_text(Path(path) / "summary.json", json.dumps(summary, indent=2, sort_keys=True))


def encode_depth(depth01: np.ndarray) -> np.ndarray:
    return np.round(np.clip(depth01, 0, 1) * 65535).astype(np.uint16)


def decode_depth(depth_u16: np.ndarray) -> np.ndarray:
    return depth_u16.astype(np.float32) / 65535.0


def write_shard(path: Path, index: int, *, rgb: np.ndarray, depth01: np.ndarray, motion: np.ndarray,
                joints: np.ndarray, seeds: np.ndarray, raw_frames: np.ndarray, scenes: Scene,
                attempted_seeds: np.ndarray, failed_seeds: np.ndarray,
                infeasible_seeds: np.ndarray | None = None) -> Path:
    """Write one shard atomically; returns its path. ``failed_seeds`` are the attempted seeds not kept;
    ``infeasible_seeds`` those of them without a valid placement (the rest: the expert failed)."""
    n = len(seeds)
    for name, leaf in _scene_leaves(scenes):
        if leaf.shape[:1] != (n,):
            raise ValueError(f"shard scene/{name} has shape {leaf.shape}, expected leading ({n},)")
    for name, arr, shape in (("rgb", rgb, (n,)), ("depth", depth01, (n,)), ("motion", motion, (n, 101, 10)),
                             ("joints", joints, (n, 101, 7))):
        if arr.shape[: len(shape)] != shape:
            raise ValueError(f"shard {name} has shape {arr.shape}, expected leading {shape}")
    final = Path(path) / f"shard_{index:05d}.h5"
    tmp = final.with_name(final.name + ".tmp")
    with h5py.File(tmp, "w") as f:
        kw = dict(compression="gzip", compression_opts=4)
        h, w = rgb.shape[1:3] if n else (1, 1)
        f.create_dataset("rgb", data=rgb.astype(np.uint8), chunks=(1, h, w, 3) if n else None, **kw)
        f.create_dataset("depth", data=encode_depth(depth01), chunks=(1, h, w) if n else None, **kw)
        f.create_dataset("motion", data=motion.astype(np.float32))
        f.create_dataset("joints", data=joints.astype(np.float32))
        f.create_dataset("seed", data=np.asarray(seeds, np.int64))
        f.create_dataset("raw_frames", data=np.asarray(raw_frames, np.int32))
        f.attrs["attempted_seeds"] = np.asarray(attempted_seeds, np.int64)
        f.attrs["failed_seeds"] = np.asarray(failed_seeds, np.int64)
        f.attrs["infeasible_seeds"] = np.asarray([] if infeasible_seeds is None else infeasible_seeds, np.int64)
        for name, leaf in _scene_leaves(scenes):
            f.create_dataset(f"scene/{name}", data=leaf)
        f.attrs["format_version"] = FORMAT_VERSION
    os.replace(tmp, final)
    return final


SCENE_ARRAYS = ("qpos", "mocap_pos", "mocap_quat", "rgba")


def _scene_leaves(scenes: Scene) -> list[tuple[str, np.ndarray]]:
    """(name, array) of every scene field, params as ``params/<name>``."""
    out = [(k, np.asarray(getattr(scenes, k))) for k in SCENE_ARRAYS]
    return out + [(f"params/{k}", np.asarray(v)) for k, v in sorted(scenes.params.items())]


def _read_scenes(group) -> Scene:
    params = group.get("params")
    return Scene(**{k: np.asarray(group[k]) for k in SCENE_ARRAYS},
                 params={k: np.asarray(params[k]) for k in params} if params is not None else {})


def _concat_scenes(parts: list[Scene]) -> Scene:
    return jax.tree.map(lambda *xs: np.concatenate(xs), *parts)


def clean_partial(path: Path) -> int:
    """Remove temporary files an interrupted run left behind; returns how many."""
    n = 0
    for tmp in Path(path).glob("*.tmp"):
        tmp.unlink()
        n += 1
    return n


def shards(path: Path) -> list[Path]:
    return sorted(Path(path).glob(SHARD_GLOB))


@dataclass
class Progress:
    """What the shards of a split already hold."""

    kept: int
    attempted: np.ndarray  # all seeds tried so far (kept and failed)
    failed: np.ndarray
    next_shard: int
    infeasible: np.ndarray  # failed seeds without a valid placement (shards before suite 2: none recorded)


def read_progress(path: Path) -> Progress:
    kept, attempted, failed, infeasible, nxt = 0, [], [], [], 0
    for s in shards(path):
        try:
            with h5py.File(s, "r") as f:
                kept += len(f["seed"])
                attempted.append(np.asarray(f.attrs["attempted_seeds"]))
                failed.append(np.asarray(f.attrs["failed_seeds"]))
                infeasible.append(np.asarray(f.attrs.get("infeasible_seeds", np.zeros((0,), np.int64))))
        except (OSError, KeyError) as e:
            raise DatasetError(f"shard {s} is unreadable ({e}); delete it and re-run to regenerate it") from e
        nxt = max(nxt, int(s.stem.split("_")[1]) + 1)
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros((0,), np.int64)  # noqa: E731
    return Progress(kept, cat(attempted), cat(failed), nxt, cat(infeasible))
