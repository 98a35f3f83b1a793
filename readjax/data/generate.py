"""Batched scripted-demonstration generation (MJX rollouts, vmapped and sharded over devices).

For a task and split, seeds are tried in a fixed order (train: 0, 1, 2, ...; test: 1_000_000,
1_000_001, ...; the two never overlap) and a demo is kept only if the expert succeeded
(RLBench's rule). The dataset is the first ``episodes`` successful seeds, so it is a pure
function of (task, split, episodes) and resuming an interrupted run reproduces it exactly.
"""

from __future__ import annotations

import functools
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from readjax import provenance, sharding, tasks
from readjax.prng import seed_pure
from readjax.data import store
from readjax.data.resample import resample_demo
from readjax.sim import camera as cam_lib
from readjax.sim.controller import rollout
from readjax.sim.kinematics import fk
from readjax.sim.render import DEPTH_FAR, DEPTH_NEAR, SceneRenderer, render_scenes

# seeds of each split: disjoint ranges (a validation split chooses settings; test reports them)
SPLITS = {"train": 0, "test": 1_000_000, "val": 2_000_000}
MAX_ATTEMPT_FACTOR = 3  # give up when the expert fails this often (a broken task)


@dataclass(frozen=True)
class GenerateConfig:
    task: str
    split: str = "train"
    episodes: int = 200
    out: str = "data"
    batch_size: int = 32
    image_size: int = 128
    camera: str = "front"

    def validate(self) -> "GenerateConfig":
        task = tasks.canonical_name(self.task)
        if self.split not in SPLITS:
            raise ValueError(f"unknown split {self.split!r}; use one of {sorted(SPLITS)}")
        if not isinstance(self.episodes, int) or self.episodes < 1:
            raise ValueError(f"--episodes must be a positive integer, got {self.episodes!r}")
        if self.batch_size < 1:
            raise ValueError(f"--batch-size must be positive, got {self.batch_size}")
        sharding.check_batch(self.batch_size)
        if self.image_size < 16 or self.image_size > 512:
            raise ValueError(f"--image-size must be in [16, 512], got {self.image_size}")
        return GenerateConfig(task, self.split, self.episodes, self.out, self.batch_size, self.image_size,
                              self.camera)


def split_seeds(split: str, start: int, count: int) -> np.ndarray:
    return SPLITS[split] + np.arange(start, start + count, dtype=np.int64)


@functools.cache
def episode_fn(env):
    """jit(vmap(reset -> expert rollout)) over a batch of integer seeds (one per env and process).
    Scenes come from seed-pure keys (``TaskEnv.sample_scene``), so an episode is a function of its
    seed alone, whatever the batch."""

    def episode(seed):
        st0 = env.reset(seed_pure(seed))
        plan = env.expert_plan(st0.scene)
        st, trace = rollout(env, st0, plan, env.expert_durations)
        q0 = st0.data.qpos[env.chain.qpos_adr]
        # a seed without a valid placement (no candidate fitted or could be reached) is dropped like
        # one whose expert fails: RLBench's rule that an unsuccessful demo is not a demo
        ok = st.success & ~st.failure & st0.scene.params["feasible"]
        return st0.scene, ok, q0, trace

    return jax.jit(jax.vmap(episode), in_shardings=sharding.batch_sharding())


def traces_to_motions(env, cam: cam_lib.CameraParams, q0: np.ndarray, trace) -> tuple[np.ndarray, np.ndarray]:
    """Recorded rollouts (B, T, ...) plus the start state -> motions (B, 101, 10), joints (B, 101, 7)."""
    p0, r0 = fk(env.chain, jnp.asarray(q0))
    pos = np.concatenate([np.asarray(p0)[:, None], np.asarray(trace.tcp_pos)], 1)
    rot = np.concatenate([np.asarray(r0)[:, None], np.asarray(trace.tcp_rot)], 1)
    # The gripper's commanded state (1 open, 0 closed), like RLBench's binary gripper_open, not the
    # measured opening: around a wide object (put_rubbish's ball) the closed fingers stay 65 % open,
    # which the evaluation protocol (open if grip > 0.5) would execute as "open".
    grip = np.concatenate([np.ones((len(q0), 1), np.float32), np.asarray(trace.grip_cmd)], 1)
    joints = np.concatenate([np.asarray(q0)[:, None], np.asarray(trace.q)], 1)
    uvz = np.asarray(cam_lib.project_uvz(cam, jnp.asarray(pos)))
    r_cam = np.asarray(cam_lib.rotation_to_camera(cam, jnp.asarray(rot)))
    motions, joint_out = [], []
    for b in range(len(q0)):
        uvz_b, rot_b, grip_b, q_b = resample_demo(uvz[b], r_cam[b], grip[b], joints[b])
        m = np.concatenate([uvz_b, rot_b[:, :2, :].reshape(-1, 6), grip_b[:, None]], axis=1)
        motions.append(m)
        joint_out.append(q_b)
    return np.stack(motions).astype(np.float32), np.stack(joint_out).astype(np.float32)


def dataset_meta(cfg: GenerateConfig, env, cam: cam_lib.CameraParams) -> dict:
    return {
        "task": cfg.task, "code": env.code, "split": cfg.split, "image_size": cfg.image_size,
        "camera_name": cfg.camera, "camera": cam.to_dict(), "depth_near": DEPTH_NEAR, "depth_far": DEPTH_FAR,
        "control_dt": env.control_dt, "episode_steps": env.episode_steps,
        "format_version": store.FORMAT_VERSION, "seed_base": SPLITS[cfg.split],
        "suite": tasks.SUITE_VERSION,
    }


