"""Executing predicted motions in simulation (METHOD.md section 11) and success tables.

A plan's 101 frames are converted to world end-effector poses with the dataset's camera, each
pose is solved by IK (warm-started from the previous one, so the arm takes the nearby branch), and
the arm moves through the joint-space waypoints in order with the gripper open when grip > 0.5.
A waypoint IK cannot reach (error > ``reach_tol``) is skipped (the arm holds the previous one);
more than ``max_skipped`` skips abort the episode as a failure. Success = the task's condition held
at any control step (the environment tracks it), without a failure.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from readjax import sharding, tasks
from readjax.data import motion as motion_lib
from readjax.sim import ik
from readjax.sim.camera import CameraParams
from readjax.sim.controller import rollout_joints
from readjax.sim.kinematics import HOME_Q

TRACE_KEYS = ("tcp_pos", "ctrl", "attached", "rel_pos", "rel_quat")
AVG12 = tasks.AVG12
AVG16 = tasks.AVG16


@dataclass(frozen=True)
class ExecConfig:
    ik_iterations: int = 25  # per waypoint, warm-started from the previous waypoint
    reach_pos_tol: float = 0.01  # m: a waypoint IK misses by more is "cannot be reached"
    reach_rot_tol: float = 0.1  # rad
    max_skipped: int = 10  # more skipped waypoints abort the episode (METHOD.md section 11)


def segment_durations(env) -> tuple[int, ...]:
    """Control steps between consecutive frames: the expert's episode length spread over 100 gaps,
    so a plan is executed at the demonstrations' pace."""
    per = max(1, int(round(env.episode_steps / 100)))
    return (per,) * (motion_lib.FRAMES)


def solve_waypoints(env, pos: jax.Array, rot: jax.Array, cfg: ExecConfig):
    """IK through (W, 3) / (W, 3, 3) poses; returns q (W, 7) with skipped ones held, skipped (W,)."""
    q_home = jnp.asarray(HOME_Q)

    def body(q_prev, target):
        p, r = target
        q = ik.solve_ik(env.chain, q_prev, p, r, cfg.ik_iterations)
        pe, re = ik.pose_error(env.chain, q, p, r)
        ok = (pe < cfg.reach_pos_tol) & (re < cfg.reach_rot_tol)
        q_keep = jnp.where(ok, q, q_prev)
        return q_keep, (q_keep, ~ok)

    _, (q, skipped) = lax.scan(body, q_home, (pos, rot))
    return q, skipped


@functools.cache
def executor(env, cam: CameraParams, cfg: ExecConfig = ExecConfig()):
    """jit(vmap(execute)) for one task and camera: (scenes, motions (B,101,10)) -> results dict."""
    durations = segment_durations(env)

    def execute(scene, motion):
        pos, rot, grip = motion_lib.decode(cam, motion)
        q_way, skipped = solve_waypoints(env, pos, rot, cfg)
        state = env.reset_to(scene)
        state, trace = rollout_joints(env, state, q_way, (grip > 0.5).astype(jnp.float32), durations)
        n_skip = jnp.sum(skipped)
        aborted = n_skip > cfg.max_skipped
        return {
            "success": state.success & ~aborted,
            "skipped": n_skip,
            "aborted": aborted,
            "failure": state.failure,
            "tcp_pos": trace.tcp_pos,
            "ctrl": trace.ctrl,
            "attached": trace.attached,
            "rel_pos": trace.rel_pos,
            "rel_quat": trace.rel_quat,
        }

    return jax.jit(jax.vmap(execute))


def execute_motions(env, cam: CameraParams, scenes, motions, batch_size: int = 32,
                    cfg: ExecConfig = ExecConfig(), keep_traces: bool = False) -> dict[str, np.ndarray]:
    """Execute many plans in batches (padded to a fixed batch so one compile serves all)."""
    motions = np.asarray(motions, np.float32)
    motion_lib.check_motion(motions, "plans")
    n = len(motions)
    sharding.check_batch(batch_size)
    fn = executor(env, cam, cfg)
    out: dict[str, list] = {}
    for start in range(0, n, batch_size):
        idx = np.arange(start, start + batch_size) % n  # pad the last batch by wrapping around
        sc = jax.tree.map(lambda x: jnp.asarray(np.asarray(x)[idx]), scenes)
        res = jax.tree.map(np.asarray, fn(sc, jnp.asarray(motions[idx])))
        take = min(batch_size, n - start)
        for k, v in res.items():
            if k in TRACE_KEYS and not keep_traces:
                continue
            out.setdefault(k, []).append(v[:take])
    return {k: np.concatenate(v) for k, v in out.items()}


def scenes_for_seeds(env, seeds) -> object:
    """The episodes' scenes, re-sampled from their seeds (pure function of (task, seed))."""
    keys = jax.vmap(jax.random.key)(jnp.asarray(np.asarray(seeds), jnp.int32))
    return jax.tree.map(np.asarray, jax.jit(jax.vmap(env.sample_scene))(keys))


def success_table(rates: dict[str, float]) -> dict[str, float]:
    """Per-task success (%) plus Avg12 / Avg16 where every member task is present (paper layout)."""
    by_code = {tasks.code_of(t): 100.0 * r for t, r in rates.items()}
    table = {c: by_code[c] for c in AVG16 if c in by_code}
    if all(c in by_code for c in AVG12):
        table["Avg12"] = float(np.mean([by_code[c] for c in AVG12]))
    if all(c in by_code for c in AVG16):
        table["Avg16"] = float(np.mean([by_code[c] for c in AVG16]))
    if "Avg12" not in table and by_code:
        table["Avg"] = float(np.mean(list(by_code.values())))
    return table


