"""The dataset store: HDF5 shards, one per generated batch, written atomically.

Layout of a split (``data/<task>/<split>/``)::

    meta.json          task, split, image size, camera intrinsics/extrinsics, depth planes
    shard_00000.h5     rgb (n,H,W,3) uint8 · depth (n,H,W) uint16 (normalised depth * 65535)
                       motion (n,101,10) f32 · joints (n,101,7) f32 · seed (n,) i64
                       raw_frames (n,) i32; attrs: attempted_seeds, failed_seeds
                       scene/ qpos, mocap_pos, mocap_quat, rgba, params/<name>: each episode's
                       scene, everything ``env.reset_to`` needs (format 2)
    summary.json       what generation reports (kept, attempted, expert success rate, ...)

A shard is written to a temporary name and renamed into place, so an interrupted run leaves
only whole shards; resuming reads the attempted seeds back from them (no duplicates, nothing
lost). Loading concatenates the shards in order.

Format 2 stores each episode's scene beside its image, and evaluation executes that stored scene;
format 3 records the gripper's commanded state (1 open, 0 closed) in a motion's grip channel.
Format-1 datasets are refused: their scenes could only be re-sampled from seeds, and before
readjax.prng that re-sampling depended on the batch (two thirds of test episodes ran in a scene
other than the one their image showed).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

import jax

from readjax.sim.camera import CameraParams
from readjax.sim.env import Scene

# 3: a motion's grip is the commanded gripper state (2 recorded the measured opening, which reads
#    "open" around wide grasped objects); 2: each episode's scene is stored (1 re-sampled it)
FORMAT_VERSION = 3
SHARD_GLOB = "shard_*.h5"


class DatasetError(RuntimeError):
    """A dataset is missing, inconsistent or corrupted."""


def split_dir(root: str | os.PathLike, task: str, split: str) -> Path:
    return Path(root) / task / split


@dataclass
class Dataset:
    """A loaded split: first-frame RGB-D images, motions, joint trajectories and seeds."""

    task: str
    split: str
    camera: CameraParams
    rgbd: np.ndarray  # (N, H, W, 4) float32: RGB in [0, 1], normalised depth in [0, 1]
    motion: np.ndarray  # (N, 101, 10) float32
    joints: np.ndarray  # (N, 101, 7) float32
    seeds: np.ndarray  # (N,) int64
    scenes: Scene | None = None  # leaves (N, ...): each episode's scene, what env.reset_to executes
    meta: dict = field(default_factory=dict)  # meta.json as generated (image_size: the rendered size)

    def __len__(self) -> int:
        return len(self.seeds)

    @property
    def image_size(self) -> int:
        return int(self.rgbd.shape[1])

    @property
    def fingerprint(self) -> str:
        """Content hash (seeds, motions, image size): checkpoints record it to catch mix-ups."""
        h = hashlib.sha256()
        h.update(self.task.encode())
        h.update(np.ascontiguousarray(self.seeds).tobytes())
        h.update(np.ascontiguousarray(self.motion).tobytes())
        h.update(str(self.rgbd.shape).encode())
        return h.hexdigest()[:16]

    def fingerprint_matches(self, fingerprint: str, image_size: int) -> bool:
        """Whether this dataset, resized to ``image_size``, is the one a run recorded."""
        return self.resized(image_size).fingerprint == fingerprint if self.image_size % image_size == 0 else False

    def resized(self, size: int) -> "Dataset":
        """The same data with images area-downsampled to size x size (size must divide H)."""
        return Dataset(self.task, self.split, scale_camera(self.camera, size), resize_images(self.rgbd, size),
                       self.motion, self.joints, self.seeds, self.scenes, self.meta)

    def subset(self, idx) -> "Dataset":
        idx = np.asarray(idx)
        return Dataset(self.task, self.split, self.camera, self.rgbd[idx], self.motion[idx],
                       self.joints[idx], self.seeds[idx], take_scenes(self.scenes, idx), self.meta)


def take_scenes(scenes: Scene, idx) -> Scene:
    """Episodes ``idx`` of a batch of scenes (numpy leaves)."""
    return jax.tree.map(lambda x: np.asarray(x)[idx], scenes)


def resize_images(images: np.ndarray, size: int) -> np.ndarray:
    h = images.shape[1]
    if h == size:
        return images
    if h % size:
        raise ValueError(f"cannot area-downsample {h}px images to {size}px (size must divide {h})")
    f = h // size
    n, _, w, c = images.shape
    return images.reshape(n, size, f, w // f, f, c).mean(axis=(2, 4)).astype(np.float32)


def scale_camera(cam: CameraParams, size: int) -> CameraParams:
    """The same camera at another square resolution (normalised uv are unchanged)."""
    s = size / cam.width
    k = np.array(cam.intrinsics, np.float64)
    k[:2] *= s
    return CameraParams(k, cam.cam_to_world, size, size)


# ---------------------------------------------------------------- writing

def write_meta(path: Path, meta: dict) -> None:
    path.mkdir(parents=True, exist_ok=True)
    _atomic_write_text(path / "meta.json", json.dumps(meta, indent=2, sort_keys=True))


def read_meta(path: Path) -> dict | None:
    f = Path(path) / "meta.json"
    if not f.exists():
        return None
    try:
        return json.loads(f.read_text())
    except json.JSONDecodeError as e:
        raise DatasetError(f"{f} is not valid JSON ({e}); delete the folder to regenerate it") from e


def _atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_summary(path: Path, summary: dict) -> None:
    _atomic_write_text(Path(path) / "summary.json", json.dumps(summary, indent=2, sort_keys=True))


def encode_depth(depth01: np.ndarray) -> np.ndarray:
    return np.round(np.clip(depth01, 0, 1) * 65535).astype(np.uint16)


def decode_depth(depth_u16: np.ndarray) -> np.ndarray:
    return depth_u16.astype(np.float32) / 65535.0


def write_shard(path: Path, index: int, *, rgb: np.ndarray, depth01: np.ndarray, motion: np.ndarray,
                joints: np.ndarray, seeds: np.ndarray, raw_frames: np.ndarray, scenes: Scene,
                attempted_seeds: np.ndarray, failed_seeds: np.ndarray) -> Path:
    """Write one shard atomically; returns its path."""
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


def read_progress(path: Path) -> Progress:
    kept, attempted, failed, nxt = 0, [], [], 0
    for s in shards(path):
        try:
            with h5py.File(s, "r") as f:
                kept += len(f["seed"])
                attempted.append(np.asarray(f.attrs["attempted_seeds"]))
                failed.append(np.asarray(f.attrs["failed_seeds"]))
        except (OSError, KeyError) as e:
            raise DatasetError(f"shard {s} is unreadable ({e}); delete it and re-run to regenerate it") from e
        nxt = max(nxt, int(s.stem.split("_")[1]) + 1)
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros((0,), np.int64)  # noqa: E731
    return Progress(kept, cat(attempted), cat(failed), nxt)


# ---------------------------------------------------------------- reading

def load_dataset(path: str | os.PathLike, limit: int | None = None) -> Dataset:
    """Load a split folder (``data/<task>/<split>``); ``limit`` keeps the first demos only."""
    path = Path(path)
    meta = read_meta(path)
    if meta is None:
        raise DatasetError(f"no dataset at {path} (meta.json missing); generate it with "
                           f"`python -m experiments.generate`")
    check_format(path, meta)
    files = shards(path)
    if not files:
        raise DatasetError(f"dataset {path} has no shards yet")
    parts = {k: [] for k in ("rgb", "depth", "motion", "joints", "seed")}
    scene_parts = []
    total = 0
    for s in files:
        try:
            with h5py.File(s, "r") as f:
                for k in parts:
                    parts[k].append(np.asarray(f[k]))
                scene_parts.append(_read_scenes(f["scene"]))
        except (OSError, KeyError) as e:
            raise DatasetError(f"shard {s} is unreadable ({e}); delete it and re-run generation") from e
        total += len(parts["seed"][-1])
        if limit is not None and total >= limit:
            break
    arr = {k: np.concatenate(v) for k, v in parts.items()}
    scenes = _concat_scenes(scene_parts)
    if limit is not None:
        if limit > len(arr["seed"]):
            raise DatasetError(f"{path} holds {len(arr['seed'])} demos, fewer than the {limit} asked for")
        arr = {k: v[:limit] for k, v in arr.items()}
        scenes = take_scenes(scenes, np.arange(limit))
    order = np.argsort(arr["seed"], kind="stable")
    arr = {k: v[order] for k, v in arr.items()}
    scenes = take_scenes(scenes, order)
    if not np.all(np.isfinite(arr["motion"])):
        raise DatasetError(f"{path} contains non-finite motions")
    rgbd = np.concatenate([arr["rgb"].astype(np.float32) / 255.0, decode_depth(arr["depth"])[..., None]], -1)
    return Dataset(
        task=meta["task"], split=meta["split"], camera=CameraParams.from_dict(meta["camera"]), rgbd=rgbd,
        motion=arr["motion"], joints=arr["joints"], seeds=arr["seed"], scenes=scenes, meta=meta,
    )


def check_format(path: Path, meta: dict) -> None:
    """Refuse a dataset of another format in one line that says how to regenerate it."""
    version = meta.get("format_version")
    if version == FORMAT_VERSION:
        return
    why = {1: "it stores no scenes, and its scenes cannot be rebuilt from seeds (before format 2 a scene "
              "depended on its generation batch)",
           2: "its motions record the measured gripper opening, which the evaluation executes as 'open' "
              "around wide objects (format 3 records the commanded state)"}.get(
        version, f"this readjax reads format {FORMAT_VERSION}")
    raise DatasetError(
        f"{path} is a format-{version} dataset: {why}; delete it and regenerate: python -m "
        f"experiments.generate --task {meta.get('task', 'TASK')} --split {meta.get('split', 'SPLIT')} "
        f"--episodes N --image-size {meta.get('image_size', 64)} --out {Path(path).parent.parent}")
