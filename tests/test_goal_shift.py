"""Moving a task's goal object, and the goal-shift diagnostic's arithmetic (the planner end to end:
tests/test_pipeline.py)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.lab import goal_shift


@pytest.mark.parametrize("task", ["reach_target", "push_button"])
def test_moving_the_goal_moves_it_and_nothing_else(task):
    env = tasks.make(task)
    scenes = jax.vmap(env.sample_scene)(jax.random.split(jax.random.key(3), 4))
    delta = goal_shift.horizontal_shifts(4, 0.05, seed=1)
    moved = env.move_goal(scenes, delta)
    np.testing.assert_allclose(np.asarray(env.goal(moved)) - np.asarray(env.goal(scenes)), delta, atol=1e-6)
    changed = [np.flatnonzero(np.any(np.abs(np.asarray(b) - np.asarray(a)).reshape(4, -1) > 0, axis=0))
               for a, b in ((scenes.qpos, moved.qpos), (scenes.mocap_pos, moved.mocap_pos))]
    assert sum(len(c) for c in changed) in (2, 3)  # the goal's x and y (z is not moved)
    assert np.array_equal(np.asarray(scenes.rgba), np.asarray(moved.rgba))
    # one scene, one move: the same as in the batch
    one = env.move_goal(jax.tree.map(lambda x: x[0], scenes), delta[0])
    np.testing.assert_allclose(np.asarray(env.goal(one)), np.asarray(env.goal(moved))[0], atol=1e-6)


def test_a_task_without_one_goal_object_says_so():
    env = tasks.make("close_box")
    assert env.goal(env.default_scene()) is None
    with pytest.raises(ValueError, match="no single goal object"):
        env.move_goal(env.default_scene(), np.zeros(3))


def test_sensitivity_is_the_ends_move_along_the_goals_in_units_of_it():
    shifts = goal_shift.horizontal_shifts(5, 0.04, seed=0)
    np.testing.assert_allclose(np.linalg.norm(shifts, axis=1), 0.04, rtol=1e-6)
    assert np.all(shifts[:, 2] == 0)
    ends = np.random.default_rng(0).normal(size=(5, 3))
    across = np.stack([-shifts[:, 1], shifts[:, 0], np.full(5, 0.01)], axis=1)  # orthogonal to each move
    s = goal_shift.sensitivity(ends, ends + np.array([[1.0], [0.5], [0.0], [-1.0], [1.0]]) * shifts + across, shifts)
    np.testing.assert_allclose(s, [1.0, 0.5, 0.0, -1.0, 1.0], atol=1e-6)


def test_bins_hold_their_values_and_leave_empty_ones_out():
    x = np.array([0.5, 1.5, 5.0, 30.0])
    v = np.array([1.0, 0.0, 0.2, 0.9])
    rows = goal_shift.binned(x, v, (0, 2, 4, 8, 1000))
    assert [(r["lo"], r["n"]) for r in rows] == [(0, 2), (4, 1), (8, 1)]
    assert rows[0]["median"] == 0.5 and rows[0]["follows"] == 0.5
    assert rows[2]["follows"] == 1.0


def test_pixel_uv_matches_the_feature_samplers_convention():
    uv = goal_shift.pixel_uv(4)
    assert uv.shape == (4, 4, 2)
    np.testing.assert_allclose(uv[0, 0], [-0.75, -0.75])
    np.testing.assert_allclose(uv[1, 3], [0.75, -0.25])  # (u: column 3, v: row 1)
