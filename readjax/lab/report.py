"""Assemble every evaluation under a runs folder into the paper's tables (methods x tasks with
Avg12 / Avg16 where all member tasks are present), a chart (bars, or a heat map for many rows), and the provenance."""

from __future__ import annotations

import fnmatch
import json
from pathlib import Path
from typing import Callable

import numpy as np

from readjax import failure_modes, tasks
from readjax.lab import refine_report, verification
from readjax.lab.cost_table import cost_lines
from readjax.lab.paired import mcnemar_p, paired_outcomes
from readjax.lab.replicates import across_lines
from readjax.lab.result_record import PROTOCOLS, protocol
from readjax.lab.sweep_grid import CELL_PREFIX
from readjax.lab.sweep_table import format_table7
from readjax.tables import markdown_table, natural_key, row_label, success_chart, success_table


def run_label(run_dir: Path, runs_root: Path, task: str) -> str:
    """A run's name in the tables: its path below ``runs_root`` without the task folder
    (``read`` for ``runs/reach_target/read``; ``runs3/read`` or ``sweep/L0.1`` deeper down), so
    the same run name for the same task in two places stays two rows."""
    parts = [p for p in run_dir.relative_to(runs_root).parts if p != task]
    return "/".join(parts) or run_dir.name


def _matches(run_dir: Path, label: str, patterns: tuple[str, ...]) -> bool:
    return any(fnmatch.fnmatch(run_dir.name, pat) or fnmatch.fnmatch(label, pat) for pat in patterns)


def _kept(run_dir: Path, label: str, exclude: tuple[str, ...], include: tuple[str, ...]) -> bool:
    """Whether a run (or sweep) folder passes the report's name filters: no ``exclude`` pattern
    matches it and, where ``include`` patterns are given, one of them does."""
    return not _matches(run_dir, label, exclude) and (not include or _matches(run_dir, label, include))


def _json_records(root: Path, pattern: str, keys: tuple[str, ...]):
    """(path, record) of every JSON object below ``root`` matching ``pattern`` that holds all ``keys``,
    in path order; unreadable files and other records are skipped (a report reads what it knows)."""
    for f in sorted(root.rglob(pattern)):
        try:
            r = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if isinstance(r, dict) and all(k in r for k in keys):
            yield f, r


def collect(runs_root: str | Path, exclude: tuple[str, ...] = (), include: tuple[str, ...] = ()) -> list[dict]:
    """All evaluation results (``<run>/eval/<name>.json``) below ``runs_root``, except those of runs
    whose name (folder name, or the label of ``run_label``) matches one of the ``exclude`` glob
    patterns, and, where ``include`` patterns are given, only those of runs matching one of them."""
    root = Path(runs_root)
    out = []
    for f, r in _json_records(root, "eval/*.json", ("success_rate", "task")):
        if r.get("split", "test") != "test":  # a validation evaluation is never a table's number
            continue
        run_dir = f.parent.parent
        label = run_label(run_dir, root, r["task"])
        if not _kept(run_dir, label, exclude, include):
            continue
        r["_run_name"] = label
        r["_verified"] = verification.evaluation_verified(root, r)  # its test split replayed 100 % (on record here)
        r["_sweep_cell"] = str(r.get("name", "")).startswith(CELL_PREFIX)  # shown in its sweep's table only
        r["_file"] = str(f)
        out.append(r)
    return out


def rows_by_label(results: list[dict]) -> dict[str, dict[str, dict]]:
    """The results as table rows: row label -> task -> result."""
    rows: dict[str, dict[str, dict]] = {}
    for r in results:
        rows.setdefault(row_label(r), {})[r["task"]] = r
    return rows


def tables(results: list[dict]) -> dict[str, dict[str, float]]:
    rows = rows_by_label(results)
    return {label: success_table({t: r["success_rate"] for t, r in rows[label].items()})
            for label in sorted(rows, key=natural_key)}


def machine_of(r: dict) -> str:
    m = r.get("machine") or {}
    return f"{m.get('backend', '?')}: {m.get('devices', '?')}" if m else "not recorded"


def stacks(results: list[dict]) -> tuple[dict[str, str], list[str], dict[tuple, list[dict]]]:
    """The software every result shares, the packages whose versions differ between results, and
    the results grouped by (machine, differing versions): a table may mix runs made on a GPU
    machine's stack with runs made here, and the reader should see which is which."""
    keys = list(dict.fromkeys(k for r in results for k in r.get("versions", {})))
    differing = [k for k in keys if len({r.get("versions", {}).get(k) for r in results}) > 1]
    common = {k: results[0].get("versions", {}).get(k) for k in keys if k not in differing}
    groups: dict[tuple, list[dict]] = {}
    for r in results:
        key = (machine_of(r), *(str(r.get("versions", {}).get(k, "–")) for k in differing))
        groups.setdefault(key, []).append(r)
    return common, differing, groups