def check_existing(path: Path, meta: dict) -> None:
    """Refuse to mix demos of another task/split/image size into an existing folder."""
    old = store.read_meta(path)
    if old is None:
        if store.shards(path):
            raise store.DatasetError(f"{path} holds shards but no meta.json; remove it or choose another --out")
        return
    store.check_format(path, old)
    store.check_suite(path, old)
    for key in ("task", "split", "image_size", "camera_name"):
        if old.get(key) != meta[key]:
            raise store.DatasetError(
                f"{path} already holds a dataset with {key}={old.get(key)!r}, not {meta[key]!r}; "
                f"choose another --out or delete that folder"
            )


def generate(cfg: GenerateConfig, progress: bool = True, stop_after_batches: int | None = None) -> dict:
    """Generate (or resume) a split; returns the summary also written to ``summary.json``.

    ``stop_after_batches`` simulates an interruption (for tests of resuming).
    """
    cfg = cfg.validate()
    env = tasks.make(cfg.task)
    path = store.split_dir(cfg.out, cfg.task, cfg.split)
    cam = cam_lib.camera_from_model(env.mj_model, cfg.camera, cfg.image_size, cfg.image_size)
    meta = dataset_meta(cfg, env, cam)
    check_existing(path, meta)
    path.mkdir(parents=True, exist_ok=True)
    store.clean_partial(path)
    store.write_meta(path, dict(meta, versions=provenance.versions()))
    done = store.read_progress(path)
    kept, attempted_n, failed_n = done.kept, len(done.attempted), len(done.failed)
    infeasible_n = len(done.infeasible)
    next_seed = int(done.attempted.max() - SPLITS[cfg.split] + 1) if attempted_n else 0
    shard_idx = done.next_shard
    start = time.time()
    run_fn = episode_fn(env) if kept < cfg.episodes else None
    max_attempts = MAX_ATTEMPT_FACTOR * cfg.episodes + cfg.batch_size
    bar = _progress_bar(progress, cfg, kept)
    batches = 0
    with SceneRenderer(env.mj_model, cfg.image_size, cfg.image_size, cfg.camera) as renderer:
        while kept < cfg.episodes:
            if attempted_n >= max_attempts:
                raise RuntimeError(
                    f"{cfg.task}: expert succeeded on only {kept}/{attempted_n} seeds; giving up "
                    f"(a task whose expert fails this often is broken)"
                )
            seeds = split_seeds(cfg.split, next_seed, cfg.batch_size)
            scenes, ok, q0, trace = run_fn(jnp.asarray(seeds, jnp.int32))  # async: render meanwhile
            rgb, depth = render_scenes(renderer, env, scenes)
            ok = np.asarray(ok)
            feasible = np.asarray(scenes.params["feasible"])
            # Keep successes in seed order until the target count; later seeds are not attempted.
            need = cfg.episodes - kept
            cum = np.cumsum(ok)
            last = len(seeds) if cum[-1] <= need else int(np.searchsorted(cum, need)) + 1
            ok, sel = ok[:last], np.flatnonzero(ok[:last])
            motions, joints = traces_to_motions(env, cam, np.asarray(q0)[sel],
                                                jax.tree.map(lambda x: np.asarray(x)[sel], trace))
            store.write_shard(
                path, shard_idx, rgb=rgb[sel], depth01=depth[sel], motion=motions, joints=joints,
                seeds=seeds[sel], raw_frames=np.full(len(sel), env.episode_steps + 1),
                scenes=store.take_scenes(scenes, sel),
                attempted_seeds=seeds[:last], failed_seeds=seeds[:last][~ok],
                infeasible_seeds=seeds[:last][~feasible[:last]],
            )
            shard_idx += 1
            kept += len(sel)
            attempted_n += last
            failed_n += int((~ok).sum())
            infeasible_n += int((~feasible[:last]).sum())
            next_seed += last
            bar.update(len(sel))
            bar.set_postfix(expert=f"{kept}/{attempted_n}")
            batches += 1
            if stop_after_batches is not None and batches >= stop_after_batches and kept < cfg.episodes:
                bar.close()
                return {"interrupted": True, "episodes_kept": kept}
    bar.close()
    summary = {
        **asdict(cfg),
        "episodes_kept": kept,
        "episodes_attempted": attempted_n,
        "episodes_failed": failed_n,
        "expert_success_rate": kept / max(attempted_n, 1),
        # RLBench's rule: a seed without a valid placement has no demonstration; the expert's own
        # success is counted over the seeds that had one
        "episodes_infeasible": infeasible_n,
        "expert_success_rate_feasible": kept / max(attempted_n - infeasible_n, 1),
        # summed over the invocations that built the split (a resumed or no-op run adds its own)
        "seconds": round(_previous_seconds(path) + time.time() - start, 2),
        "physics_steps_per_episode": env.episode_steps * env.substeps,
        "versions": provenance.versions(),
        "machine": provenance.machine(),
    }
    store.write_summary(path, summary)
    return summary


def _previous_seconds(path: Path) -> float:
    f = Path(path) / "summary.json"
    try:
        return float(json.loads(f.read_text()).get("seconds", 0.0)) if f.exists() else 0.0
    except (ValueError, OSError):
        return 0.0


def _progress_bar(enabled: bool, cfg: GenerateConfig, initial: int):
    return tqdm(total=cfg.episodes, initial=initial, desc=f"{cfg.task}/{cfg.split}", unit="demo",
                disable=not enabled, dynamic_ncols=True)