def format_table(rows: dict[str, dict[str, float]]) -> str:
    """Methods x tasks in the paper's column order (PC RT PB ... | Avg12 Avg16)."""
    cols = [c for c in list(AVG16) + ["Avg", "Avg12", "Avg16"] if any(c in r for r in rows.values())]
    width = max([6] + [len(m) for m in rows])
    head = f"{'method':<{width}} " + " ".join(f"{c:>6}" for c in cols)
    lines = [head, "-" * len(head)]
    for m, r in rows.items():
        lines.append(f"{m:<{width}} " + " ".join(f"{r[c]:6.1f}" if c in r else f"{'-':>6}" for c in cols))
    return "\n".join(lines)


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


def perturb_images(rgbd: np.ndarray, cfg: EvalConfig, seed: int) -> np.ndarray:
    """Table 9's perturbed test images: Gaussian noise on RGB and a brightness factor."""
    if cfg.image_noise == 0 and cfg.brightness == 1.0:
        return rgbd
    rng = np.random.default_rng(seed)
    out = rgbd.copy()
    out[..., :3] = out[..., :3] * cfg.brightness + rng.normal(scale=cfg.image_noise, size=out[..., :3].shape)
    out[..., :3] = np.clip(out[..., :3], 0, 1)
    return out.astype(np.float32)


def evaluate(planner, test_ds, cfg: EvalConfig, out_dir=None, name: str = "eval", progress: bool = True) -> dict:
    """Plan for the test episodes, execute every plan in MJX, write ``out_dir/<name>.json``
    (+ an overlay PNG and a rollout MP4) and return the result dict."""
    import json
    import time
    from pathlib import Path

    from tqdm.auto import tqdm

    from readjax import provenance

    if cfg.episodes > len(test_ds):
        raise ValueError(f"the test split holds {len(test_ds)} episodes, fewer than --episodes {cfg.episodes}")
    ds = test_ds.subset(np.arange(cfg.episodes)).resized(planner.image_size)
    env = planner.env
    scenes = scenes_for_seeds(env, ds.seeds)
    images = perturb_images(ds.rgbd, cfg, cfg.seed)
    n_steps = planner.n_steps if cfg.N is None else cfg.N
    t0 = time.time()
    plans = []
    bs = min(cfg.batch_size, len(ds))
    for s in tqdm(range(0, len(ds), bs), desc="planning", disable=not progress, unit="batch"):
        idx = np.arange(s, s + bs) % len(ds)  # fixed batch shape: one compile
        key = jax.random.fold_in(jax.random.key(cfg.seed), s)
        p = planner.plan(images[idx], key, N=n_steps, retrieval_method=cfg.retrieval,
                         gt_motion=ds.motion[idx], rank=cfg.rank)
        take = min(bs, len(ds) - s)
        plans.append(jax.tree.map(lambda x: x[:take], vars(p)))
    plan = {k: np.concatenate([p[k] for p in plans]) for k in plans[0]}
    t_plan = time.time() - t0
    res = execute_motions(env, planner.camera, scenes, plan["motion"], batch_size=bs,
                          keep_traces=cfg.videos > 0)
    t_exec = time.time() - t0 - t_plan
    rate = float(np.mean(res["success"]))
    result = {
        "task": planner.task, "code": tasks.code_of(planner.task), "run": str(planner.run_dir),
        "method": planner.spec.get("method", "read"), "name": name,
        "success_rate": rate, "table": success_table({planner.task: rate}),
        "episodes": len(ds), "seeds": ds.seeds.tolist(), "success": res["success"].astype(int).tolist(),
        "skipped_waypoints_mean": float(np.mean(res["skipped"])), "aborted": int(np.sum(res["aborted"])),
        # mean world-frame distance between the retrieved and the ground-truth end-effector paths
        "retrieval_error_m": _path_distance(planner.camera, plan["retrieved"], ds.motion),
        "eval_config": {**vars(cfg), "N": n_steps if planner.model.iterative else None}, "configs": planner.spec.get("configs"),
        "seconds": {"planning": round(t_plan, 2), "execution": round(t_exec, 2)},
        "versions": provenance.versions(), "machine": provenance.machine(),
    }
    if out_dir is not None:
        from readjax import viz

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{name}.json").write_text(json.dumps(result, indent=2))
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


class _AttrTree(dict):
    """A dict whose keys are also attributes, and which jax.tree maps like a dict."""

    def __getattr__(self, k):
        return self[k]


jax.tree_util.register_pytree_node(
    _AttrTree, lambda d: (list(d.values()), list(d.keys())), lambda keys, vals: _AttrTree(zip(keys, vals)))


def _path_distance(camera, a: np.ndarray, b: np.ndarray) -> float:
    """Mean distance (m) between the end-effector positions of two motion batches (B, 101, 10)."""
    pa = np.asarray(motion_lib.decode(camera, jnp.asarray(a))[0])
    pb = np.asarray(motion_lib.decode(camera, jnp.asarray(b))[0])
    return float(np.mean(np.linalg.norm(pa - pb, axis=-1)))
