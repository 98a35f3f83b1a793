"""Executing plans in simulation (METHOD.md section 11).

A plan's 101 frames are converted to world end-effector poses with the dataset's camera, each
pose is solved by IK (warm-started from the previous one; the null-space pull towards the home
posture runs at the expert's rate, its iterations per control step times the steps per frame, the
remaining iterations converge on the pose alone: pulled to convergence at every frame, the posture
can flip between two frames, a 0.6 rad swing of three joints that the expert spread over nine), and
the arm moves through the joint-space waypoints in order with the gripper open when grip > 0.5.
A waypoint IK cannot reach (error > ``reach_tol``) is skipped (the arm holds the previous one);
more than ``max_skipped`` skips abort the episode as a failure. Success = the task's condition held
at any control step (the environment tracks it), without a failure.

Plans run in the episodes' *stored* scenes (``Dataset.scenes``), never in scenes re-sampled from
seeds: :func:`readjax.data.guard.check_scene_images` proves beforehand that each scene is the one
its image shows.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from readjax import motion as motion_lib
from readjax import sharding
from readjax.sim import ik
from readjax.sim.camera import CameraParams
from readjax.sim.controller import IK_ITERATIONS_PER_STEP, rollout_joints
from readjax.sim.kinematics import HOME_Q

TRACE_KEYS = ("tcp_pos", "ctrl", "attached", "rel_pos", "rel_quat")


@dataclass(frozen=True)
class ExecConfig:
    ik_iterations: int = 25  # per waypoint, warm-started from the previous waypoint
    reach_pos_tol: float = 0.01  # m: a waypoint IK misses by more is "cannot be reached"
    reach_rot_tol: float = 0.1  # rad
    max_skipped: int = 10  # more skipped waypoints abort the episode (METHOD.md section 11)
    # the null-space pull towards the home posture at the expert's rate: its IK iterations per control
    # step times the control steps per frame (the rest of a waypoint's iterations converge on the pose
    # alone), so the posture drifts as continuously as the expert's did; False: every iteration pulls
    expert_rate_posture: bool = True


def execution_record(cfg: ExecConfig = ExecConfig()) -> dict:
    """How plans were executed, as records keep it (``execution``): a replay or evaluation compares
    with another only under the same."""
    return asdict(cfg)


def segment_durations(env) -> tuple[int, ...]:
    """Control steps between consecutive frames: the expert's episode length spread over 100 gaps,
    so a plan is executed at the demonstrations' pace."""
    per = max(1, int(round(env.episode_steps / 100)))
    return (per,) * (motion_lib.FRAMES)


def solve_waypoints(env, pos: jax.Array, rot: jax.Array, cfg: ExecConfig):
    """IK through (W, 3) / (W, 3, 3) poses; returns q (W, 7) with skipped ones held, skipped (W,)."""
    q_home = jnp.asarray(HOME_Q)
    pulls = min(cfg.ik_iterations, IK_ITERATIONS_PER_STEP * segment_durations(env)[0])

    def body(q_prev, target):
        p, r = target
        if not cfg.expert_rate_posture:
            q = ik.solve_ik(env.chain, q_prev, p, r, cfg.ik_iterations)
        else:
            q = ik.solve_ik(env.chain, q_prev, p, r, pulls)
            q = ik.solve_ik(env.chain, q, p, r, cfg.ik_iterations - pulls, rest=q)
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
            "held": jnp.any(trace.attached),  # an object was held at some step (a grasp happened)
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
    batch_size = sharding.fit_batch(batch_size, n)
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
