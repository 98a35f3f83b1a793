"""Hyper-parameter sweeps over Table 7's N / K / L / T (METHOD.md section 9).

N (refinement steps) is test-time only: one trained model serves every N. K (neighbour pool),
L (lambda) and T (theta1) change training, so each of their combinations is its own run; the
autoencoder stage does not depend on them and is trained once and shared. Every finished cell
(a training run, an evaluation) is kept on disk and skipped when the sweep is run again; with
``results`` set, a cell whose run is not on this machine (a fresh one) but whose evaluations are
committed there on the same test episodes is taken from there, not trained again. The cells' trainings
are steps on Ray (``experiments.train`` processes, :mod:`readjax.lab.ray_grid`: an embedded Ray on this
machine, or the cluster at ``ray_address``), side by side as the machines allow; this process evaluates
each cell, in the sweep's order, as soon as its training has finished, and publishes the table after each.
This module runs a sweep (``run_sweep``: the cells' trainings as steps, ``training_steps``; their
evaluations, ``entry_cells``); its grid and settings are :mod:`readjax.lab.sweep_grid`, what a cell
records and where a finished one is found :mod:`readjax.lab.sweep_cells`, the table and the plot
:mod:`readjax.lab.sweep_table`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Callable

from readjax import _runtime, config, evaluation, methods, stage_folder, tasks
from readjax.data import store
from readjax.data.generate import GenerateConfig, generate
from readjax.lab import ray_grid, ray_resources, sweep_table
from readjax.lab.steps import Step, train_command
from readjax.lab.sweep_cells import (cell_diagnostics, check_reference_run, committed_cells,
                                     is_trained, reusable_evaluation, run_label, vae_trace)
from readjax.lab.sweep_grid import (CELL_PREFIX, DEFAULTS, SweepConfig, cell_overrides, cell_settings,
                                    setting_of, value_label)
from readjax.planner import Planner


def run_sweep(cfg: SweepConfig, progress: bool = True, execute: Callable | None = None) -> dict:
    """Run (or resume) the sweep; returns its record (as sweep.json). ``execute(steps, log=,
    on_finished=)`` runs the cells' training steps (default: on Ray, ``ray_grid.run_on_ray``; tests
    pass ``steps.run_in_order`` with a stand-in for the commands)."""
    task = tasks.canonical_name(cfg.task)
    sweep_dir = Path(cfg.out) / task / cfg.name
    n_values = cfg.grid.get("N", [DEFAULTS["N"]])
    if cfg.vary not in ("all", "one"):
        raise ValueError(f"vary must be 'all' or 'one', got {cfg.vary!r}")
    ray_resources.parse_resources(cfg.resources)  # a mistake there fails now, not after the test split's generation
    test_dir = store.split_dir(cfg.data, task, "test")
    if not test_dir.exists() or store.read_progress(test_dir).kept < cfg.episodes:
        generate(GenerateConfig(task=task, split="test", episodes=cfg.episodes, out=cfg.data,
                                image_size=store.existing_image_size(cfg.data, task) or 64), progress=progress)
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
        run_name = "_".join(f"{k}{value_label(v)}" for k, v in values.items()) or "default"
        run_dir = sweep_dir / run_name
        configs = config.override(config.presets(cfg.preset), cell_overrides(cfg, values))
        is_reference = bool(cfg.reference_run) and setting_of(configs) == reference
        trained = Path(cfg.reference_run) if is_reference else run_dir
        # Table 7's layout: N varied at A's training (which is also evaluated at A's N, the pairs' anchor),
        # every other cell at A's N
        ns = n_values if cfg.vary == "all" else sorted(set(n_values) | {reference["N"]}) if at_a else [reference["N"]]
        kept = None
        if not is_trained(trained, cfg.model) and not all((run_dir / "eval" / f"{CELL_PREFIX}N{n}.json").exists()
                                                           for n in ns):
            # a fresh machine: the trained run is gone, its finished cells are in RESULTS (committed)
            found = [committed.get(tuple(setting_of(configs, n).values())) for n in ns]
            kept = found if all(found) else None
        if kept is None and is_reference:
            check_reference_run(trained, task, cfg.model, configs)
        plan.append((values, run_name, run_dir, configs, trained, ns, kept))
    training = {e[2] for e in plan if _to_train(e, cfg.model)}  # the run folders of the cells to train
    steps = training_steps(cfg, task, plan, _shared_autoencoder(cfg, plan))

    def publish() -> dict:
        # the cells so far, after each cell: a sweep of hours leaves its finished cells in
        # RESULTS (committed) even if this machine goes before the last one
        out = {"task": task, "code": tasks.code_of(task), "model": cfg.model, "preset": cfg.preset,
               "grid": cfg.grid, "episodes": cfg.episodes, "reference": reference, "vary": cfg.vary,
               "cells": list(cells)}
        for folder in [sweep_dir] + ([Path(cfg.results) / task / cfg.name] if cfg.results else []):
            sweep_table.write_sweep(out, folder)
        return out

    published = {"next": 0, "out": None}

    def evaluate_ready(_step=None) -> None:
        """Evaluate and publish the cells, in the sweep's order, up to the first whose training runs."""
        while published["next"] < len(plan):
            entry = plan[published["next"]]
            if entry[2] in training and not is_trained(entry[2], cfg.model):
                return
            cells.extend(entry_cells(cfg, task, entry, test_ds, progress))
            published["out"], published["next"] = publish(), published["next"] + 1

    if steps:
        run = execute or (lambda steps, **kw: ray_grid.run_on_ray(
            steps, address=cfg.ray_address, log_dir=sweep_dir / "logs",
            resources=ray_resources.parse_resources(cfg.resources), **kw))
        run(steps, log=print if progress else (lambda _: None), on_finished=evaluate_ready)
    evaluate_ready()
    return published["out"]


