"""The grid's cost per task: the wall clock and CPU time that ``experiments.pipeline`` recorded for
each step (``<task>/pipeline_timing.json``, :mod:`readjax.lab.timing`), as the report's table."""

from __future__ import annotations

from pathlib import Path

from readjax import tasks
from readjax.lab.timing import timing_entries, timing_records


def cost_lines(runs_root: str | Path, only_tasks: set[str] | None = None, suite: int | None = None) -> list[str]:
    """The pipeline's wall clock per task (``<task>/pipeline_timing.json``, written by
    ``experiments.pipeline``): minutes per step group and in all, with the machine's load when the
    steps started (timings beside another job are not idle-machine timings); ``only_tasks``: those
    tasks' records alone (a focused report's); ``suite``: the steps run on that suite version of the
    tasks alone (a record that names none predates suite 2)."""
    records = {t: {lb: st for lb, st in r.items() if suite is None or st.get("suite", 1) == suite}
               for t, r in timing_records(runs_root).items() if only_tasks is None or t in only_tasks}
    records = {t: r for t, r in records.items() if r}
    if not records:
        return []

    def column(label: str, kind: str) -> str:  # one column per training, the rest summed by kind
        return label if kind == "train" else kind

    cols = list(dict.fromkeys(column(lb, st["kind"]) for steps in records.values() for lb, st in steps.items()))
    order = ["generate", "verify"] + sorted(c for c in cols if c.startswith("train")) + ["evaluate", "media"]
    cols = [c for c in order if c in cols] + [c for c in cols if c not in order]
    order_of = {name: i for i, name in enumerate(tasks.names())}
    lines = ["## Pipeline wall clock per task" + (f", suite {suite}" if suite is not None else ""), "",
             "Minutes per step as `experiments.pipeline` ran it (generate: test and training splits; "
             "evaluate: every evaluation of every method). Load: the 1-minute load average when the "
             "task's steps started, min-max. CPU: the steps' CPU minutes (user + system; recorded since "
             "2026-12-04, with the share of steps that have it), which a job beside them or a pause does "
             "not inflate as it does the wall clock. A training stopped and resumed counts every run "
             "of it (since 2026-12-04; earlier records hold its last run only).", "",
             "| task | " + " | ".join(cols) + " | total | CPU | cores | load |", "|---" * (len(cols) + 5) + "|"]
    totals = dict.fromkeys(cols + ["total", "cpu"], 0.0)
    for task in sorted(records, key=lambda t: order_of.get(t, len(order_of))):
        steps = records[task]
        mins = dict.fromkeys(cols, 0.0)
        for lb, st in steps.items():
            mins[column(lb, st["kind"])] += st["seconds"] / 60
        total = sum(mins.values())
        for c in cols:
            totals[c] += mins[c]
        totals["total"] += total
        loads = [st["load_at_start"] for st in steps.values() if st.get("load_at_start") is not None]
        cores = sorted({str(st.get("cpus")) for st in steps.values()})
        load = f"{min(loads):.1f}-{max(loads):.1f}" if loads else "–"
        cpu = [st["cpu_seconds"] / 60 for st in steps.values() if st.get("cpu_seconds")]
        totals["cpu"] += sum(cpu)
        cpu_cell = "–" if not cpu else f"{sum(cpu):.1f}" + ("" if len(cpu) == len(steps) else f" ({len(cpu)}/{len(steps)})")
        lines.append(f"| {tasks.code_of(task)} | " + " | ".join(f"{mins[c]:.1f}" for c in cols)
                     + f" | {total:.1f} | {cpu_cell} | {','.join(cores)} | {load} |")
    lines.append(f"| all {len(records)} | " + " | ".join(f"{totals[c]:.1f}" for c in cols)
                 + f" | {totals['total']:.1f} | {totals['cpu']:.1f} | | |")
    return lines + [""]


GRID_KINDS = {"generate": "data", "verify": "data", "train": "train", "evaluate": "evaluate", "choose": "evaluate",
              "media": "evaluate"}


def grid_cost_lines(results_root: str | Path, runs, suite: int) -> list[str]:
    """What a grid cost, per task: the hours of the steps its timing records give to ``runs`` (the grid's
    run folders) on ``suite``, and of that suite's data steps (the val split, and any split the grid
    generated). Wall clock and CPU hours, and the trainings counted; nothing while no step has such a
    record (records name their run and suite since 2026-12-07)."""
    runs, per_task = set(runs), {}
    for task, entries in timing_entries(results_root).items():
        for label, e in entries:
            if e.get("suite") != suite or not (e.get("run") in runs or e.get("run") is None and e["kind"] in
                                               ("generate", "verify")):
                continue
            row = per_task.setdefault(task, {"data": 0.0, "train": 0.0, "evaluate": 0.0, "cpu": 0.0, "trainings": 0})
            row[GRID_KINDS.get(e["kind"], "evaluate")] += e["seconds"] / 3600
            row["cpu"] += e.get("cpu_seconds", 0.0) / 3600
            row["trainings"] += e["kind"] == "train"
    if not per_task:
        return []
    lines = [f"### What the grid cost, per task (suite {suite})", "",
             "Hours of the steps `experiments.pipeline` recorded for the grid's runs (`pipeline_timing.json` beside "
             "each task's results; a training stopped and resumed counts every run of it): wall clock by kind of "
             "step (data: the val split and its replay; evaluate: test and val evaluations, the choice, media), "
             "and the CPU hours of them all (user + system). Each step's wall clock is its own, with the grid's "
             "other steps running beside it. "
             "Suite 2's test and training splits were generated before the grid, by the suite's own work.", "",
             "| task | trainings | data | train | evaluate | wall, all | CPU |", "|---|---|---|---|---|---|---|"]
    order = {name: i for i, name in enumerate(tasks.names())}
    total = dict.fromkeys(("data", "train", "evaluate", "cpu", "trainings"), 0.0)
    for task in sorted(per_task, key=lambda t: order.get(t, len(order))):
        row = per_task[task]
        for k in total:
            total[k] += row[k]
        wall = row["data"] + row["train"] + row["evaluate"]
        lines.append(f"| {tasks.code_of(task)} | {row['trainings']} | {row['data']:.2f} | {row['train']:.2f} | "
                     f"{row['evaluate']:.2f} | {wall:.2f} | {row['cpu']:.2f} |")
    wall = total["data"] + total["train"] + total["evaluate"]
    lines.append(f"| all {len(per_task)} | {total['trainings']:.0f} | {total['data']:.2f} | {total['train']:.2f} | "
                 f"{total['evaluate']:.2f} | {wall:.2f} | {total['cpu']:.2f} |")
    return lines + [""]
