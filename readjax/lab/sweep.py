"""Hyper-parameter sweeps over Table 7's N / K / L / T (METHOD.md section 9).

N (refinement steps) is test-time only: one trained model serves every N. K (neighbour pool),
L (lambda) and T (theta1) change training, so each of their combinations is its own run; the
autoencoder stage does not depend on them and is trained once and shared. Every finished cell
(a training run, an evaluation) is kept on disk and skipped when the sweep is run again; with
``results`` set, a cell whose run is not on this machine (a fresh one) but whose evaluations are
committed there on the same test episodes is taken from there, not trained again. ``jobs`` > 1 trains
the cells side by side, ``jobs`` at a time (``experiments.train`` processes through the grid's step
runner), and evaluates and publishes each batch as it finishes.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from readjax import _runtime, config, evaluation, methods, result_record, scheduler, stage_folder, tasks
from readjax.claims import VERSION_MARK, split_versions_differ
from readjax.data import store
from readjax.data.generate import GenerateConfig, generate
from readjax.paired import discordant
from readjax.planner import Planner

TEST_TIME = ("N",)
TRAIN_KEYS = {"K": "train.K", "L": "sde.lam", "T": "sde.theta1"}
DEFAULTS = {"N": config.DEFAULT_N, "K": 3, "L": 0.5, "T": 2.0}  # the paper's setting A (its paper preset's)


def setting_of(configs: dict, n: int = config.DEFAULT_N) -> dict:
    """The Table-7 values a run is trained with (its configs after the preset and the overrides) at N."""
    return {"N": n, "K": configs["train"].K, "L": configs["sde"].lam, "T": configs["sde"].theta1}
CELL_PREFIX = "sweep_"  # a cell's evaluation is RUN/eval/<CELL_PREFIX>N<n>.json (reports list it by sweep)


def parse_grid(items) -> dict[str, list]:
    """["N=1,10,100", "L=0.1,0.5"] -> {"N": [1, 10, 100], "L": [0.1, 0.5]}."""
    grid = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"grid entry {item!r} is not of the form KEY=v1,v2,...")
        key, values = item.split("=", 1)
        key = key.strip()
        if key not in DEFAULTS:
            raise ValueError(f"cannot sweep {key!r}; sweepable: {', '.join(DEFAULTS)}")
        try:
            vals = [int(v) if key in ("N", "K") else float(v) for v in values.split(",") if v.strip()]
        except ValueError:
            raise ValueError(f"grid {key}: expected numbers, got {values!r}") from None
        if not vals:
            raise ValueError(f"grid {key} has no values")
        if key in ("N", "K") and min(vals) < (0 if key == "N" else 1):
            raise ValueError(f"grid {key} values must be >= {0 if key == 'N' else 1}")
        grid[key] = vals
    if not grid:
        raise ValueError("empty grid: give at least one of N=..., K=..., L=..., T=...")
    return grid


@dataclass(frozen=True)
class SweepConfig:
    task: str
    grid: dict = field(default_factory=dict)
    model: str = "read"
    preset: str = "cpu"
    data: str = "data"
    out: str = "runs"
    name: str = "sweep"
    episodes: int = 100
    sets: tuple = ()
    batch_size: int = 50
    results: str | None = None  # also write sweep.json / table.md / sweep.png to RESULTS/<task>/<name>/
    # a finished run trained exactly as setting A (e.g. the grid's READ run): the cell of that setting
    # evaluates it instead of training it again (checked: its recipe and training set must match)
    reference_run: str | None = None
    # "all": every combination of the grid's values; "one": Table 7's layout, setting A and each key
    # varied alone from it (the other keys at A's values; N varied at A's training only)
    vary: str = "all"
    # trainings at once (jobs > 1: each cell's training an ``experiments.train`` process, the
    # evaluations after them in this one); a GPU holds a dozen, 2 cores two
    jobs: int = 1
    # also keep committed cells measured on the same seeds but another version of the test split (another
    # CPU's float rounding of the expert's motions: the same scenes and images, fingerprints differ);
    # off, such cells are trained again. The table marks each pair across versions (VERSION_MARK).
    other_split_versions: bool = False


def _label(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def run_sweep(cfg: SweepConfig, progress: bool = True) -> dict:
    task = tasks.canonical_name(cfg.task)
    sweep_dir = Path(cfg.out) / task / cfg.name
    train_keys = [k for k in TRAIN_KEYS if k in cfg.grid]
    n_values = cfg.grid.get("N", [DEFAULTS["N"]])
    if cfg.vary not in ("all", "one"):
        raise ValueError(f"vary must be 'all' or 'one', got {cfg.vary!r}")
    if cfg.jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {cfg.jobs}")
    test_dir = store.split_dir(cfg.data, task, "test")
    if not test_dir.exists() or store.read_progress(test_dir).kept < cfg.episodes:
        meta = store.read_meta(store.split_dir(cfg.data, task, "train")) or {}
        generate(GenerateConfig(task=task, split="test", episodes=cfg.episodes, out=cfg.data,
                                image_size=meta.get("image_size", 64)), progress=progress)
    test_ds = store.load_dataset(test_dir, limit=cfg.episodes)
    cells = []
    # setting A of this sweep: its preset's own values (the paper preset: the paper's A; the cpu preset
    # trains on K = 50), with the fixed --set overrides
    reference = setting_of(config.override(config.presets(cfg.preset), list(cfg.sets)))
    committed = committed_cells(Path(cfg.results) / task / cfg.name if cfg.results else None, test_ds,
                                other_versions=cfg.other_split_versions)
    plan = []  # (values, run_name, run_dir, configs, trained, Ns, committed cells or None)
    for values in cell_settings(cfg.grid, reference, cfg.vary):
        at_a = all(values[k] == reference[k] for k in values)
        run_name = "_".join(f"{k}{_label(v)}" for k, v in values.items()) or "default"
        run_dir = sweep_dir / run_name
        configs = config.override(config.presets(cfg.preset), cell_overrides(cfg, values))
        is_reference = bool(cfg.reference_run) and setting_of(configs) == reference
        trained = Path(cfg.reference_run) if is_reference else run_dir
        # Table 7's layout: N varied at A's training (which is also evaluated at A's N, the pairs' anchor),
        # every other cell at A's N
        ns = n_values if cfg.vary == "all" else sorted(set(n_values) | {reference["N"]}) if at_a else [reference["N"]]
        kept = None
        if not _is_trained(trained, cfg.model) and not all((run_dir / "eval" / f"{CELL_PREFIX}N{n}.json").exists()
                                                           for n in ns):
            # a fresh machine: the trained run is gone, its finished cells are in RESULTS (committed)
            found = [committed.get(tuple(setting_of(configs, n).values())) for n in ns]
            kept = found if all(found) else None
        if kept is None and is_reference:
            check_reference_run(trained, task, cfg.model, configs)
        plan.append((values, run_name, run_dir, configs, trained, ns, kept))
    vae_source = _shared_autoencoder(cfg, plan)
    to_train = [e for e in plan if _to_train(e, cfg.model)]

    def publish() -> dict:
        # the cells so far, after each training: a sweep of hours leaves its finished cells in
        # RESULTS (committed) even if this machine goes before the last one
        out = {"task": task, "code": tasks.code_of(task), "model": cfg.model, "preset": cfg.preset,
               "grid": cfg.grid, "episodes": cfg.episodes, "reference": reference, "vary": cfg.vary,
               "cells": list(cells)}
        for folder in [sweep_dir] + ([Path(cfg.results) / task / cfg.name] if cfg.results else []):
            write_sweep(out, folder)
        return out

    for values, run_name, run_dir, configs, trained, ns, kept in plan:
        if kept is not None:
            cells += kept
            if progress:
                for c in kept:
                    print(_cell_line(task, c, c["success"]) + f" (committed in {cfg.results})", flush=True)
            out = publish()
            continue
        if cfg.jobs > 1 and to_train and to_train[0][2] == run_dir:
            # the next `jobs` cells to train, side by side; each is evaluated (and published) as the
            # loop reaches it, so a sweep cut short keeps every finished batch's cells
            batch, to_train = to_train[:cfg.jobs], to_train[cfg.jobs:]
            train_side_by_side(cfg, task, batch, vae_source, sweep_dir, progress)
        if trained == run_dir:
            # the autoencoder ignores K, L, T: the first cell trains it, the others start from it
            shared = ({"vae_from": vae_source} if vae_source is not None and Path(vae_source) != run_dir
                      and "vae" in methods.stages(cfg.model) else {})
            methods.module(cfg.model).train(task, cfg.data, run_dir, configs, cfg.preset, progress=progress, **shared)
        if (trained / "vae").exists():
            vae_source = vae_source or trained
        planner = None
        for n in ns:
            name = f"{CELL_PREFIX}N{n}"
            f = run_dir / "eval" / f"{name}.json"  # in the sweep's folder, also for a reference run's cell
            if f.exists():
                result = json.loads(f.read_text())
            elif trained != run_dir and (reused := reusable_evaluation(trained, cfg.model, n, test_ds)) is not None:
                result = reused  # the reference run's own evaluation of these episodes (the pipeline's)
                f.parent.mkdir(parents=True, exist_ok=True)
                f.write_text(json.dumps(result))
            else:
                planner = planner or Planner.load(trained, data_root=cfg.data)
                ecfg = evaluation.EvalConfig(episodes=cfg.episodes, N=n, batch_size=min(cfg.batch_size, cfg.episodes),
                                             videos=0)
                result = evaluation.evaluate(planner, test_ds, ecfg, out_dir=run_dir / "eval", name=name,
                                             progress=progress)
            full = setting_of(configs, n)  # what this cell trained with, not the paper's defaults
            cells.append({**full, "run": run_label(trained, cfg.out), "success": result["success_rate"],
                          "table": result["table"], "seeds": result["seeds"],
                          "outcomes": [int(x) for x in result["success"]],
                          "test_fingerprint": test_ds.fingerprint, "vae_trace": vae_trace(trained),
                          **cell_diagnostics(result)})
            if progress:
                print(_cell_line(task, full, result["success_rate"]), flush=True)
        # Each cell compiles its own programs: free them before the process nears the kernel's
        # cap on memory mappings (see readjax._runtime).
        del planner
        _runtime.release_compiled_if_crowded()
        out = publish()
    return out


def run_label(run: Path, out) -> str:
    """How a cell names the run it evaluated: relative to the runs root (``reach_target/table7/K3_L0.5_T2``)
    where it lies under it, so that a committed sweep names no machine's folders; else as given."""
    try:
        return str(Path(run).resolve().relative_to(Path(out).resolve()))
    except ValueError:
        return str(run)


