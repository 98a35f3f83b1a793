"""Where executed plans ended, against the scene's landmarks (``TaskEnv.landmarks``): which object
each plan's end point is nearest, and how far from it.

A failure whose plan ends nearest a distractor went for the wrong object (a retrieval or
recognition error, which a local refinement cannot undo); one that ends nearest the target
missed it by a distance (a precision error: depth or image position). Evaluation records both per
episode, so a table's failures can be counted by kind without re-planning.

The same measure on the *retrieved* motion (where refinement started) splits success by start:
how often a plan that started at the wrong object, or far from the right one, still succeeded.
That separates what retrieval limits from what refinement limits.
"""

from __future__ import annotations

from collections import Counter

import numpy as np


def nearest_landmarks(end: np.ndarray, landmarks: dict[str, np.ndarray]) -> tuple[list[str], np.ndarray]:
    """For end points (B, 3) and landmark groups {name: (B, k, 3)}: the nearest group's name per
    episode and the distance (m) to its nearest point (B,)."""
    end = np.asarray(end, np.float64)
    if end.ndim != 2 or end.shape[1] != 3:
        raise ValueError(f"end points must have shape (B, 3), got {end.shape}")
    if not landmarks:
        raise ValueError("no landmarks: this task defines none (TaskEnv.landmarks)")
    names = list(landmarks)
    dist = []
    for n in names:
        pts = np.asarray(landmarks[n], np.float64)
        if pts.ndim != 3 or pts.shape[0] != end.shape[0] or pts.shape[2] != 3:
            raise ValueError(f"landmark group {n!r} must have shape ({end.shape[0]}, k, 3), got {pts.shape}")
        dist.append(np.linalg.norm(end[:, None] - pts, axis=-1).min(axis=1))
    dist = np.stack(dist, axis=1)
    which = dist.argmin(axis=1)
    return [names[i] for i in which], dist[np.arange(len(end)), which]


def summarise(end: np.ndarray, landmarks: dict[str, np.ndarray], success) -> dict:
    """Per episode: the plan's end point, its nearest landmark group and the distance; and the
    failures counted by nearest group with their median distance."""
    success = np.asarray(success, bool)
    nearest, dist = nearest_landmarks(end, landmarks)
    failed = [(n, d) for n, d, ok in zip(nearest, dist, success) if not ok]
    counts = Counter(n for n, _ in failed)
    return {
        "plan_end_m": np.round(np.asarray(end, np.float64), 4).tolist(),
        "nearest_landmark": nearest,
        "landmark_distance_m": np.round(dist, 4).tolist(),
        "failures_by_nearest": {n: {"count": counts[n],
                                    "median_distance_m": float(np.median([d for m, d in failed if m == n]))}
                                for n in landmarks if counts[n]},
    }


START_BINS_M = (0.03, 0.06, 0.10)  # distance buckets (m) of a start to its nearest landmark


def _bucket_labels(bins=START_BINS_M) -> list[str]:
    """Every bucket's label, nearest first: [0, b1), [b1, b2), ..., [b_last, inf)."""
    edges = (0.0, *bins)
    return [f"{100 * lo:g}-{100 * hi:g} cm" for lo, hi in zip(edges, bins)] + [f">= {100 * bins[-1]:g} cm"]


def by_start(start: np.ndarray, landmarks: dict[str, np.ndarray], success, bins=START_BINS_M) -> dict:
    """Success split by where each plan started (the retrieved motion's end point, (B, 3)): per
    nearest landmark group and distance bucket, ``{group: {bucket: {"episodes", "succeeded"}}}``,
    plus each episode's start group and distance. Buckets with no episode are left out."""
    success = np.asarray(success, bool)
    nearest, dist = nearest_landmarks(start, landmarks)
    labels = _bucket_labels(bins)
    bucket = np.searchsorted(np.asarray(bins), dist, side="right")  # d < b1 -> 0, ..., d >= b_last -> last
    table: dict[str, dict[str, dict[str, int]]] = {}
    for n in landmarks:
        for k, label in enumerate(labels):
            members = success[(np.asarray(nearest) == n) & (bucket == k)]
            if members.size:
                table.setdefault(n, {})[label] = {"episodes": int(members.size), "succeeded": int(members.sum())}
    return {"start_nearest": nearest, "start_distance_m": np.round(dist, 4).tolist(), "success_by_start": table}


def bucket_rank(label: str, bins=START_BINS_M) -> int:
    """A bucket label's place in :func:`_bucket_labels` (nearest first), for sorting."""
    return _bucket_labels(bins).index(label)


# ---------------------------------------------------------------------------------------------
# Failure modes of any task, from the plan, its ground truth and the executed rollout

KEYFRAME_TOL_M = 0.02  # a key frame planned farther than this from the ground truth's is "off"
WRONG_PLACE_M = 0.10  # ... and farther than this, the plan went somewhere else (not a precision error)
KEYFRAME_TOL_DEG = 10.0  # ... or turned more than this away from it
# causes before consequences: a plan whose key frames are off explains the missed grasp or task
# failure that follows
MODES = ("unreachable", "gripper sequence", "wrong place", "depth", "image position", "orientation",
         "missed grasp", "task failure", "near miss")
