"""What a Table-7 sweep's cell records beside its success (the run it evaluated, its autoencoder's
trace, its evaluation's failure records), and where a finished cell is found without evaluating it:
committed in ``results/`` (``committed_cells``), a reference run's own evaluation of the same episodes
(``reusable_evaluation``), a reference run checked to be the cell it stands in for
(``check_reference_run``).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from readjax import config, methods, stage_folder
from readjax.lab import result_record
from readjax.lab.sweep_grid import DEFAULTS


def run_label(run: Path, out) -> str:
    """How a cell names the run it evaluated: relative to the runs root (``reach_target/table7/K3_L0.5_T2``)
    where it lies under it, so that a committed sweep names no machine's folders; else as given."""
    try:
        return str(Path(run).resolve().relative_to(Path(out).resolve()))
    except ValueError:
        return str(run)


def is_trained(run: Path, model: str) -> bool:
    """Whether every stage of ``model`` is finished in ``run`` on this machine."""
    return all(stage_folder.is_finished(Path(run) / s) for s in methods.stages(model))


def committed_cells(folder: Path | None, test_ds, other_versions: bool = False) -> dict[tuple, dict]:
    """The cells of a sweep committed in ``folder`` (RESULTS/<task>/<name>/sweep.json) measured on
    ``test_ds``'s episodes (same test fingerprint and seeds), by (N, K, L, T). A cell recorded
    without its test fingerprint is not taken: nothing then says which episodes it ran.

    ``other_versions``: also a cell on the same seeds whose fingerprint differs. A test split
    generated on another CPU can differ at float precision (XLA rounds the expert's rollout
    differently per instruction set: PB's motions by < 1e-6 m, its scenes and images identical,
    BENCHMARKS 18k), so its episodes are the same scenes seen in the same images. The cell keeps
    its own fingerprint, and the table marks its pairs across versions."""
    f = folder / "sweep.json" if folder is not None else None
    if f is None or not f.exists():
        return {}
    seeds = [int(x) for x in test_ds.seeds]
    out = {}
    for c in json.loads(f.read_text()).get("cells", []):
        fingerprint = c.get("test_fingerprint")
        if (not fingerprint or (fingerprint != test_ds.fingerprint and not other_versions) or "outcomes" not in c
                or [int(x) for x in c["seeds"]] != seeds):
            continue
        out[tuple(c[k] for k in DEFAULTS)] = c
    return out


def vae_trace(run: Path) -> str | None:
    """A digest of the run's autoencoder training trace (every logged loss of ``vae/metrics.jsonl``,
    wall-clock times left out), or None for a method without one. Two cells with the same trace
    decode with the same autoencoder: the sweep's pairs then differ only in what the cell varies,
    also when a cell was trained on another machine from an autoencoder trained again there."""
    rows = stage_folder.read_metrics(Path(run) / "vae")
    if not rows:
        return None
    h = hashlib.sha256()
    for r in rows:
        h.update(json.dumps({k: v for k, v in r.items() if k != "time_s"}, sort_keys=True).encode())
    return h.hexdigest()[:16]


def cell_diagnostics(result: dict) -> dict:
    """What a cell keeps of its evaluation's failure records, so that the committed sweep says why a
    setting loses, not only that it does: failures by mode, and each episode's start (its retrieved
    motion's key-frame error, cm). Empty for an evaluation recorded before failure modes were."""
    f = result.get("failures") or {}
    out = {}
    if "counts" in f:
        out["failure_modes"] = dict(f["counts"])
    if f.get("start_keyframe_error_cm") is not None:
        out["start_error_cm"] = list(f["start_keyframe_error_cm"])
    return out


def reusable_evaluation(run: Path, model: str, n: int, test_ds) -> dict | None:
    """A finished evaluation in ``run``'s own eval/ that is exactly the cell this sweep would
    evaluate: ``model`` at N = ``n`` from SPE's top-1 on clean images with the run's own refinement,
    on ``test_ds``'s episodes (same count and content hash). The pipeline evaluates a reference run
    at the N a sweep asks for, so setting A's cells need not run twice; the copy records its source."""
    for f in sorted((run / "eval").glob("*.json")):
        try:
            r = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if (result_record.is_eval(r, model, n) and r.get("episodes") == len(test_ds)
                and r.get("test_fingerprint") == test_ds.fingerprint):
            return {**r, "reused_from": str(f)}
    return None


def check_reference_run(run: Path, task: str, model: str, configs: dict) -> None:
    """A reference run stands in for a cell only if it is that cell: the same task and method, every
    config field the recipe holds equal (inference-only and data-derived ones aside), training
    finished. Its training set is checked when it is loaded (``Planner.load``)."""
    from readjax.methods.base import read_run

    spec = read_run(run)
    if spec.get("task") != task or spec.get("method") != model:
        raise ValueError(f"--reference-run {run}: a {spec.get('method')} run on {spec.get('task')}, "
                         f"not {model} on {task}")
    wanted = json.loads(json.dumps(config.configs_to_dict(configs, list(spec["configs"]))))
    differ = result_record.recipe_differences(spec["configs"], wanted)
    if differ:
        raise ValueError(f"--reference-run {run} was trained otherwise than this sweep's setting A: "
                         f"{', '.join(differ)} differ (same --preset and --set?)")
    unfinished = [s for s in methods.stages(model) if not stage_folder.is_finished(run / s)]
    if unfinished:
        raise ValueError(f"--reference-run {run}: stage(s) {', '.join(unfinished)} not trained")
