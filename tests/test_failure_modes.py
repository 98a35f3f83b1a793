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


def _grip(*closed_spans, frames=11):
    """A gripper channel (frames,) open (1) except on the given [start, stop) spans (0)."""
    g = np.ones(frames)
    for a, b in closed_spans:
        g[a:b] = 0.0
    return g


def test_closings_and_key_frames():
    grips = np.stack([_grip(), _grip((3, 6)), _grip((2, 4), (7, 11)), _grip((0, 11))])
    assert failure_modes.closings(grips).tolist() == [0, 1, 2, 1]  # a motion that starts closed counts once
    frames = failure_modes.keyframes(grips)
    assert [f.tolist() for f in frames] == [[10], [3, 6, 10], [2, 4, 7, 10], [10]]


def test_key_frame_error_splits_depth_from_image_position():
    """The camera at the origin looks along +x: an error along x is depth, one along y crosses the image."""
    t = 11
    gt = np.zeros((2, t, 3))
    gt[:, :, 0] = 1.0  # the ground truth 1 m in front of the camera
    plan = gt.copy()
    plan[0, -1, 0] += 0.05  # episode 0 ends 5 cm too deep
    plan[1, 5, 1] += 0.03  # episode 1 is 3 cm sideways at its key frame 5 (where the gripper closes)
    plan[1, 2, 1] += 0.5  # ... and far off at frame 2, which is no key frame
    grips = np.stack([_grip(), _grip((5, 11))])
    err = failure_modes.keyframe_errors(plan, gt, grips, np.zeros(3))
    np.testing.assert_allclose(err["error"], [0.05, 0.03], atol=1e-9)
    np.testing.assert_allclose(err["depth"], [0.05, 0.0], atol=1e-9)
    np.testing.assert_allclose(err["lateral"], [0.0, 0.03], atol=1e-9)
    assert err["frame"].tolist() == [10, 5]


def test_failure_modes_truth_table():
    """The first mode that applies names a failure, in the order of MODES (causes before the missed
    grasp or task failure they lead to); a success has none."""
    n = 10
    success = np.array([1, 0, 0, 0, 0, 0, 0, 0, 0, 0], bool)
    aborted = np.array([0, 1, 0, 0, 0, 0, 0, 0, 0, 0], bool)
    failure = np.array([0, 1, 1, 1, 1, 1, 1, 0, 1, 0], bool)  # a failure condition behind most causes
    plan_c = np.array([1, 2, 2, 1, 1, 1, 1, 1, 1, 1])
    gt_c = np.ones(n, int)
    held = np.array([1, 0, 0, 0, 0, 0, 0, 0, 1, 1], bool)  # nothing held behind every cause but the last two
    errors = {"error": np.array([0.3, 0.3, 0.3, 0.3, 0.05, 0.05, 0.01, 0.01, 0.01, 0.01]),
              "depth": np.array([0, 0, 0, 0, 0.04, 0.01, 0, 0, 0, 0]),
              "lateral": np.array([0, 0, 0, 0.3, 0.01, 0.04, 0.01, 0.01, 0.01, 0.01]),
              "rotation_deg": np.array([90, 90, 90, 90, 90, 90, 30, 5, 5, 5.0])}
    modes = failure_modes.classify(success, aborted, failure, plan_c, gt_c, held, errors)
    assert modes == [None, "unreachable", "gripper sequence", "wrong place", "depth", "image position",
                     "orientation", "missed grasp", "task failure", "near miss"]
    # a task without graspable objects has no missed grasps
    assert failure_modes.classify(success, aborted, failure, plan_c, gt_c, None, errors)[7] == "near miss"


def _rz(deg):
    c, s_ = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1.0]])


def test_orientation_error_ignores_a_constant_yaw_but_not_a_short_twist():
    """Key frames 5 (grasp) and 10 (end). The demonstration twists 160 degrees about the approach
    axis between them."""
    t, frames = 11, np.array([5, 10])
    gt = np.stack([np.eye(3)] * 5 + [_rz(0)] * 5 + [_rz(160)])
    assert failure_modes.orientation_error(gt, gt, frames) == pytest.approx(0.0, abs=1e-6)
    yawed = np.einsum("tij,jk->tik", gt, _rz(90))  # the same motion grasping a square cap 90 degrees on
    assert failure_modes.orientation_error(yawed, gt, frames) == pytest.approx(0.0, abs=1e-4)
    short = gt.copy()
    short[10] = _rz(140)  # twists 20 degrees too little
    assert failure_modes.orientation_error(short, gt, frames) == pytest.approx(20.0, abs=1e-4)
    assert failure_modes.orientation_parts(short, gt, frames) == pytest.approx((0.0, 20.0), abs=1e-4)
    tilted = gt.copy()
    c, s_ = np.cos(np.radians(15)), np.sin(np.radians(15))
    tilted[5] = np.array([[1, 0, 0], [0, c, -s_], [0, s_, c]])  # the approach axis tilted 15 degrees
    assert failure_modes.orientation_error(tilted, gt, frames) == pytest.approx(15.0, abs=1e-4)
    tilt, turn = failure_modes.orientation_parts(tilted, gt, frames)  # a tilt at the grasp alone also turns
    assert tilt == pytest.approx(15.0, abs=1e-4) and 0 < turn <= 15.0 + 1e-4  # the hand between the key frames
    np.testing.assert_allclose(failure_modes.rotation_angles(_rz(180), np.eye(3)), 180.0)
    err = failure_modes.keyframe_errors(np.zeros((1, t, 3)) + [1, 0, 0], np.zeros((1, t, 3)) + [1, 0, 0],
                                        _grip((5, 10))[None], np.zeros(3), short[None], gt[None])
    np.testing.assert_allclose(err["rotation_deg"], [20.0], atol=1e-4)


def test_diagnose_counts_failures_by_mode():
    t = 11
    gt_pos = np.zeros((3, t, 3))
    gt_pos[:, :, 0] = 1.0
    plan_pos = gt_pos.copy()
    plan_pos[2, -1, 0] += 0.15  # a failure 15 cm too deep
    motion = np.ones((3, t, 10))
    rot = np.broadcast_to(np.eye(3), (3, t, 3, 3))
    start = gt_pos.copy()
    start[1:, -1, 1] += 0.2  # refinement started 20 cm off on episodes 1 and 2
    out = failure_modes.diagnose(motion, (plan_pos, rot), motion, (gt_pos, rot), np.zeros(3), success=[1, 1, 0],
                                 aborted=[0, 0, 0], failure=[0, 0, 1], held=None, start_pos=start)
    assert out["mode"] == [None, None, "wrong place"] and out["counts"] == {"wrong place": 1}
    assert out["start_keyframe_error_cm"] == [0.0, 20.0, 20.0] and out["failed_from_a_wrong_start"] == 1
    assert out["task_failure"] == [0, 0, 1] and out["held"] is None and out["aborted"] == [0, 0, 0]
    assert out["keyframe_error_cm"] == [0.0, 0.0, 15.0] and out["keyframe_depth_cm"][2] == 15.0
    assert out["median_keyframe_error_cm"] == {"succeeded": 0.0, "failed": 15.0}
    assert out["keyframe_rotation_deg"] == [0.0, 0.0, 0.0] and out["tolerance_deg"] == 10.0
    assert set(failure_modes.MODE_HELP) == set(failure_modes.MODES)
