"""Evaluation: plan for a test split, execute every plan in the episode's stored scene, tabulate.

Two entry points share one execution path -- the scene guard
(:func:`readjax.data.guard.check_scene_images`), then :func:`readjax.sim.execute.execute_motions`
in the stored scenes: :func:`evaluate` runs a planner's motions (the guard runs before planning,
so a mismatch costs no planning time) and :func:`replay_ground_truth` the split's own recorded
motions, which must succeed 100 % -- the check that an evaluation measures what it says.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import jax
import numpy as np
from tqdm.auto import tqdm

from readjax import atomic_write, failure_modes, provenance, retrieval, stage_folder, tables, tasks, viz
from readjax import motion as motion_lib
from readjax.data.guard import check_scene_images
from readjax.data.store import Dataset
from readjax.sim.execute import execute_motions, execution_record

@dataclass(frozen=True)
class EvalConfig:
    episodes: int = 100
    N: int | None = None  # refinement steps; None = the planner's default
    retrieval: str = "spe"  # or "cheat" (oracle)
    rank: int = 1  # oracle neighbour rank
    batch_size: int = 50
    seed: int = 0
    videos: int = 4  # rollouts rendered to the MP4 (0 = none)
    image_noise: float = 0.0  # Table 9 perturbations of the test image
    brightness: float = 1.0
    candidates: int = 1  # SPE candidates refined, the one with the smallest fixed-point residual kept
    rounds: int | None = None  # refinements in a row, each from the previous plan; None = the run's sde.rounds


def perturb_images(rgbd: np.ndarray, cfg: EvalConfig, seed: int, episode_seeds: np.ndarray) -> np.ndarray:
    """Table 9's perturbed test images: Gaussian noise on RGB and a brightness factor. Each image's
    noise is drawn from (``seed``, its episode's seed) alone, so an episode sees the same image in
    any subset or order of the split."""
    if cfg.image_noise == 0 and cfg.brightness == 1.0:
        return rgbd
    out = rgbd.astype(np.float32, copy=True)
    for i, episode in enumerate(np.asarray(episode_seeds)):
        noise = np.random.default_rng([seed, int(episode)]).normal(scale=cfg.image_noise, size=out[i, ..., :3].shape)
        out[i, ..., :3] = np.clip(out[i, ..., :3] * cfg.brightness + noise, 0, 1)
    return out


def evaluate(planner, test_ds, cfg: EvalConfig, out_dir=None, name: str = "eval", progress: bool = True,
             extra: dict | None = None) -> dict:
    """Plan for the episodes of ``test_ds`` (the test split, or the validation split: the record names
    which), execute every plan in its stored scene (after the scene guard), write
    ``out_dir/<name>.json`` (+ an overlay PNG and a rollout MP4) and return the result dict;
    ``extra``: fields added to the record (where its refinement setting was chosen)."""
    if cfg.episodes > len(test_ds):
        raise ValueError(f"the test split holds {len(test_ds)} episodes, fewer than --episodes {cfg.episodes}")
    env = planner.env
    ds = test_ds.subset(np.arange(cfg.episodes))
    check_scene_images(env, ds)  # before any planning: a mismatch wastes no time
    ds = ds.resized(planner.image_size)
    scenes = ds.scenes
    images = perturb_images(ds.rgbd, cfg, cfg.seed, ds.seeds)
    n_steps = planner.n_steps if cfg.N is None else cfg.N
    rounds = (planner.default_rounds if n_steps > 0 else 1) if cfg.rounds is None else cfg.rounds
    t0 = time.time()
    plans = []
    bs = min(cfg.batch_size, len(ds))
    for s in tqdm(range(0, len(ds), bs), desc="planning", disable=not progress, unit="batch"):
        idx = np.arange(s, s + bs) % len(ds)  # fixed batch shape: one compile
        key = jax.random.fold_in(jax.random.key(cfg.seed), s)
        p = planner.plan(images[idx], key, N=n_steps, retrieval_method=cfg.retrieval,
                         gt_motion=ds.motion[idx], rank=cfg.rank, candidates=cfg.candidates,
                         rounds=rounds)
        take = min(bs, len(ds) - s)
        plans.append(jax.tree.map(lambda x: x[:take], vars(p)))
    plan = {k: np.concatenate([p[k] for p in plans]) for k in plans[0]}
    t_plan = time.time() - t0
    res = execute_motions(env, planner.camera, scenes, plan["motion"], batch_size=bs,
                          keep_traces=cfg.videos > 0)  # scenes already checked against the images
    t_exec = time.time() - t0 - t_plan
    rate = float(np.mean(res["success"]))
    retrieved_pos = np.asarray(retrieval.positions(planner.camera, plan["retrieved"]))  # where each plan's refinement started
    gt_pos, gt_rot = motion_lib.world_poses(planner.camera, ds.motion)
    result = {
        "task": planner.task, "code": tasks.code_of(planner.task), "run": str(planner.run_dir),
        "method": planner.spec.get("method", "read"), "name": name, "split": test_ds.split,
        "success_rate": rate, "table": tables.success_table({planner.task: rate}),
        "episodes": len(ds), "seeds": ds.seeds.tolist(), "scenes": "stored (guard passed)", "success": res["success"].astype(int).tolist(),
        "skipped_waypoints_mean": float(np.mean(res["skipped"])), "aborted": int(np.sum(res["aborted"])),
        # mean world-frame distance between the retrieved and the ground-truth end-effector paths
        "retrieval_error_m": float(np.mean(np.linalg.norm(retrieved_pos - gt_pos, axis=-1))),
        "execution": execution_record(),  # how plans were executed (IK, skipped waypoints)
        "eval_config": {**vars(cfg), "N": n_steps if planner.model.iterative else None, "rounds": rounds,
                        "refine_update": refine_update(planner.model)},
        "configs": planner.spec.get("configs"),
        "training": stage_folder.stage_records(planner.run_dir),  # per stage: steps and why it stopped
        # which data: the evaluated split as stored (experiments.verify records the same hash; the field
        # keeps its name for a val split too, ``split`` says which) and the training set the run learnt
        # from; a table row is only comparable to rows on the same test split
        "test_fingerprint": test_ds.fingerprint, "train_fingerprint": planner.spec.get("dataset_fingerprint"),
        "suite": tasks.suite_of(test_ds.meta),  # which version of the tasks the episodes belong to
        "seconds": {"planning": round(t_plan, 2), "execution": round(t_exec, 2)},
        "versions": provenance.versions(), "machine": provenance.machine(), "commit": provenance.commit(),
        **(extra or {}),
    }
    # every failure by mode (unreachable, gripper sequence, wrong place, depth, ..., task failure)
    result["failures"] = failure_modes.diagnose(
        plan["motion"], (plan["positions"], plan["rotations"]), ds.motion, (gt_pos, gt_rot),
        np.asarray(planner.camera.cam_to_world)[:3, 3], res["success"], res["aborted"], res["failure"],
        res["held"] if env.graspable else None,
        start_pos=retrieved_pos if planner.model.uses_retrieval or cfg.retrieval == "cheat" else None)
    marks = scene_landmarks(env, scenes)
    if marks:  # where each plan ended: failures counted by the object they went for
        result["end_points"] = failure_modes.summarise(plan["positions"][:, -1], marks, res["success"])
        if planner.model.uses_retrieval or cfg.retrieval == "cheat":  # and where refinement started
            result["starts"] = failure_modes.by_start(retrieved_pos[:, -1], marks, res["success"])
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        # a reader (a parallel grid's copy) never sees half of it
        atomic_write.write_text(out / f"{name}.json", json.dumps(result, indent=2), tmp_name=f".{name}.json.tmp")
        k = min(8, len(ds))
        viz.motion_overlay(ds.rgbd[:k], [("retrieved", plan["retrieved"][:k], (255, 200, 0)),
                                         ("planned", plan["motion"][:k], (0, 200, 255)),
                                         ("ground truth", ds.motion[:k], (60, 230, 60))],
                           out / f"{name}_overlay.png",
                           titles=["ok" if s else "fail" for s in res["success"][:k]])
        if cfg.videos > 0:
            traces = _AttrTree({kk: res[kk] for kk in ("ctrl", "attached", "rel_pos", "rel_quat")})
            frames = viz.rollout_video(env, scenes, traces, max_episodes=cfg.videos)
            viz.save_video(out / f"{name}_rollouts.mp4", frames)
    return result


def scene_landmarks(env, scenes) -> dict[str, np.ndarray]:
    """The task's landmark groups (``TaskEnv.landmarks``) of a batch of scenes: {name: (B, k, 3)};
    empty for tasks that define none."""
    if not env.landmarks(jax.tree.map(lambda x: x[0], scenes)):
        return {}
    return {k: np.asarray(v) for k, v in jax.vmap(env.landmarks)(scenes).items()}


def refine_update(model) -> str | None:
    """The inference update (``sde.update``) the model will run (READ, READ-L, READ-O with CD); None
    for other methods."""
    return getattr(model, "refine_update", None)


def replay_ground_truth(env, ds: Dataset, batch_size: int = 32) -> dict:
    """Execute a split's own recorded motions exactly as :func:`evaluate` executes plans (scene
    guard, decode -> IK -> MJX -> predicate). Anything below 100 % means the evaluation path does
    not measure what it claims."""
    t0 = time.time()
    check_scene_images(env, ds)
    t_guard = time.time() - t0
    res = execute_motions(env, ds.camera, ds.scenes, ds.motion, batch_size=batch_size)
    success = res["success"].astype(bool)
    return {
        "task": ds.task, "code": tasks.code_of(ds.task), "split": ds.split, "episodes": len(ds),
        "success_rate": float(success.mean()), "successes": int(success.sum()),
        "failed_seeds": ds.seeds[~success].tolist(), "seeds": ds.seeds.tolist(),
        "success": success.astype(int).tolist(),
        "skipped_waypoints_mean": float(np.mean(res["skipped"])), "aborted": int(np.sum(res["aborted"])),
        "image_size": ds.image_size, "batch_size": batch_size, "format_version": ds.meta.get("format_version"),
        "suite": tasks.suite_of(ds.meta),
        "dataset_fingerprint": ds.fingerprint, "commit": provenance.commit(),
        "execution": execution_record(),
        "seconds": {"guard": round(t_guard, 2), "execution": round(time.time() - t0 - t_guard, 2)},
        "versions": provenance.versions(), "machine": provenance.machine(),
    }


class _AttrTree(dict):
    """A dict whose keys are also attributes, and which jax.tree maps like a dict."""

    def __getattr__(self, k):
        return self[k]


jax.tree_util.register_pytree_node(
    _AttrTree, lambda d: (list(d.values()), list(d.keys())), lambda keys, vals: _AttrTree(zip(keys, vals)))

