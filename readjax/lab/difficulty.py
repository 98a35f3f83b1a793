"""How hard a task is, with no trained model: the paper's oracle rows (supplement Table 5, "Cheat").

For every test episode, the i-th nearest training demonstration to its ground-truth motion (the
oracle distance of :func:`readjax.retrieval.oracle_ranking`) is executed in the episode's stored scene
through the evaluation path (scene guard, decode -> IK -> MJX -> predicate), without refinement. If
copying the nearest of 1000 demonstrations already solves a task, no planner can be told apart from
another on it; the paper's own Cheat (i = 1) row is the difficulty the suite should have.

One record per test split version: ``results/<task>/difficulty/<test fingerprint>.json``. A record
is measured only on a split whose ground truth replays at 100 % (``experiments.verify``), and only
with a training split of the same suite version and camera.
"""

from __future__ import annotations

import json
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from readjax import atomic_write, failure_modes, provenance, retrieval, tasks
from readjax import motion as motion_lib
from readjax.data import store
from readjax.data.guard import check_scene_images
from readjax.lab import main_table, paper, verification
from readjax.sim.execute import execute_motions, execution_record

FOLDER = "difficulty"
RANKS = (1, 3, 10)
TOLERANCE = 15.0  # points: the suite is as hard as the paper's where |ours - paper| <= this at i = 1


def record_path(results, task: str, fingerprint: str) -> Path:
    return Path(results) / task / FOLDER / f"{fingerprint}.json"


def check_compatible(train: store.Dataset, test: store.Dataset) -> None:
    """Refuse a pair of splits whose motions do not live in the same frame or benchmark."""
    if train.task != test.task:
        raise store.DatasetError(f"the training split is {train.task}, the test split {test.task}")
    if tasks.suite_of(train.meta) != tasks.suite_of(test.meta):
        raise store.DatasetError(f"{train.task}: the training split is suite {tasks.suite_of(train.meta)}, "
                                 f"the test split suite {tasks.suite_of(test.meta)}")
    if not np.allclose(train.camera.cam_to_world, test.camera.cam_to_world, atol=1e-6):
        raise store.DatasetError(f"{train.task}: the two splits were recorded with different cameras")


def measure(task: str, data_root, results, ranks=RANKS, episodes: int = 100, train_episodes: int | None = None,
            batch_size: int = 50, require_replay: bool = True) -> dict:
    """Execute the oracle's i-th neighbour for every test episode; write and return the record."""
    task = tasks.canonical_name(task)
    env = tasks.make(task)
    train = store.load_dataset(store.split_dir(data_root, task, "train"), limit=train_episodes)
    test_all = store.load_dataset(store.split_dir(data_root, task, "test"))
    if episodes > len(test_all):
        raise ValueError(f"{task}: the test split holds {len(test_all)} episodes, fewer than {episodes}")
    check_compatible(train, test_all)
    if require_replay and not verification.is_verified(results, task, test_all.fingerprint, episodes):
        raise store.DatasetError(
            f"{task}: the test split {test_all.fingerprint} has no 100 % ground-truth replay of {episodes} "
            f"episodes under {results}; run python -m experiments.verify --task {task} --data {data_root} "
            f"--results {results} first")
    test = test_all.subset(np.arange(episodes))
    t0 = time.time()
    check_scene_images(env, test)
    order = retrieval.oracle_ranking(test.camera, test.motion, train.motion)
    gt_pose = motion_lib.world_poses(test.camera, test.motion)
    cam_origin = np.asarray(test.camera.cam_to_world)[:3, 3]
    by_rank = {}
    for i in ranks:
        idx = order[:, min(i, order.shape[1]) - 1]
        res = execute_motions(env, test.camera, test.scenes, train.motion[idx], batch_size=batch_size)
        pose = motion_lib.world_poses(test.camera, train.motion[idx])
        success = res["success"].astype(bool)
        by_rank[str(i)] = {
            "success_rate": float(success.mean()), "success": success.astype(int).tolist(),
            "neighbour_seeds": train.seeds[idx].tolist(),
            "position_error_m": float(np.mean(np.linalg.norm(pose[0] - gt_pose[0], axis=-1))),
            "aborted": int(np.sum(res["aborted"])), "failure": int(np.sum(res["failure"])),
            # why the copies that failed failed: worst key-frame errors against the ground truth, modes
            "failures": failure_modes.diagnose(
                train.motion[idx], pose, test.motion, gt_pose, cam_origin, res["success"], res["aborted"],
                res["failure"], res["held"] if env.graspable else None),
        }
    code = tasks.code_of(task)
    record = {
        "task": task, "code": code, "suite": tasks.suite_of(test.meta), "episodes": episodes,
        "seeds": test.seeds.tolist(), "test_fingerprint": test_all.fingerprint,
        "train_fingerprint": train.fingerprint, "train_episodes": len(train),
        "ranks": by_rank, "paper_cheat": {str(i): paper.CHEAT[i][code] for i in ranks if i in paper.CHEAT},
        "replay_verified": verification.is_verified(results, task, test_all.fingerprint, episodes),
        # how the splits were generated: seeds tried, kept, without a valid placement, expert success
        "generation": {split: _generation_summary(store.split_dir(data_root, task, split))
                       for split in ("train", "test")},
        "execution": execution_record(),  # how plans were executed (IK, skipped waypoints)
        "created": datetime.now(UTC).isoformat(timespec="seconds"),  # which record of a task is newest
        "seconds": round(time.time() - t0, 2), "versions": provenance.versions(),
        "machine": provenance.machine(), "commit": provenance.commit(),
    }
    path = record_path(results, task, test_all.fingerprint)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write.write_text(path, json.dumps(record, indent=2))
    return record