def entry_cells(cfg: SweepConfig, task: str, entry: tuple, test_ds, progress: bool) -> list[dict]:
    """A sweep plan's entry's cells, one per N: committed ones as kept, the others evaluated here (or
    taken from the reference run's own evaluations of the same episodes)."""
    values, run_name, run_dir, configs, trained, ns, kept = entry
    if kept is not None:
        if progress:
            for c in kept:
                print(_cell_line(task, c, c["success"]) + f" (committed in {cfg.results})", flush=True)
        return list(kept)
    cells, planner = [], None
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
    return cells


def _cell_line(task: str, setting: dict, success: float) -> str:
    """A cell's progress line: its N, K, L, T and success."""
    return f"  {task} " + " ".join(f"{k}={value_label(setting[k])}" for k in DEFAULTS) + f": {100 * success:.1f}%"


def _to_train(entry: tuple, model: str) -> bool:
    """Whether a sweep plan's cell is still to train here: not a reference run, not taken from the
    committed results, not finished."""
    _, _, run_dir, _, trained, _, kept = entry
    return kept is None and trained == run_dir and not is_trained(run_dir, model)


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


def training_steps(cfg: SweepConfig, task: str, plan: list, vae_source: Path | None) -> list[Step]:
    """The steps training every cell of ``plan`` still to train, each an ``experiments.train`` process
    (with the cell's overrides). Cells share ``vae_source``'s autoencoder (it ignores K, L, T); without
    one the first cell's is trained first, alone, and the others start from it."""
    python = sys.executable

    def argv(run_name: str, values: dict, extra=()) -> list[str]:
        return train_command(python, task=task, model=cfg.model, preset=cfg.preset, name=f"{cfg.name}/{run_name}",
                             data=cfg.data, out=cfg.out, overrides=cell_overrides(cfg, values), extra=extra)

    todo = [entry[:3] for entry in plan if _to_train(entry, cfg.model)]  # (values, run name, run folder)
    if not todo:
        return []
    steps, first_vae = [], None
    if vae_source is None and "vae" in methods.stages(cfg.model):
        values, run_name, run_dir = todo[0]
        first_vae = Step("train", task, f"train {run_name} (autoencoder only)", argv(run_name, values, ["--stage", "vae"]),
                         made=lambda d=run_dir: stage_folder.is_finished(d / "vae"), resumes=True)
        steps.append(first_vae)
        vae_source = run_dir
    for values, run_name, run_dir in todo:
        extra = ["--vae-from", str(vae_source)] if vae_source is not None and run_dir != vae_source else []
        step = Step("train", task, f"train {run_name}", argv(run_name, values, extra),
                    made=lambda d=run_dir: is_trained(d, cfg.model), resumes=True,
                    progress=lambda d=run_dir: stage_folder.progress(d))
        if first_vae is not None:
            step.needs.append(first_vae)
        steps.append(step)
    return steps