def provenance_lines(results: list[dict]) -> list[str]:
    common, differing, groups = stacks(results)
    lines = ["## Provenance", "", "| package | version |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in common.items()]
    lines += ["", "Machines and differing software the results were evaluated with (the stack a run "
              "was trained with is in its `run.json`):", "",
              "| machine | " + " | ".join(differing + ["results"]) + " |", "|---" * (len(differing) + 2) + "|"]
    for key, rs in groups.items():
        cell = "; ".join(f"{label} ({', '.join(tasks.code_of(t) for t in by_task)})"
                         for label, by_task in sorted(rows_by_label(rs).items()))
        lines.append("| " + " | ".join(key) + f" | {cell} |")
    return lines


def paired_comparison(results: list[dict], reference: str) -> dict[str, dict[str, str]]:
    """Each row against the ``reference`` row (a label of the tables) on the episodes both ran:
    the difference in success points and the exact McNemar p-value, per task. With 100 episodes a
    difference of a few points is usually noise; the p-value says which are not."""
    rows = rows_by_label(results)
    if reference not in rows:
        raise ValueError(f"--compare: no row {reference!r}; rows are: {', '.join(sorted(rows, key=natural_key))}")
    ref = rows[reference]
    out: dict[str, dict[str, str]] = {}
    for label in sorted(rows, key=natural_key):
        if label == reference:
            continue
        cells = {}
        for task, r in rows[label].items():
            if task not in ref:
                continue
            pair = paired_outcomes(r, ref[task])
            if pair is None:
                continue
            a, b = pair
            diff = 100.0 * (np.mean(a) - np.mean(b))
            cells[tasks.code_of(task)] = f"{diff:+.0f} (p={mcnemar_p(a, b):.2g})"
        if cells:
            out[label] = cells
    return out


def comparison_lines(results: list[dict], reference: str) -> list[str]:
    table = paired_comparison(results, reference)
    cols = [c for c in tasks.AVG16 if any(c in r for r in table.values())]
    lines = [f"## Paired comparison with `{reference}`", "",
             "Difference in success points on the same test episodes, and the exact McNemar p-value "
             "(two-sided; p < 0.05 is unlikely to be episode noise).", "",
             "| method | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    lines += [f"| {label} | " + " | ".join(r.get(c, "–") for c in cols) + " |" for label, r in table.items()]
    return lines + [""]


def start_lines(results: list[dict]) -> list[str]:
    """Per task with landmarks, each retrieving row's success split by where refinement started
    (``failure_modes.by_start``, recorded by evaluation): succeeded / episodes per start group and
    distance. It shows which failures retrieval caused and which refinement did not undo."""
    with_starts = [r for r in results if r.get("starts")]
    if not with_starts:
        return []
    lines = ["## Where refinement started (tasks with landmarks)", "",
             "Succeeded / episodes, split by the retrieved motion's end point: the landmark it lies nearest "
             "and how far from it. A plan that starts at a distractor has to be moved to the target by "
             "refinement; one that starts far from the target has to be moved a long way.", ""]
    for task in sorted({r["task"] for r in with_starts}):
        rows = sorted((r for r in with_starts if r["task"] == task), key=lambda r: natural_key(row_label(r)))
        cols: list[tuple[str, str]] = []
        for r in rows:
            for group, buckets in r["starts"]["success_by_start"].items():
                cols += [(group, b) for b in buckets if (group, b) not in cols]
        cols.sort(key=lambda c: (c[0] != "target", c[0], failure_modes.bucket_rank(c[1])))
        lines += [f"| {tasks.code_of(task)} | " + " | ".join(f"{g} {b}" for g, b in cols) + " |",
                  "|---|" + "---|" * len(cols)]
        for r in rows:
            by = r["starts"]["success_by_start"]
            cells = [(f"{by[g][b]['succeeded']} / {by[g][b]['episodes']}" if b in by.get(g, {}) else "–") for g, b in cols]
            lines.append(f"| {row_label(r)} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def sweeps(runs_root: str | Path, exclude: tuple[str, ...] = (), include: tuple[str, ...] = ()) -> list[dict]:
    """Every sweep below ``runs_root`` (``sweep.json``), filtered by its folder name as ``collect``
    filters runs."""
    return [json.loads(f.read_text()) for f in sorted(Path(runs_root).rglob("sweep.json"))
            if _kept(f.parent, f.parent.name, exclude, include)]


def refine_reports(runs_root: str | Path, exclude: tuple[str, ...] = (), include: tuple[str, ...] = ()) -> list[dict]:
    """Every single-start ``experiments.refine_report`` JSON below ``runs_root``
    (``<run>/diagnostics/refine_*.json``), filtered by its run's name as ``collect`` filters runs;
    each labelled ``<run>: <file stem>`` (``label``). Multi-rank correction-range reports have no
    checks and are left out."""
    root = Path(runs_root)
    found = []
    for f, r in _json_records(root, "diagnostics/refine_*.json", ("rows", "task")):
        run_dir = f.parent.parent
        label = run_label(run_dir, root, r["task"])
        if _kept(run_dir, label, exclude, include):
            found.append(dict(r, label=f"{label}: {f.stem.removeprefix('refine_')}"))
    return found


def refine_check_lines(reports: list[dict]) -> list[str]:
    """The refinement issue's checks, one row per saved refine_report (none: no section)."""
    if not reports:
        return []
    return ["## Refinement against the ground truth (no simulator)", "",
            "`experiments.refine_report`: median 3D end error of the plans for 100 training images (retrieval "
            "returns their own demonstration, the exact answer) and 100 test images. Checks: on training images "
            "the largest N ends no further off than N = 1 (refinement does not walk away from a correct answer), "
            "on test images no further than N = 0 (it improves on its retrieval); per image, how many end worse / "
            f"better by more than {10 * refine_report.TIE_CM:g} mm, with the exact sign test.", "",
            refine_report.format_checks_table(reports), ""]


def write_report(runs_root: str | Path, out: str | Path, exclude: tuple[str, ...] = (),
                 compare: tuple[str, ...] | str | None = (),
                 main: Callable[[list[dict], Path], list[str]] | None = None, include: tuple[str, ...] = (),
                 cost_suite: int | None = None) -> str:
    """The markdown report of every evaluation under ``runs_root`` (runs and sweeps filtered by
    ``exclude`` / ``include`` name patterns, see ``collect``); ``compare``: the rows to pair every
    other row with (one paired table each); ``main``: builds a section shown first, from the results
    and a chart path beside ``out`` (``readjax.lab.main_table.lines`` for the paper's main table);
    ``cost_suite``: the cost table of that suite's pipeline steps alone."""
    compare = (compare,) if isinstance(compare, str) else tuple(compare or ())
    results = collect(runs_root, exclude, include)
    found_sweeps = sweeps(runs_root, exclude, include)
    if not results and not found_sweeps:
        raise FileNotFoundError(f"no evaluation results or sweeps under {runs_root} (run experiments.evaluate "
                                f"or experiments.sweep first)")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    listed = [r for r in results if not r["_sweep_cell"]]
    by_protocol = {p: [r for r in listed if protocol(r) == p] for p in PROTOCOLS}
    chart = out.with_suffix(".png")
    if listed:
        success_chart(tables(by_protocol["main"] or listed), chart)
    seeds = sorted({(r["task"], min(r["seeds"]), max(r["seeds"]), len(r["seeds"])) for r in results if r.get("seeds")})
    lines = [
        "# Results", "",
        f"Every evaluation found under `{runs_root}` ({len(results)} result files), success rate in % over "
        "the fixed test episodes. Avg12/Avg16 appear only when all their tasks are present; otherwise "
        "`Avg` is the mean over the tasks present.", "",
    ]
    if main is not None:
        lines += main(listed, out.with_name(out.stem + "_main.png"))
    chart_shown = False
    for p, heading in PROTOCOLS.items():
        if by_protocol[p]:
            lines += [f"## {heading}", "", markdown_table(tables(by_protocol[p])), ""]
            if not chart_shown:  # the chart shows the first table (the main one when there is one)
                lines += [f"![success by task]({chart.name})", ""]
                chart_shown = True
    for reference in compare:
        lines += comparison_lines(listed, reference)
    lines += across_lines(by_protocol["main"])
    lines += start_lines(by_protocol["main"])
    for sw in found_sweeps:
        lines += [f"## Sweep: {sw['model']} on {sw['task']} ({sw['episodes']} episodes per cell)", "",
                  format_table7(sw), ""]
    lines += refine_check_lines(refine_reports(runs_root, exclude, include))
    lines += cost_lines(runs_root, {r["task"] for r in results} | {sw["task"] for sw in found_sweeps} if include else None,
                        cost_suite)
    lines += provenance_lines(results)
    lines += ["", "| task | test seeds | episodes |", "|---|---|---|"]
    lines += [f"| {t} | {a}..{b} | {n} |" for t, a, b, n in seeds]
    lines += ["", "Result files:", ""] + [f"- `{r['_file']}`" for r in results]
    text = "\n".join(lines) + "\n"
    out.write_text(text)
    return text