MODE_HELP = {
    "unreachable": "IK could not reach more than the allowed number of waypoints: the episode aborted",
    "gripper sequence": "the plan closes the gripper a different number of times than the demonstration",
    "wrong place": "a key frame more than 10 cm off: the plan went for another place (a distractor, or "
                   "where the retrieved demonstration's object was), not a matter of precision",
    "depth": "a key frame off by more than the position tolerance, mostly along the camera's ray",
    "image position": "a key frame off by more than the position tolerance, mostly across the image",
    "orientation": "key frames in place, but the approach axis tilted or the turn between two key frames "
                   "off by more than the rotation tolerance (a constant yaw offset does not count)",
    "missed grasp": "key frames in place and the gripper closes as in the demonstration, but it never holds "
                    "an object",
    "task failure": "key frames in place, but the task's own failure condition fired between them "
                    "(e.g. the wire touched, a cap lifted before it was unscrewed)",
    "near miss": "none of the above: the motion between the key frames, or the last centimetres, failed",
}


def closings(grip: np.ndarray) -> np.ndarray:
    """How many times each motion closes the gripper: open (> 0.5) -> closed transitions, (B, T) -> (B,)."""
    closed = np.asarray(grip) <= 0.5
    return np.sum(closed[:, 1:] & ~closed[:, :-1], axis=1) + closed[:, 0]


def keyframes(gt_grip: np.ndarray) -> list[np.ndarray]:
    """Per episode, the ground truth's key frames: the frames where its gripper opens or closes, and
    the last frame (where the motion ends)."""
    closed = np.asarray(gt_grip) <= 0.5
    out = []
    for c in closed:
        change = np.nonzero(c[1:] != c[:-1])[0] + 1
        out.append(np.unique(np.append(change, len(c) - 1)))
    return out


