"""Failure modes: each plan's end point against the scene's landmarks."""

import jax
import numpy as np
import pytest

from readjax import failure_modes, tasks
from readjax.evaluation import scene_landmarks


def test_nearest_landmark_and_failure_counts():
    marks = {"target": np.array([[[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]]]),
             "distractor": np.array([[[0.3, 0, 0], [0, 0.5, 0]], [[1.0, 0.2, 0]] * 2, [[0, 0, 0.4], [0, 0, -0.4]]])}
    end = np.array([[0.25, 0.0, 0.0], [1.0, 0.05, 0.0], [0.0, 0.0, 0.1]])
    nearest, dist = failure_modes.nearest_landmarks(end, marks)
    assert nearest == ["distractor", "target", "target"]
    np.testing.assert_allclose(dist, [0.05, 0.05, 0.1])
    s = failure_modes.summarise(end, marks, [False, True, False])
    assert s["failures_by_nearest"] == {"target": {"count": 1, "median_distance_m": pytest.approx(0.1)},
                                        "distractor": {"count": 1, "median_distance_m": pytest.approx(0.05)}}
    assert s["nearest_landmark"] == nearest and len(s["plan_end_m"]) == 3
    with pytest.raises(ValueError, match="no landmarks"):
        failure_modes.nearest_landmarks(end, {})
    with pytest.raises(ValueError, match="shape"):
        failure_modes.nearest_landmarks(end, {"target": marks["target"][:2]})


def test_success_split_by_where_refinement_started():
    marks = {"target": np.zeros((5, 1, 3)), "distractor": np.tile([[[1.0, 0.0, 0.0]]], (5, 1, 1))}
    start = np.array([[0, 0, 0.01], [0, 0, 0.02], [0, 0, 0.07], [0, 0, 0.3], [0.98, 0, 0]])
    s = failure_modes.by_start(start, marks, [True, False, True, False, False])
    assert s["start_nearest"] == ["target"] * 4 + ["distractor"]
    assert s["success_by_start"] == {
        "target": {"0-3 cm": {"episodes": 2, "succeeded": 1}, "6-10 cm": {"episodes": 1, "succeeded": 1},
                   ">= 10 cm": {"episodes": 1, "succeeded": 0}},
        "distractor": {"0-3 cm": {"episodes": 1, "succeeded": 0}}}
    assert list(s["success_by_start"]["target"]) == ["0-3 cm", "6-10 cm", ">= 10 cm"]  # nearest first
    assert [failure_modes.bucket_rank(b) for b in ("0-3 cm", "3-6 cm", "6-10 cm", ">= 10 cm")] == [0, 1, 2, 3]


def test_reach_target_landmarks_are_the_spheres():
    """RT's target landmark is the sphere its predicate measures against, the distractors the other two."""
    env = tasks.make("reach_target")
    scenes = jax.vmap(env.sample_scene)(jax.random.split(jax.random.key(0), 3))
    marks = scene_landmarks(env, scenes)
    assert set(marks) == {"target", "distractor"}
    assert marks["target"].shape == (3, 1, 3) and marks["distractor"].shape == (3, 2, 3)
    np.testing.assert_allclose(marks["target"][:, 0], np.asarray(scenes.params["target"]))
    assert np.all(np.linalg.norm(marks["distractor"] - marks["target"], axis=-1) >= 0.2 - 1e-6)
    assert scene_landmarks(tasks.make("push_button"), jax.vmap(tasks.make("push_button").sample_scene)(
        jax.random.split(jax.random.key(0), 2))) == {}
