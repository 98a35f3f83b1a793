"""Why a task's oracle row lies where it does: the task's tolerance against how far the copies are.

A copied demonstration succeeds when its key frames (where the gripper opens or closes, and the end)
land within what the task tolerates. Both halves are measured from a difficulty record
(:mod:`readjax.lab.difficulty`), with no extra simulation:

- **how far the copies are**: the worst key-frame error of the i = 1 neighbour against each test
  episode's ground truth (median, cm): the spread of the placement against the density of 1000
  demonstrations;
- **what the task tolerates**: success against that error, pooled over the executed ranks
  (i = 1, 3, 10: 300 copies at errors from millimetres to decimetres), in bins;
- **how the copies failed**: i = 1 failures by mode (:mod:`readjax.failure_modes`).

A task far easier than the paper's row has copies well inside its tolerance; a task far harder has
copies outside it, or fails on a term the error does not capture (a task failure such as a touched
wire). Which of placement spread or tolerance differs from RLBench's is then the question the
task's audit (docs/tasks.md) answers.
"""

from __future__ import annotations

import numpy as np

from readjax import tasks
from readjax.lab import paper

BINS_CM = (0.0, 1.0, 2.0, 4.0, 8.0, np.inf)


def _bin_labels(bins=BINS_CM) -> list[str]:
    labels = [f"{lo:g}-{hi:g} cm" for lo, hi in zip(bins[:-1], bins[1:]) if np.isfinite(hi)]
    return labels + [f"≥ {bins[-2]:g} cm"]


def tolerance_profile(record: dict, bins=BINS_CM) -> list[tuple[int, int]]:
    """(successes, copies) per key-frame-error bin, pooled over the record's ranks."""
    err, ok = [], []
    for r in record["ranks"].values():
        f = r.get("failures")
        if f is None:
            continue
        err += f["keyframe_error_cm"]
        ok += r["success"]
    err, ok = np.asarray(err, float), np.asarray(ok, bool)
    which = np.digitize(err, bins[1:-1])
    return [(int(ok[which == b].sum()), int((which == b).sum())) for b in range(len(bins) - 1)]


def summary(record: dict) -> dict | None:
    """The measured reason of one task: median i = 1 key-frame error (cm), the tolerance profile and
    the i = 1 failures by mode; None for a record measured before failures were recorded."""
    first = record["ranks"].get("1")
    if first is None or "failures" not in first:
        return None
    f = first["failures"]
    return {"median_error_cm": float(np.median(f["keyframe_error_cm"])),
            "median_rotation_deg": float(np.median(f["keyframe_rotation_deg"])),
            "profile": tolerance_profile(record), "modes": f["counts"]}


def _cell(successes: int, n: int) -> str:
    return "–" if n == 0 else f"{100 * successes / n:.0f} % ({n})"


def table(records: dict[str, dict]) -> str:
    """Markdown: per task, i = 1 ours - paper, where the copies land and what the task tolerates."""
    labels = _bin_labels()
    lines = ["| task | i = 1: ours - paper | copies' worst key-frame error, median (i = 1) | "
             + " | ".join(f"success at {lb}" for lb in labels) + " | i = 1 failures by mode |",
             "|" + "---|" * (4 + len(labels))]
    for code in tasks.AVG16:
        r = next((v for v in records.values() if v["code"] == code), None)
        s = summary(r) if r else None
        if s is None:
            continue
        diff = 100 * r["ranks"]["1"]["success_rate"] - paper.CHEAT[1][code]
        modes = ", ".join(f"{m} {n}" for m, n in sorted(s["modes"].items(), key=lambda kv: -kv[1])) or "none"
        lines.append(f"| {code} | {diff:+.0f} | {s['median_error_cm']:.1f} cm, {s['median_rotation_deg']:.0f}° | "
                     + " | ".join(_cell(*c) for c in s["profile"]) + f" | {modes} |")
    return "\n".join(lines)
