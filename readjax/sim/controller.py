"""Following end-effector waypoints: Cartesian interpolation -> IK -> joint targets -> physics.

A :class:`WaypointPlan` is W end-effector poses with a gripper command each; segment i moves
from pose i-1 (the start pose for i = 0) to pose i over ``durations[i]`` control steps with a
smooth (zero-velocity at both ends) profile, commanding the gripper ``grip[i]`` throughout.
Durations are static Python ints so an episode is one fixed-length ``lax.scan``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import lax

from readjax import geometry as geo
from readjax.sim import ik
from readjax.sim.kinematics import fk, grip_from_fingers

IK_ITERATIONS_PER_STEP = 3  # the expert's warm-started IK iterations per 20 ms control step

@struct.dataclass
class WaypointPlan:
    pos: jax.Array  # (W, 3) world
    quat: jax.Array  # (W, 4) world, w x y z
    grip: jax.Array  # (W,) 1 = open, 0 = closed


class Trace(NamedTuple):
    """What a rollout records at every control step (after the step)."""

    tcp_pos: jax.Array  # (T, 3)
    tcp_rot: jax.Array  # (T, 3, 3)
    q: jax.Array  # (T, 7) measured arm joints
    grip: jax.Array  # (T,) measured gripper opening in [0, 1]
    grip_cmd: jax.Array  # (T,) the gripper command of the step: 1 = open, 0 = closed (what a motion records)
    success: jax.Array  # (T,) success reached so far
    ik_error: jax.Array  # (T,) position error of the IK command against its target (m)
    ctrl: jax.Array  # (T, nu) actuator command applied during the step (replayable in C MuJoCo)
    attached: jax.Array  # (T, n_graspable) grasp state after the step
    rel_pos: jax.Array  # (T, n_graspable, 3) attached objects' pose in the tcp frame
    rel_quat: jax.Array  # (T, n_graspable, 4)


def segment_schedule(durations) -> tuple[np.ndarray, np.ndarray]:
    """Per control step: segment index and interpolation fraction in (0, 1]."""
    durations = np.asarray(durations, np.int64)
    if durations.ndim != 1 or np.any(durations < 1):
        raise ValueError(f"segment durations must be positive integers, got {durations}")
    seg = np.repeat(np.arange(len(durations)), durations)
    start = np.concatenate([[0], np.cumsum(durations)[:-1]])
    frac = (np.arange(len(seg)) - start[seg] + 1) / durations[seg]
    return seg.astype(np.int32), frac.astype(np.float32)


def smoothstep(a: jax.Array) -> jax.Array:
    return a * a * (3 - 2 * a)


def plan_targets(plan: WaypointPlan, start_pos: jax.Array, start_quat: jax.Array, durations):
    """Cartesian target (pos, quat, grip) for every control step: arrays (T, ...)."""
    seg, frac = segment_schedule(durations)
    pos_from = jnp.concatenate([start_pos[None], plan.pos[:-1]])[seg]
    quat_from = jnp.concatenate([start_quat[None], plan.quat[:-1]])[seg]
    a = smoothstep(jnp.asarray(frac))
    pos = pos_from + a[:, None] * (plan.pos[seg] - pos_from)
    quat = geo.slerp(quat_from, plan.quat[seg], a)
    return pos, quat, plan.grip[seg]


def rollout(env, state, plan: WaypointPlan, durations, ik_iterations: int = IK_ITERATIONS_PER_STEP):
    """Execute a plan from ``state``; returns (final state, :class:`Trace`). Pure, jit/vmap-able."""
    q0 = state.data.qpos[env.chain.qpos_adr]
    p0, r0 = fk(env.chain, q0)
    pos, quat, grip = plan_targets(plan, p0, geo.mat_to_quat(r0), durations)
    rot = geo.quat_to_mat(quat)

    def body(carry, target):
        st, q_cmd = carry
        p_t, r_t, g_t = target
        q_cmd = ik.solve_ik(env.chain, q_cmd, p_t, r_t, ik_iterations)
        p_cmd, _ = fk(env.chain, q_cmd)
        st = env.step(st, q_cmd, g_t)
        q_meas = st.data.qpos[env.chain.qpos_adr]
        tp, tr = fk(env.chain, q_meas)
        rec = Trace(
            tcp_pos=tp,
            tcp_rot=tr,
            q=q_meas,
            grip=grip_from_fingers(st.data.qpos[env.finger_qpos_adr]),
            grip_cmd=(g_t > 0.5).astype(jnp.float32),
            success=st.success,
            ik_error=jnp.linalg.norm(p_cmd - p_t),
            ctrl=st.data.ctrl,
            attached=st.grasp.attached,
            rel_pos=st.grasp.rel_pos,
            rel_quat=st.grasp.rel_quat,
        )
        return (st, q_cmd), rec

    (state, _), trace = lax.scan(body, (state, q0), (pos, rot, grip))
    return state, trace


def kinematic_tracking(chain, q0: jax.Array, plan: WaypointPlan, durations, ik_iterations: int = IK_ITERATIONS_PER_STEP,
                       stride: int = 1):
    """The expert's IK tracking of a plan without physics: the same interpolated targets and
    warm-started IK as :func:`rollout`, every ``stride``-th control step (with ``stride`` times the
    iterations, so the arm keeps up). Returns (max position error m, max orientation error rad,
    min distance of any joint to its limits rad) over the episode: whether the demonstration's
    waypoints can be reached along its path, RLBench's ``Task.validate`` without a path planner."""
    p0, r0 = fk(chain, q0)
    pos, quat, _ = plan_targets(plan, p0, geo.mat_to_quat(r0), durations)
    pos, quat = pos[stride - 1::stride], quat[stride - 1::stride]
    rot = geo.quat_to_mat(quat)
    lower, upper = jnp.asarray(chain.lower), jnp.asarray(chain.upper)

    def body(q, target):
        p_t, r_t = target
        q = ik.solve_ik(chain, q, p_t, r_t, ik_iterations * stride)
        pe, re = ik.pose_error(chain, q, p_t, r_t)
        margin = jnp.min(jnp.minimum(q - lower, upper - q))
        return q, (pe, re, margin)

    _, (pe, re, margin) = lax.scan(body, q0, (pos, rot))
    return pe.max(), re.max(), margin.min()


