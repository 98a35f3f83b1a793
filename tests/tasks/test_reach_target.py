"""RT: success-predicate truth table and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import ik
from readjax.tasks import sampling
from readjax.tasks.common import down_quat
from readjax import geometry as geo
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("reach_target")


def _tip_at(env, scene, point):
    q = ik.solve_ik(env.chain, jnp.asarray(scene.qpos[:7]), jnp.asarray(point), geo.quat_to_mat(down_quat(0.0)), 200)
    qpos = np.array(scene.qpos)
    qpos[env.chain.qpos_adr] = np.asarray(q)
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


@pytest.mark.parametrize(
    "where, expected",
    [("target", True), ("target+2cm", True), ("target+4cm", False), ("distractor", False), ("home", False)],
)
def test_truth_table(env, where, expected):
    scene = env.sample_scene(jax.random.key(7))
    target = np.asarray(scene.mocap_pos[env.target_mocap])
    point = {
        "target": target,
        "target+2cm": target + [0, 0, 0.02],
        "target+4cm": target + [0, 0, 0.04],
        "distractor": np.asarray(scene.mocap_pos[env.distractor_mocap[0]]),
    }.get(where)
    data = _tip_at(env, scene, point) if point is not None else hand_built(env, np.asarray(scene.qpos),
                                                                            scene.mocap_pos, scene.mocap_quat)
    ok, fail, _ = judge(env, scene, data, grasping(env, None))
    assert (ok, fail) == (expected, False)


def test_distractors_are_far_and_not_red(env):
    for seed in range(20):
        s = env.sample_scene(jax.random.key(seed))
        pts = np.asarray(s.mocap_pos)
        d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(3)
        assert d.min() >= 0.2
        rgb = np.asarray(s.rgba)[:, :3]
        assert np.all(np.linalg.norm(rgb - np.asarray(sampling.RED), axis=1) > 0.3)  # never red
        assert not np.allclose(rgb[0], rgb[1])  # two different colours


def test_spheres_in_boundary_not_turned_and_feasible(env):
    """Static workspace: centres inside the boundary, no rotation, every early seed placeable."""
    from readjax.tasks.reach_target import HIGH, LOW
    for seed in range(12):
        s = env.sample_scene(jax.random.key(seed))
        pts = np.asarray(s.mocap_pos)
        assert np.all(pts >= np.asarray(LOW) - 1e-6) and np.all(pts <= np.asarray(HIGH) + 1e-6)
        np.testing.assert_allclose(np.asarray(s.mocap_quat), np.tile([1.0, 0, 0, 0], (3, 1)), atol=1e-6)
        assert bool(s.params["feasible"])


def test_scene_ok_is_the_min_distance(env):
    scene = env.draw_scene(jax.random.key(0, impl="threefry2x32"))
    mocap = np.asarray(scene.mocap_pos).copy()
    mocap[env.distractor_mocap[0]] = mocap[env.target_mocap] + [0.0, 0.19, 0.0]
    mocap[env.distractor_mocap[1]] = mocap[env.target_mocap] + [0.0, -0.25, 0.0]
    assert not bool(env.scene_ok(scene.replace(mocap_pos=jnp.asarray(mocap))))
    mocap[env.distractor_mocap[0]] = mocap[env.target_mocap] + [0.0, 0.21, 0.0]
    assert bool(env.scene_ok(scene.replace(mocap_pos=jnp.asarray(mocap))))


def test_spawn_points_sequential_min_distance():
    """RLBench's sequential sampling: each point >= min_dist from those before (when one was found)."""
    from readjax.tasks.reach_target import spawn_points
    for seed in range(50):
        pts = np.asarray(spawn_points(jax.random.key(seed, impl="threefry2x32"), 3, (0, 0, 0), (0.4, 0.6, 0.33), 0.2))
        d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(3)
        assert d.min() >= 0.2


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("reach_target")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.ik_error < 0.01)
