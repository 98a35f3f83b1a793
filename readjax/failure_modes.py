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