def _cell_line(task: str, setting: dict, success: float) -> str:
    """A cell's progress line: its N, K, L, T and success."""
    return f"  {task} " + " ".join(f"{k}={_label(setting[k])}" for k in DEFAULTS) + f": {100 * success:.1f}%"


def cell_overrides(cfg: SweepConfig, values: dict) -> list[str]:
    """The config overrides a cell trains with: the sweep's --set, then the cell's K / L / T."""
    return list(cfg.sets) + [f"{TRAIN_KEYS[k]}={v}" for k, v in values.items()]


def _is_trained(run: Path, model: str) -> bool:
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


def _to_train(entry: tuple, model: str) -> bool:
    """Whether a sweep plan's cell is still to train here: not a reference run, not taken from the
    committed results, not finished."""
    _, _, run_dir, _, trained, _, kept = entry
    return kept is None and trained == run_dir and not _is_trained(run_dir, model)


def _shared_autoencoder(cfg: SweepConfig, plan: list) -> Path | None:
    """The run whose finished autoencoder the cells to train start from: the reference run's or the
    first cell's already on disk; None: the first cell to train trains it."""
    if "vae" not in methods.stages(cfg.model):
        return None
    if cfg.reference_run:
        if stage_folder.is_finished(Path(cfg.reference_run) / "vae"):
            return Path(cfg.reference_run)
        if any(_to_train(e, cfg.model) for e in plan):
            raise ValueError(f"--reference-run {cfg.reference_run}: no finished autoencoder stage there, and "
                             f"the cells to train start from it; train it again (`experiments.train --stage vae` "
                             f"with the run's name and --set), or let the grid's pipeline do it")
        return None
    return next((Path(t) for *_, t, _, _ in plan if stage_folder.is_finished(Path(t) / "vae")), None)