def joint_targets(q_way: jax.Array, start_q: jax.Array, durations) -> jax.Array:
    """Joint-space interpolation (smoothstep per segment) through waypoints: (T, 7) targets."""
    seg, frac = segment_schedule(durations)
    q_from = jnp.concatenate([start_q[None], q_way[:-1]])[seg]
    a = smoothstep(jnp.asarray(frac))[:, None]
    return q_from + a * (q_way[seg] - q_from)


def rollout_joints(env, state, q_way: jax.Array, grip: jax.Array, durations):
    """Execute joint-space waypoints (W, 7) with gripper commands (W,); returns (state, Trace)."""
    q0 = state.data.qpos[env.chain.qpos_adr]
    q_t = joint_targets(q_way, q0, durations)
    seg, _ = segment_schedule(durations)
    g_t = grip[seg]

    def body(st, target):
        q_cmd, g = target
        st = env.step(st, q_cmd, g)
        q_meas = st.data.qpos[env.chain.qpos_adr]
        tp, tr = fk(env.chain, q_meas)
        rec = Trace(
            tcp_pos=tp, tcp_rot=tr, q=q_meas,
            grip=grip_from_fingers(st.data.qpos[env.finger_qpos_adr]), grip_cmd=(g > 0.5).astype(jnp.float32),
            success=st.success, ik_error=jnp.zeros(()), ctrl=st.data.ctrl,
            attached=st.grasp.attached, rel_pos=st.grasp.rel_pos, rel_quat=st.grasp.rel_quat,
        )
        return st, rec

    return lax.scan(body, state, (q_t, g_t))
