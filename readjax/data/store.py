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
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

import jax

from readjax import tasks
from readjax.camera import CameraParams
from readjax.data.shard_io import (FORMAT_VERSION, SCENE_ARRAYS, SHARD_GLOB, DatasetError,  # noqa: F401
                                   Progress, _concat_scenes, _read_scenes, clean_partial, decode_depth,
                                   encode_depth, read_meta, read_progress, shards, write_meta,
                                   write_shard, write_summary)
from readjax.sim.env import Scene


def split_dir(root: str | os.PathLike, task: str, split: str) -> Path:
    return Path(root) / task / split


def existing_image_size(root: str | os.PathLike, task: str) -> int | None:
    """The image size of the task's train (else test) split on disk; None where neither exists."""
    for split in ("train", "test"):
        meta = read_meta(split_dir(root, task, split))
        if meta:
            return int(meta["image_size"])
    return None


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


# ---------------------------------------------------------------- reading

def load_dataset(path: str | os.PathLike, limit: int | None = None) -> Dataset:
    """Load a split folder (``data/<task>/<split>``); ``limit`` keeps the first demos only."""
    path = Path(path)
    meta = read_meta(path)
    if meta is None:
        raise DatasetError(f"no dataset at {path} (meta.json missing); generate it with "
                           f"`python -m experiments.generate`")
    check_format(path, meta)
    check_suite(path, meta)
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


def check_suite(path: Path, meta: dict) -> None:
    """Refuse a split generated by another suite version of the tasks (readjax.tasks.SUITE_VERSION), in
    one message that says what differs and how to regenerate it."""
    version = tasks.suite_of(meta)
    if version == tasks.SUITE_VERSION:
        return
    raise DatasetError(
        f"{path} was generated by suite {version} of the tasks ({tasks.SUITES.get(version, 'unknown')}); "
        f"this readjax's tasks are suite {tasks.SUITE_VERSION} ({tasks.SUITES[tasks.SUITE_VERSION]}). "
        f"Its scenes and demonstrations belong to another benchmark: delete it (or keep it elsewhere) and "
        f"regenerate: python -m experiments.generate --task {meta.get('task', 'TASK')} --split "
        f"{meta.get('split', 'SPLIT')} --episodes N --image-size {meta.get('image_size', 64)} "
        f"--out {Path(path).parent.parent}")
