"""The grid's cost per task: the wall clock and CPU time that ``experiments.pipeline`` recorded for
each step (``<task>/pipeline_timing.json``, :mod:`readjax.lab.timing`), as the report's table."""

from __future__ import annotations

from pathlib import Path

from readjax import tasks
from readjax.lab.timing import timing_records


def cost_lines(runs_root: str | Path, only_tasks: set[str] | None = None) -> list[str]:
    """The pipeline's wall clock per task (``<task>/pipeline_timing.json``, written by
    ``experiments.pipeline``): minutes per step group and in all, with the machine's load when the
    steps started (timings beside another job are not idle-machine timings); ``only_tasks``: those
    tasks' records alone (a focused report's)."""
    records = {t: r for t, r in timing_records(runs_root).items() if only_tasks is None or t in only_tasks}
    if not records:
        return []

    def column(label: str, kind: str) -> str:  # one column per training, the rest summed by kind
        return label if kind == "train" else kind

    cols = list(dict.fromkeys(column(lb, st["kind"]) for steps in records.values() for lb, st in steps.items()))
    order = ["generate", "verify"] + sorted(c for c in cols if c.startswith("train")) + ["evaluate", "media"]
    cols = [c for c in order if c in cols] + [c for c in cols if c not in order]
    order_of = {name: i for i, name in enumerate(tasks.names())}
    lines = ["## Pipeline wall clock per task", "",
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