def train_side_by_side(cfg: SweepConfig, task: str, plan: list, vae_source: Path | None, sweep_dir: Path,
                       progress: bool) -> None:
    """Train every cell of ``plan`` still to train, ``cfg.jobs`` at once, each an ``experiments.train``
    process (logs in SWEEP/logs/). Cells share ``vae_source``'s autoencoder; without one the first
    cell's is trained first, alone, and the others start from it."""
    python = sys.executable

    def argv(run_name: str, values: dict, extra=()) -> list[str]:
        return scheduler.train_command(python, task=task, model=cfg.model, preset=cfg.preset,
                                       name=f"{cfg.name}/{run_name}", data=cfg.data, out=cfg.out,
                                       overrides=cell_overrides(cfg, values), extra=extra)

    todo = [entry[:3] for entry in plan if _to_train(entry, cfg.model)]  # (values, run name, run folder)
    if not todo:
        return
    steps, first_vae = [], None
    if vae_source is None and "vae" in methods.stages(cfg.model):
        values, run_name, run_dir = todo[0]
        first_vae = scheduler.Step("train", task, f"train {run_name} (autoencoder only)",
                                   argv(run_name, values, ["--stage", "vae"]),
                                   made=lambda d=run_dir: stage_folder.is_finished(d / "vae"), resumes=True)
        steps.append(first_vae)
        vae_source = run_dir
    for values, run_name, run_dir in todo:
        extra = ["--vae-from", str(vae_source)] if vae_source is not None and run_dir != vae_source else []
        step = scheduler.Step("train", task, f"train {run_name}", argv(run_name, values, extra),
                              made=lambda d=run_dir: _is_trained(d, cfg.model),
                              resumes=True, progress=lambda d=run_dir: stage_folder.progress(d))
        if first_vae is not None:
            step.needs.append(first_vae)
        steps.append(step)
    scheduler.run_steps(steps, log=print if progress else (lambda _: None), jobs=cfg.jobs,
                        log_dir=sweep_dir / "logs")