def rotation_angles(r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """Geodesic angle (degrees) between rotation matrices (..., 3, 3)."""
    cos = (np.einsum("...ij,...ij->...", np.asarray(r1, np.float64), np.asarray(r2, np.float64)) - 1) / 2
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def orientation_parts(plan_rot: np.ndarray, gt_rot: np.ndarray, frames: np.ndarray) -> tuple[float, float]:
    """(tilt, turn) in degrees, the two parts of :func:`orientation_error`: the largest tilt of the
    approach axis (the rotation's third column) from the ground truth's at the key frames, and the
    largest error in how far the gripper turns between consecutive key frames (from the first
    frame when there is only one)."""
    pr, gr = np.asarray(plan_rot, np.float64), np.asarray(gt_rot, np.float64)
    tilt = np.degrees(np.arccos(np.clip(np.sum(pr[frames, :, 2] * gr[frames, :, 2], axis=-1), -1.0, 1.0)))
    ends = frames if len(frames) > 1 else np.concatenate([[0], frames])
    turn_p = np.einsum("kji,kjl->kil", pr[ends[:-1]], pr[ends[1:]])
    turn_g = np.einsum("kji,kjl->kil", gr[ends[:-1]], gr[ends[1:]])
    return float(tilt.max()), float(rotation_angles(turn_p, turn_g).max())


def orientation_error(plan_rot: np.ndarray, gt_rot: np.ndarray, frames: np.ndarray) -> float:
    """One plan's orientation error at its key frames (degrees), blind to a constant turn about the
    gripper's approach axis: the larger of :func:`orientation_parts`. A grasp of a symmetric object
    (a square cap, a cylinder) at another yaw is as good as the demonstration's, so the absolute
    rotation error is no measure of a failure; a tilted approach or a short twist is."""
    return max(orientation_parts(plan_rot, gt_rot, frames))


def keyframe_errors(plan_pos: np.ndarray, gt_pos: np.ndarray, gt_grip: np.ndarray, cam_origin: np.ndarray,
                    plan_rot: np.ndarray | None = None, gt_rot: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The worst key frame of each plan against its ground truth (world positions (B, T, 3)): the 3D
    distance there, and its split along the camera's ray to the ground-truth point (depth) and
    across it (image position), in m, (B,) each; the worst frame's index; and, given world
    rotations (B, T, 3, 3), the orientation error (:func:`orientation_error`, degrees)."""
    plan_pos, gt_pos = np.asarray(plan_pos, np.float64), np.asarray(gt_pos, np.float64)
    worst = {k: np.zeros(len(plan_pos)) for k in ("error", "depth", "lateral", "rotation_deg")}
    frame = np.zeros(len(plan_pos), int)
    for b, frames in enumerate(keyframes(gt_grip)):
        if plan_rot is not None:
            worst["rotation_deg"][b] = orientation_error(plan_rot[b], gt_rot[b], frames)
        e = plan_pos[b, frames] - gt_pos[b, frames]
        dist = np.linalg.norm(e, axis=-1)
        k = int(np.argmax(dist))
        ray = gt_pos[b, frames[k]] - np.asarray(cam_origin, np.float64)
        ray /= np.linalg.norm(ray)
        along = float(e[k] @ ray)
        worst["error"][b], worst["depth"][b] = dist[k], abs(along)
        worst["lateral"][b] = np.linalg.norm(e[k] - along * ray)
        frame[b] = frames[k]
    return {**worst, "frame": frame}


def classify(success, aborted, failure, plan_closings, gt_closings, held, errors: dict[str, np.ndarray],
             tol: float = KEYFRAME_TOL_M, tol_deg: float = KEYFRAME_TOL_DEG,
             wrong_place: float = WRONG_PLACE_M) -> list[str | None]:
    """Each episode's failure mode (:data:`MODES`, the first that applies, in that order), None for a
    success. ``held``: (B,) whether the rollout ever held an object, or None for a task without
    graspable objects (then no failure is a missed grasp)."""
    modes = []
    for b, ok in enumerate(np.asarray(success, bool)):
        if ok:
            modes.append(None)
        elif aborted[b]:
            modes.append("unreachable")
        elif plan_closings[b] != gt_closings[b]:
            modes.append("gripper sequence")
        elif errors["error"][b] > wrong_place:
            modes.append("wrong place")
        elif errors["error"][b] > tol:
            modes.append("depth" if errors["depth"][b] > errors["lateral"][b] else "image position")
        elif errors["rotation_deg"][b] > tol_deg:
            modes.append("orientation")
        elif held is not None and gt_closings[b] > 0 and not held[b]:
            modes.append("missed grasp")
        elif failure[b]:
            modes.append("task failure")
        else:
            modes.append("near miss")
    return modes


def median_by_outcome(values, success) -> dict[str, float | None]:
    """The median of per-episode ``values`` over the episodes that succeeded and over those that
    failed (None where there are none), rounded to 2 decimals."""
    v, ok = np.asarray(values, np.float64), np.asarray(success, bool)
    median = lambda mask: float(np.round(np.median(v[mask]), 2)) if mask.any() else None  # noqa: E731
    return {"succeeded": median(ok), "failed": median(~ok)}


def diagnose(plan_motion: np.ndarray, plan_pose: tuple, gt_motion: np.ndarray, gt_pose: tuple,
             cam_origin: np.ndarray, success, aborted, failure, held, start_pos: np.ndarray | None = None,
             tol: float = KEYFRAME_TOL_M, tol_deg: float = KEYFRAME_TOL_DEG) -> dict:
    """What an evaluation records to explain its failures. Per episode: the measurements (the plan's
    and the demonstration's gripper closings, the worst key-frame errors: position in cm, total /
    depth / across the image, rotation in degrees; whether the rollout aborted, held an object, hit
    the task's failure condition) and the failure mode they give (:func:`classify`); with
    ``start_pos`` (world positions (B, T, 3) of the retrieved motions READ refined from) also the
    start's worst key-frame error, which tells a failure retrieval set up from one refinement made.
    Summaries: the failures counted by mode, how many failures started a wrong place away, and the
    median worst key-frame error of the episodes that succeeded and of those that failed.
    ``plan_pose`` / ``gt_pose``: world (positions (B, T, 3), rotations (B, T, 3, 3))."""
    success, aborted, failure = (np.asarray(x, bool) for x in (success, aborted, failure))
    held = None if held is None else np.asarray(held, bool)
    plan_c, gt_c = closings(plan_motion[..., 9]), closings(gt_motion[..., 9])
    err = keyframe_errors(plan_pose[0], gt_pose[0], gt_motion[..., 9], cam_origin, plan_pose[1], gt_pose[1])
    modes = classify(success, aborted, failure, plan_c, gt_c, held, err, tol, tol_deg)
    counts = Counter(m for m in modes if m is not None)
    cm = lambda x: np.round(100 * np.asarray(x), 2).tolist()  # noqa: E731
    out = {
        "tolerance_cm": 100 * tol, "tolerance_deg": tol_deg, "wrong_place_cm": 100 * WRONG_PLACE_M,
        "mode": modes,
        "plan_closings": plan_c.astype(int).tolist(), "gt_closings": gt_c.astype(int).tolist(),
        "keyframe_error_cm": cm(err["error"]), "keyframe_depth_cm": cm(err["depth"]),
        "keyframe_lateral_cm": cm(err["lateral"]), "keyframe_frame": err["frame"].astype(int).tolist(),
        "keyframe_rotation_deg": np.round(err["rotation_deg"], 1).tolist(),
        "aborted": aborted.astype(int).tolist(), "task_failure": failure.astype(int).tolist(),
        "held": None if held is None else held.astype(int).tolist(),
        "counts": {m: counts[m] for m in MODES if counts[m]},
        "median_keyframe_error_cm": median_by_outcome(100 * err["error"], success),
    }
    if start_pos is not None:
        start = keyframe_errors(start_pos, gt_pose[0], gt_motion[..., 9], cam_origin)["error"]
        out["start_keyframe_error_cm"] = cm(start)
        out["failed_from_a_wrong_start"] = int(np.sum(~success & (start > WRONG_PLACE_M)))
    return out