def _generation_summary(split_dir: Path) -> dict | None:
    keys = ("episodes_kept", "episodes_attempted", "episodes_failed", "episodes_infeasible",
            "expert_success_rate", "expert_success_rate_feasible", "seconds")
    try:
        summary = json.loads((Path(split_dir) / "summary.json").read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None
    return {k: summary[k] for k in keys if k in summary}


def load_records(results, suite: int = tasks.SUITE_VERSION) -> dict[str, dict]:
    """The newest difficulty record of every task whose split is of ``suite``: by its ``created`` time
    (a record without one is older than any with one), then by file name. Not by file time, which a fresh
    clone sets to the checkout's, so a task measured again (its split regenerated) would be shown at random."""
    found = []
    for f in sorted(Path(results).glob(f"*/{FOLDER}/*.json")):
        try:
            r = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if tasks.suite_of(r) == suite and r.get("task") in tasks.names():
            found.append((r.get("created", ""), f.name, r))
    return {r["task"]: r for _, _, r in sorted(found, key=lambda x: x[:2])}


def _paper(i: int, code: str) -> str:
    return str(paper.CHEAT[i][code]) if i in paper.CHEAT else "–"


def oracle_rates(records: dict[str, dict], i: int = 1) -> dict[str, float]:
    """Task code -> the oracle's success % copying the i-th nearest training demonstration, with Avg12 /
    Avg16 where every member task has a record."""
    return main_table.with_averages({r["code"]: 100.0 * r["ranks"][str(i)]["success_rate"] for r in records.values()
                                     if str(i) in r.get("ranks", {})}, [])


def comparability_line(records: dict[str, dict]) -> str:
    """One sentence on how far the suite's difficulty is from the paper's benchmark, by the oracle's
    i = 1 row (Table 5's Cheat (1)): its Avg12 / Avg16 beside the paper's, and the tasks more than
    :data:`TOLERANCE` points easier or harder."""
    ours = oracle_rates(records, 1)
    if "Avg16" not in ours:
        return ""
    diff = {c: ours[c] - paper.CHEAT[1][c] for c in tasks.AVG16}
    easier = [f"{c} {d:+.0f}" for c, d in diff.items() if d > TOLERANCE]
    harder = [f"{c} {d:+.0f}" for c, d in diff.items() if d < -TOLERANCE]
    return (f"How comparable with the paper's row: copying the nearest training demonstration with no model (the "
            f"paper's Cheat (1), [docs/difficulty.md](docs/difficulty.md)) solves {ours['Avg12']:.1f} / "
            f"{ours['Avg16']:.1f} % (Avg12 / Avg16) here, {paper.CHEAT_AVERAGES[1]['Avg12']} / "
            f"{paper.CHEAT_AVERAGES[1]['Avg16']} % in the paper; more than {TOLERANCE:.0f} points easier here: "
            f"{', '.join(easier) or 'none'}; harder: {', '.join(harder) or 'none'}.")


def table(records: dict[str, dict], ranks=RANKS) -> str:
    """The difficulty table in markdown: per task ours beside the paper's Cheat row, i = 1 / 3 / 10,
    the i = 1 difference and whether it lies within ``TOLERANCE``; then the Avg12 / Avg16 rows."""
    head = ("| task | " + " | ".join(f"ours i = {i}" for i in ranks) + " | "
            + " | ".join(f"paper i = {i}" for i in ranks) + " | i = 1: ours - paper | within ±15 |")
    lines = [head, "|" + "---|" * (2 + 2 * len(ranks) + 1)]
    ours = {i: {} for i in ranks}
    for code in tasks.AVG16:
        r = next((v for v in records.values() if v["code"] == code), None)
        if r is None:
            lines.append(f"| {code} | " + " | ".join("–" for _ in ranks) + " | "
                         + " | ".join(_paper(i, code) for i in ranks) + " | – | – |")
            continue
        for i in ranks:
            ours[i][code] = 100.0 * r["ranks"][str(i)]["success_rate"]
        diff = ours[1][code] - paper.CHEAT[1][code] if 1 in ranks else float("nan")
        mark = "" if r.get("replay_verified") else " ‡"
        lines.append(f"| {code}{mark} | " + " | ".join(f"{ours[i][code]:.0f}" for i in ranks) + " | "
                     + " | ".join(_paper(i, code) for i in ranks)
                     + f" | {diff:+.0f} | {'yes' if abs(diff) <= TOLERANCE else '**no**'} |")
    averages = {i: oracle_rates(records, i) for i in ranks}
    for name in ("Avg12", "Avg16"):
        if all(name in averages[i] for i in ranks):
            mine = " | ".join(f"{averages[i][name]:.1f}" for i in ranks)
            theirs = " | ".join(str(paper.CHEAT_AVERAGES[i][name]) if i in paper.CHEAT_AVERAGES else "–"
                                for i in ranks)
            lines.append(f"| {name} | {mine} | {theirs} | | |")
    within = sum(abs(ours[1][c] - paper.CHEAT[1][c]) <= TOLERANCE for c in ours[1]) if 1 in ranks else 0
    lines.append("")
    lines.append(f"Within ±{TOLERANCE:.0f} points of the paper's Cheat (i = 1): {within} of {len(ours[ranks[0]])} "
                 f"tasks measured. ‡: no 100 % ground-truth replay on record for that split.")
    return "\n".join(lines)


def generation_table(records: dict[str, dict], results=None) -> str:
    """Per task, how its splits were generated: training seeds tried, kept, without a valid placement,
    the expert's success over the seeds with one, and the test split's ground-truth replay (with
    ``results``: the replay record's count where it fell short of 100 %)."""
    lines = ["| task | training seeds tried | kept | no valid placement | expert success (valid placements) "
             "| test replay |", "|---|---|---|---|---|---|"]
    for code in tasks.AVG16:
        r = next((v for v in records.values() if v["code"] == code), None)
        g = (r or {}).get("generation", {}).get("train") if r else None
        if not g:
            continue
        replay = f"{r['episodes']} / {r['episodes']}" if r.get("replay_verified") else "not on record ‡"
        short = None if r.get("replay_verified") or not results else verification.find(
            results, r["task"], r["test_fingerprint"])
        if short and "successes" in short:
            replay = f"{short['successes']} / {short['episodes']} ‡"
        lines.append(f"| {code} | {g['episodes_attempted']} | {g['episodes_kept']} | "
                     f"{g.get('episodes_infeasible', '–')} | "
                     f"{100 * g.get('expert_success_rate_feasible', g['expert_success_rate']):.1f} % | {replay} |")
    return "\n".join(lines)
