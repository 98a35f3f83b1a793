"""Plan execution helpers: the pace of a plan's frames and IK through its waypoints."""

from __future__ import annotations

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax import motion as motion_lib
from readjax.sim import execute, ik
from readjax.sim.kinematics import HOME_Q, fk

CFG = execute.ExecConfig()
W = 8  # waypoints per test path (one shape, so one compile per function)


@pytest.fixture(scope="module")
def env():
    return tasks.make("reach_target")  # the cheapest task; solve_waypoints reads env.chain


@pytest.fixture(scope="module")
def solve(env):
    return jax.jit(lambda p, r: execute.solve_waypoints(env, p, r, CFG))


def known_path(env, shift: float) -> np.ndarray:
    """W joint configurations moving smoothly away from home (inside the joint limits)."""
    delta = np.array([0.3, 0.2, -0.25, 0.3, 0.2, -0.3, 0.25], np.float32) * shift
    q = HOME_Q[None] + np.linspace(0.0, 1.0, W, dtype=np.float32)[:, None] * delta[None]
    return np.clip(q, env.chain.lower + 0.05, env.chain.upper - 0.05).astype(np.float32)


@pytest.mark.parametrize("episode_steps", [1, 30, 150, 1000, 1049])
def test_segment_durations_pace_the_101_frames_like_the_expert(episode_steps):
    d = execute.segment_durations(SimpleNamespace(episode_steps=episode_steps))
    assert len(d) == motion_lib.FRAMES
    assert len(set(d)) == 1 and d[0] >= 1 and all(isinstance(x, int) for x in d)
    assert d[0] == max(1, round(episode_steps / 100))
    if episode_steps >= 100:  # 100 gaps at that pace span the expert's episode to within half a gap each
        assert abs(d[0] * 100 - episode_steps) <= 50


def test_segment_durations_of_a_task(env):
    d = execute.segment_durations(env)
    assert len(d) == motion_lib.FRAMES and sum(d) == d[0] * motion_lib.FRAMES
    assert d[0] == max(1, int(round(env.episode_steps / 100)))


def test_poses_of_known_configurations_are_reached_without_skips(env, solve):
    q_true = known_path(env, 1.0)
    pos, rot = fk(env.chain, q_true)
    q, skipped = solve(pos, rot)
    assert q.shape == (W, 7) and skipped.shape == (W,)
    assert not np.any(np.asarray(skipped))
    pe, re = jax.vmap(lambda qq, p, r: ik.pose_error(env.chain, qq, p, r))(q, pos, rot)
    assert np.all(np.asarray(pe) < CFG.reach_pos_tol) and np.all(np.asarray(re) < CFG.reach_rot_tol)
    assert np.all(np.asarray(q) >= env.chain.lower) and np.all(np.asarray(q) <= env.chain.upper)


def test_an_unreachable_pose_is_skipped_and_the_previous_q_held(env, solve):
    q_true = known_path(env, 1.0)
    pos, rot = fk(env.chain, q_true)
    far = 4
    pos = np.asarray(pos).copy()
    pos[far] = pos[far] + np.array([3.0, 0.0, 0.0], np.float32)  # 3 m away: out of the arm's reach
    q, skipped = solve(jnp.asarray(pos), rot)
    skipped, q = np.asarray(skipped), np.asarray(q)
    assert skipped[far] and not np.any(skipped[:far])
    np.testing.assert_array_equal(q[far], q[far - 1])


def test_an_unreachable_first_pose_holds_home(env, solve):
    pos, rot = fk(env.chain, known_path(env, 1.0))
    pos = np.asarray(pos).copy()
    pos[0] = pos[0] + np.array([0.0, 3.0, 0.0], np.float32)
    q, skipped = solve(jnp.asarray(pos), rot)
    assert np.asarray(skipped)[0]
    np.testing.assert_array_equal(np.asarray(q)[0], HOME_Q)


def test_batched_equals_unbatched(env, solve):
    paths = [known_path(env, 1.0), known_path(env, -0.8)]
    poses = [fk(env.chain, p) for p in paths]
    pos = jnp.stack([p for p, _ in poses])
    rot = jnp.stack([r for _, r in poses])
    pos = pos.at[1, 3].add(jnp.array([0.0, 0.0, 3.0]))  # one skip in the batch too
    qb, sb = jax.jit(jax.vmap(lambda p, r: execute.solve_waypoints(env, p, r, CFG)))(pos, rot)
    for i in range(2):
        q, s = solve(pos[i], rot[i])
        np.testing.assert_array_equal(np.asarray(sb[i]), np.asarray(s))
        np.testing.assert_allclose(np.asarray(qb[i]), np.asarray(q), atol=1e-5)
    assert np.asarray(sb)[1, 3]


def test_the_posture_is_pulled_home_at_the_experts_rate_not_at_once(env):
    """A pose held for W waypoints: pulled to convergence at every waypoint (the old rule), the posture
    jumps to its home-nearest branch at the first waypoint and stays; at the expert's rate (its IK
    iterations per control step times the steps per frame) it drifts there over several waypoints,
    as the expert's tracking did, each waypoint on the pose."""
    q_a = np.asarray(known_path(env, 1.5))[-1]
    pos, rot = fk(env.chain, jnp.asarray(np.repeat(q_a[None], W, 0)))
    pulls = execute.IK_ITERATIONS_PER_STEP * execute.segment_durations(env)[0]
    assert 0 < pulls < CFG.ik_iterations
    steps = {}
    for rate in (True, False):
        cfg = execute.ExecConfig(expert_rate_posture=rate)
        q, skipped = jax.jit(lambda p, r: execute.solve_waypoints(env, p, r, cfg))(pos, rot)
        assert not np.any(np.asarray(skipped))
        steps[rate] = np.abs(np.diff(np.asarray(q), axis=0)).max(axis=1)  # posture change per waypoint
    assert steps[False][1:].max() < 1e-3  # converged at once
    assert steps[True][1:].max() > 10 * steps[False][1:].max()  # still drifting, waypoint by waypoint