def cell_settings(grid: dict, reference: dict, vary: str = "all") -> list[dict]:
    """The trained settings of a sweep, each {key: value} over the grid's training keys (K, L, T):
    ``vary`` "all" every combination; "one" Table 7's: setting A first, then each key's other values
    with the rest at A."""
    keys = [k for k in TRAIN_KEYS if k in grid]
    if vary == "all":
        return [dict(zip(keys, combo)) for combo in itertools.product(*[grid[k] for k in keys])] or [{}]
    a = {k: reference[k] for k in keys}
    return [a] + [{**a, k: v} for k in keys for v in grid[k] if v != reference[k]]


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


def write_sweep(sweep: dict, folder: Path) -> None:
    """sweep.json (every cell's settings, success and per-episode outcomes), table.md and sweep.png
    in ``folder``: the run folder's copy, or the one under results/ that is committed and that
    ``experiments.report --runs results/`` shows."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sweep.json").write_text(json.dumps(sweep, indent=2))
    (folder / "table.md").write_text(format_table7(sweep))
    plot_sweep(sweep, folder / "sweep.png")


START_BINS_CM = (3.0, 10.0)  # a cell's episodes by how far its own retrieval started: < 3, 3-10, > 10 cm


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


def solved_by_start(cell: dict) -> str:
    """``solved / episodes`` from starts in each of START_BINS_CM's ranges, e.g. ``29/30, 46/47, 11/23``."""
    start, won = np.asarray(cell["start_error_cm"], float), np.asarray(cell["outcomes"], bool)
    bins = np.digitize(start, START_BINS_CM)
    return ", ".join(f"{int(won[bins == b].sum())}/{int((bins == b).sum())}" for b in range(len(START_BINS_CM) + 1))


def _has_starts(cell: dict) -> bool:
    return "start_error_cm" in cell and "outcomes" in cell


def _modes(cell: dict) -> str:
    counts = cell.get("failure_modes")
    if counts is None:
        return ""
    return ", ".join(f"{m} {n}" for m, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))) or "none"


def _is_default(cell: dict, reference: dict) -> bool:
    return all(cell[k] == v for k, v in reference.items())


