"""The paper's main table over several trainings of each recipe: ``experiments.report --main
READ_RUNS DET_RUNS`` with comma-separated run names, one training per ``train.seed`` (e.g.
``read_s2,read_s2_seed1,read_s2_seed2``).

Each training's cells are chosen as :func:`readjax.lab.main_table.select` chooses one run's (the
setting chosen on the validation split first, the suite's test splits only, ‡ where a split has no
ground-truth replay on record). A cell of the mean table is the mean over the trainings that have the
task, their range, and how many they are where not all of the role's trainings have it; Avg12 / Avg16
are the mean (and range) over trainings of each training's own average, which a training has only
once it has every member task. Below it, every training's own row. The paired tests pool the
trainings: READ N = 100 against N = 0 of the same training, and READ's i-th training against
Deterministic's i-th (the lists' order), each pair on the same test episodes; one exact McNemar test
over the discordant episodes of all pairs.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from readjax import tasks
from readjax.lab import main_table as mt
from readjax.lab import paper
from readjax.lab import paired
from readjax.lab.result_record import is_eval
from readjax.tables import of_suite, success_chart, suite_note

ROWS = (mt.READ_ROW, mt.RETRIEVAL_ROW, mt.DET_ROW)
RECIPE_ROW = "READ, the paper's recipe (N=100)"  # --paper-recipe: refined with its own config, chosen on nothing
Trainings = dict[str, list[tuple[str, dict[str, dict]]]]  # row -> [(run, task -> result)], one per training


def split_runs(names: str) -> list[str]:
    """The run names of a comma-separated list (``--main``'s READ_RUNS / DET_RUNS)."""
    runs = [n.strip() for n in names.split(",")]
    if not all(runs):
        raise ValueError(f"--main: an empty run name in {names!r}")
    if len(set(runs)) < len(runs):
        raise ValueError(f"--main: a run named twice in {names!r}: each training counts once")
    return runs


def recipe_cells(results: list[dict], run: str) -> dict[str, dict]:
    """The ``run``'s READ evaluations at N = 100 on clean test images, SPE top-1, refined with the
    run's own config (``sde.update`` x ``sde.rounds``) and not with a choice: task -> the first by file."""
    cells: dict[str, dict] = {}
    for r in sorted(results, key=lambda r: r["_file"]):
        if r["_run_name"] == run and "chosen_on" not in r and is_eval(r, "read", 100):
            cells.setdefault(r["task"], r)
    return cells


def select_trainings(results: list[dict], read_runs: list[str], det_runs: list[str],
                     refinement: tuple[str, int], recipe_runs: list[str] = ()) -> tuple[Trainings, list[str]]:
    """Each training's cells, chosen by :func:`main_table.select` run by run (READ's trainings fill
    the READ and retrieval-only rows, Deterministic's the Deterministic row; ``recipe_runs`` the paper's
    recipe row, :func:`recipe_cells`), and its notes."""
    out: Trainings = {row: [] for row in ROWS}
    if recipe_runs:
        out[RECIPE_ROW] = [(run, recipe_cells(results, run)) for run in recipe_runs]
    notes: list[str] = []
    for run in read_runs:
        rows, run_notes = mt.select(results, run, None, refinement)
        out[mt.READ_ROW].append((run, rows[mt.READ_ROW]))
        out[mt.RETRIEVAL_ROW].append((run, rows[mt.RETRIEVAL_ROW]))
        notes += run_notes
    for run in det_runs:
        rows, run_notes = mt.select(results, None, run, refinement)
        out[mt.DET_ROW].append((run, rows[mt.DET_ROW]))
        notes += run_notes
    return out, notes


def any_measured(results: list[dict], read_runs) -> bool:
    """Whether any of a grid's READ trainings has a result in ``results``: until one has, a grid has no
    table to show."""
    return any(r["_run_name"] in read_runs for r in results)


def unmeasured(trainings: Trainings) -> list[str]:
    """The trainings (in the order named) with no evaluation in any row."""
    filled = {run for runs in trainings.values() for run, cells in runs if cells}
    named = [run for runs in trainings.values() for run, _ in runs]
    return [run for run in dict.fromkeys(named) if run not in filled]


def common_tasks(trainings: Trainings) -> list[str]:
    """The task codes every READ training measured so far was measured on at N = 100 (``Avg (k)``'s
    tasks; a training not measured yet does not empty it)."""
    have = [{tasks.code_of(t) for t in cells} for _, cells in trainings[mt.READ_ROW] if cells]
    return [c for c in tasks.AVG16 if have and all(c in h for h in have)]


def training_rates(cells: dict[str, dict], measured: list[str]) -> dict[str, float]:
    """One training's row: task code -> success %, with its own Avg12 / Avg16 / ``Avg (k)`` where it
    has every member task."""
    return mt.with_averages({tasks.code_of(t): 100.0 * r["success_rate"] for t, r in cells.items()}, measured)


TASK_MEANS = "§"  # an average over tasks of each task's mean, where some of the row's trainings lack a task


def summary(trainings: Trainings, measured: list[str]) -> dict[str, dict[str, tuple[float, float, float, int]]]:
    """Row -> column -> (mean, min, max, how many trainings have it) over the row's trainings. Where not
    every training of a row has every task of Avg12 / Avg16 but every task has one, that average is the
    mean over its tasks of each task's mean over the trainings that have it, with k = 0 (no range:
    :data:`TASK_MEANS`); where every training has them all, the two definitions agree."""
    out = {}
    for row, runs in trainings.items():
        tables = [training_rates(cells, measured) for _, cells in runs]
        cols = {c for t in tables for c in t}
        out[row] = {c: (float(np.mean(v)), min(v), max(v), len(v))
                    for c in cols for v in [[t[c] for t in tables if c in t]]}
        of_task_means = mt.with_averages({c: v[0] for c, v in out[row].items() if c in tasks.AVG16}, [])
        for name in ("Avg12", "Avg16"):
            partial = name not in out[row] or out[row][name][3] < len(runs)
            if partial and name in of_task_means:
                out[row][name] = (of_task_means[name], float("nan"), float("nan"), 0)
    return out


def spread(mean: float, lo: float, hi: float, k: int, total: int) -> str:
    """``84.3 (79-91)``: a mean over trainings, its range, and ``n=k`` where only k of ``total`` have it;
    ``84.3§`` for an average over tasks of the task means (k = 0, :func:`summary`)."""
    if k == 0:
        return f"{mean:.1f}{TASK_MEANS}"
    text = f"{mean:.1f}" + (f" ({lo:.0f}-{hi:.0f})" if k > 1 else "")
    return text + (f" n={k}" if k < total else "")


def pooled(pairs: list[tuple[str, dict, dict]], what: str, skipped: list[str]) -> str:
    """``+wins / -losses, p=..., k pairs``: one exact McNemar test over the discordant episodes of
    every pair (label, a, b) run on the same test episodes (:func:`paired.pooled`); a pair whose
    episodes differ is left out and said in ``skipped``."""
    *_, left_out, text = paired.pooled([(a, b) for _, a, b in pairs])
    for k in left_out:
        label, a, b = pairs[k]
        skipped.append(f"{label}, {what}: not the same test episodes (the seeds of `{a['_file']}` and "
                       f"`{b['_file']}` differ)")
    return text


def paired_lines(trainings: Trainings) -> list[str]:
    """The pooled paired tests per task (and, with a paper's-recipe row, READ's i-th training against
    the recipe's i-th), and the pairs left out."""
    reads, rets, dets = (trainings[row] for row in ROWS)
    recipe = trainings.get(RECIPE_ROW)
    out = ["Paired per task, pooled over trainings (exact McNemar on the discordant episodes of every pair on the "
           "same test episodes: READ N = 100 against N = 0 of the same training; READ's i-th training against "
           "Deterministic's i-th, in the order named; episodes only the first solves / only the second, two-sided p, "
           "how many pairs):", "",
           "| task | READ N=100 vs N=0 | READ N=100 vs Deterministic |"
           + (" READ N=100 vs the paper's recipe |" if recipe else ""), "|---|---|---|" + ("---|" if recipe else "")]
    skipped: list[str] = []
    for code in tasks.AVG16:
        task = tasks.canonical_name(code)
        if not any(task in cells for _, cells in reads):
            continue
        vs_retrieval = [(f"`{run}`", cells[task], ret[task]) for (run, cells), (_, ret) in zip(reads, rets)
                        if task in cells and task in ret]
        vs_det = [(f"`{run}` / `{det_run}`", cells[task], det[task]) for (run, cells), (det_run, det) in zip(reads, dets)
                  if task in cells and task in det]
        line = (f"| {code} | {pooled(vs_retrieval, f'{code} N=100 vs N=0', skipped)} | "
                f"{pooled(vs_det, f'{code} vs Deterministic', skipped)} |")
        if recipe:
            vs_recipe = [(f"`{run}` / `{other}`", cells[task], rec[task])
                         for (run, cells), (other, rec) in zip(reads, recipe) if task in cells and task in rec]
            line += f" {pooled(vs_recipe, f'{code} vs the paper' + chr(39) + 's recipe', skipped)} |"
        out.append(line)
    out.append("")
    unmatched = [f"`{run}`" for run, _ in (reads[len(dets):] if len(reads) > len(dets) else dets[len(reads):])]
    if unmatched:
        out += ["Not paired against the other role (no training at the same position in its list): "
                + ", ".join(unmatched) + ".", ""]
    if skipped:
        out += ["Pairs left out of the pooled tests:", ""] + [f"- {s}" for s in skipped] + [""]
    return out


def lines(results: list[dict], read_runs: list[str], det_runs: list[str], chart: Path | None, preset_name: str,
          refinement: tuple[str, int], suite: int, recipe_runs: list[str] = (), in_progress: bool = False,
          goals: Callable[[Trainings], list[str]] | None = None) -> list[str]:
    """The main table section over several trainings per role (markdown lines), ``results`` already
    of suite ``suite``; ``chart``: where to draw the means' bars; ``recipe_runs``: trainings of the
    paper's recipe, a row of their own. A training with no qualifying evaluation is an error, unless
    ``in_progress`` (a grid still running: it is listed as not measured yet); ``goals``: lines drawn from
    the trainings, placed after the paired tests (:func:`readjax.lab.grid_goals.lines`)."""
    trainings, notes = select_trainings(results, read_runs, det_runs, refinement, list(recipe_runs))
    rows = tuple(trainings)
    empty = unmeasured(trainings)
    if empty and not in_progress:
        raise ValueError(f"--main: no evaluation of run(s) {', '.join(repr(r) for r in empty)} "
                         f"qualifies (READ: SPE top-1, N = 0, or N = 100 with the {preset_name} preset's refinement "
                         f"{refinement[0]} x {refinement[1]} rounds; Deterministic: 'direct')")
    measured = common_tasks(trainings)
    means = summary(trainings, measured)
    paper_row = mt.with_averages(dict(paper.READ_TABLE7_A), measured)
    avg_cols = [c for c in ("Avg12", "Avg16") if c in paper_row or any(c in m for m in means.values())]
    avg_cols += [c for c in paper_row if c.startswith("Avg (")]
    cols = list(tasks.AVG16) + avg_cols
    total = {row: len(runs) for row, runs in trainings.items()}
    mean_label = {row: f"{row}: mean of {total[row]} trainings" if total[row] > 1 else f"{row}: `{runs[0][0]}`"
                  for row, runs in trainings.items()}
    unverified = {(row, run, tasks.code_of(t)) for row in rows for run, cells in trainings[row]
                  for t, r in cells.items() if not r.get("_verified", False)}
    marked = {(row, c) for row, _, c in unverified}
    position = {run: i for i, run in enumerate(read_runs + det_runs + list(recipe_runs))}
    order = lambda u: (rows.index(u[0]), position[u[1]], tasks.AVG16.index(u[2]))  # noqa: E731
    out = [f"## Main table (the paper's layout), suite {suite}", "", suite_note(suite), "",
           f"READ is each of the trainings {', '.join(f'`{r}`' for r in read_runs)} (one per `train.seed`) on each "
           f"task at N = 100, refined with the setting chosen on the task's validation split where one was chosen "
           f"(`results/<task>/<run>/choice.json`), else with the {preset_name} preset's (`sde.update={refinement[0]}`, "
           f"`sde.rounds={refinement[1]}`), on clean test images with SPE top-1 retrieval; retrieval only is the "
           f"same trainings at N = 0; Deterministic is the trainings {', '.join(f'`{r}`' for r in det_runs)}. "
           "A cell is the mean success % over the trainings that have the task (each over its test episodes), "
           "their range in brackets, and `n=k` where only k of the row's trainings have it; – = not measured yet. "
           "Avg12 / Avg16 are the mean (and range) over trainings of each training's own average, which a "
           "training has once all its tasks are measured; where some of a row's trainings will not have every "
           f"task (other seeds on fewer tasks), {TASK_MEANS} marks the mean over the tasks of each task's mean over "
           "the trainings that have it; `Avg (k)` the same over the k tasks every READ "
           "training has been measured on, the paper's row over the same tasks. Each training's own row: "
           "below." + (f" The paper's recipe: {', '.join(f'`{r}`' for r in recipe_runs)} at N = 100, refined with "
                       "its own config's update and rounds, chosen on nothing." if recipe_runs else ""), "",
           "| method | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for row in rows:
        m = means[row]
        out.append(f"| {mean_label[row]} | " + " | ".join(
            (spread(*m[c], total[row]) + ("‡" if (row, c) in marked else "")) if c in m else "–" for c in cols) + " |")
    out += [f"| {paper.READ_LABEL} | " + " | ".join(f"{paper_row[c]:.1f}" if c in paper_row else "–" for c in cols)
            + " |", ""]
    if empty:
        out += ["Still running: no evaluation of " + ", ".join(f"`{r}`" for r in empty) + " yet (a mean counts the "
                "trainings measured so far, `n=k`).", ""]
    out += ["Each training's row (success % over the task's test episodes):", "",
            "| training | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    labels: dict[str, dict[str, dict]] = {}
    for row in rows:
        for run, cells in trainings[row]:
            r = training_rates(cells, measured)
            labels[f"{row}: `{run}`"] = cells
            out.append(f"| {row}: `{run}` | " + " | ".join(
                (f"{r[c]:.1f}" + ("‡" if (row, run, c) in unverified else "")) if c in r else "–" for c in cols) + " |")
    out.append("")
    if unverified:
        out += ["‡ ran on a test split with no 100 % ground-truth replay on record (`results/<task>/verify/"
                "test_<fingerprint>.json`, written by `experiments.verify --results`): not a result until it has one: "
                + ", ".join(f"{row} `{run}` {c}" for row, run, c in sorted(unverified, key=order)) + ".", ""]
    else:
        out += ["Every cell ran on a test split whose own ground truth replayed at 100 % through the evaluation "
                "path (records: `results/<task>/verify/test_<fingerprint>.json`, matched by the split's content "
                "hash).", ""]
    if chart is not None:
        bars = {mean_label[row]: {c: v[0] for c, v in means[row].items()} for row in rows}
        success_chart({**bars, paper.READ_LABEL: paper_row}, chart)
        out += [f"![main table]({chart.name})", ""]
    out += paired_lines(trainings) + (goals(trainings) if goals else [])
    out += mt.failure_lines({lb: cells for lb, cells in labels.items() if not lb.startswith(mt.RETRIEVAL_ROW)})
    out += mt.training_lines(labels)
    first_run, first_cells = trainings[mt.READ_ROW][0]
    out += mt.media_lines(first_cells, chart.parent if chart is not None else None, whose=first_run)
    if notes:
        out += ["Cells more than one evaluation could fill:", ""] + [f"- {n}" for n in notes] + [""]
    return out


def section(results: list[dict], read_run: str, det_run: str, chart: Path | None = None, preset_name: str = "cpu",
            suite: int = tasks.SUITE_VERSION, recipe_run: str | None = None,
            goals: Callable[[Trainings], list[str]] | None = None) -> list[str]:
    """The main table section for ``experiments.report --main``: one run name per role
    (:func:`readjax.lab.main_table.lines`), or comma-separated names of several trainings per role (one
    per ``train.seed``), or a paper's-recipe row (``recipe_run``, comma-separated too): :func:`lines`.
    ``goals``: lines drawn from the trainings (:func:`readjax.lab.grid_goals.lines`), after the table."""
    refinement = mt.refinement_of(preset_name)
    if "," not in read_run and "," not in det_run and not recipe_run:
        out = mt.lines(results, read_run, det_run, chart, preset_name=preset_name, suite=suite)
        return out + (goals(select_trainings(of_suite(results, suite), [read_run], [det_run], refinement)[0])
                      if goals else [])
    return lines(of_suite(results, suite), split_runs(read_run), split_runs(det_run), chart, preset_name,
                 refinement, suite, split_runs(recipe_run) if recipe_run else [], goals=goals)