def format_table7(sweep: dict) -> str:
    """The layout of the paper's Table 7: setting, N, K, L, T, success (%); where the cells carry
    their per-episode outcomes and the sweep holds its setting A (``reference``: its preset's values
    at N = 100; the paper's A for a sweep recorded without one), each other cell against A on the
    same episodes (+ episodes only it solves / - only A solves, exact McNemar p). Where the cells keep
    their evaluations' failure records (:func:`cell_diagnostics`): the episodes solved from near,
    middling and far starts, and the failures by mode."""
    code = sweep["code"]
    reference = sweep.get("reference", DEFAULTS)
    a = next((c for c in sweep["cells"] if _is_default(c, reference) and "outcomes" in c), None)
    starts = any(_has_starts(c) for c in sweep["cells"])
    modes = any("failure_modes" in c for c in sweep["cells"])
    lo, hi = (_label(x) for x in START_BINS_CM)
    lines = [f"| setting | N | K | L | T | {code} |" + (" vs A |" if a else "")
             + (f" solved from starts < {lo} / {lo}-{hi} / > {hi} cm |" if starts else "")
             + (" failures by mode |" if modes else ""),
             "|---|---|---|---|---|---|" + ("---|" if a else "") + ("---|" if starts else "") + ("---|" if modes else "")]
    others = 0  # the other settings are lettered B, C, ... in order, A's place skipped
    across_versions = False
    for c in sweep["cells"]:
        if _is_default(c, reference):
            tag = "A (default)"
        else:
            tag = chr(ord("B") + others) if others < 25 else str(others + 1)
            others += 1
        row = f"| {tag} | {c['N']} | {c['K']} | {_label(c['L'])} | {_label(c['T'])} | {100 * c['success']:.1f} |"
        if a:
            vs = ("–" if c is a or "outcomes" not in c else
                  discordant({"seeds": c["seeds"], "success": c["outcomes"]}, {"seeds": a["seeds"], "success": a["outcomes"]}))
            if vs != "–" and split_versions_differ(c, a):
                vs += f" {VERSION_MARK}"
                across_versions = True
            row += f" {vs} |"
        if starts:
            row += f" {solved_by_start(c) if _has_starts(c) else ''} |"
        if modes:
            row += f" {_modes(c)} |"
        lines.append(row)
    if across_versions:
        lines += ["", f"{VERSION_MARK} This cell and A ran the same seeds (the same scenes and images) on different "
                  "versions of the test split: generated on different CPUs, their expert motions differ at float "
                  "precision (`test_fingerprint` in each cell)."]
    return "\n".join(lines) + "\n"


def plot_sweep(sweep: dict, path: Path) -> None:
    """Success against each swept value (one panel per key; other keys' values as separate lines)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(sweep["grid"])
    fig, axes = plt.subplots(1, len(keys), figsize=(4 * len(keys), 3.2), squeeze=False)
    reference = sweep.get("reference", DEFAULTS)
    for ax, key in zip(axes[0], keys):
        others = [k for k in keys if k != key]
        groups: dict = {}
        for c in sweep["cells"]:
            if sweep.get("vary") == "one" and any(c[k] != reference[k] for k in others):
                continue  # Table 7's layout: a key's panel shows it varied alone from setting A
            groups.setdefault(tuple(c[k] for k in others), []).append((c[key], 100 * c["success"]))
        for g, pts in groups.items():
            pts.sort()
            xs, ys = zip(*pts)
            label = ", ".join(f"{k}={_label(v)}" for k, v in zip(others, g)) or None
            ax.plot(range(len(xs)) if key == "N" else xs, ys, marker="o", label=label)
            if key == "N":
                ax.set_xticks(range(len(xs)), [str(x) for x in xs])
        ax.set_xlabel(key)
        ax.set_ylabel(f"{sweep['code']} success (%)")
        ax.set_ylim(-3, 103)
        if len(groups) > 1:
            ax.legend(fontsize=7)
    fig.suptitle(f"{sweep['model']} on {sweep['task']} ({sweep['episodes']} episodes per cell)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def success_matrix(sweep: dict) -> np.ndarray:
    return np.array([c["success"] for c in sweep["cells"]])
