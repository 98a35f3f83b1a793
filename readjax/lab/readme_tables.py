"""The README's result tables, generated: two blocks of README.md between markers, rebuilt from
results/ by ``experiments.report --pages`` (:func:`readjax.lab.pages.regenerate`) and checked for drift
by ``tests/test_pages.py``, like the pages under docs/.

* the main table, compact: READ at N = 100, its retrieval alone (N = 0), Deterministic and the paper's
  READ, Avg12 / Avg16 only, from the same selection as docs/results.md's main table
  (:mod:`readjax.lab.main_table`), with the spread over trainings where a row has several;
* the baselines: one row per method of docs/baselines.md's grid (the same runs and evaluations as
  its claims, :mod:`readjax.lab.claims`), per task and averaged over the tasks present.

Every row says which suite (version of the tasks) its results ran on.
"""

from __future__ import annotations

import re

import numpy as np

from readjax import tasks
from readjax.lab import claims, difficulty, grid_goals, main_table, main_table_seeds, paper
from readjax.lab.replicates import across_trainings
from readjax.lab.report import collect
from readjax.lab.result_record import eval_config_of
from readjax.tables import of_suite, row_label, success_table

END = "<!-- end generated -->"
MAIN_BLOCK = "<!-- generated: main table (python -m experiments.report --pages) -->"
BASELINES_BLOCK = "<!-- generated: baselines (python -m experiments.report --pages) -->"
# the baselines block's rows: role (as in claims.ROLES) -> the method's name
BASELINE_ROWS = {"deterministic": "Deterministic", "vpsde": "VPSDE", "vpsde_cg": "VPSDE+CG",
                 "read_o": "READ-O", "read_l": "READ-L", "read": "READ, N = 100"}


TEST_CHOSEN = ("READ's refinement in these rows (`cold_anchor` x 2 rounds, the cpu preset's) was chosen by comparing "
               "success on reach_target's test episodes (BENCHMARKS 8k-8l), not on a validation split as suite "
               "{current}'s is; they leave the README once suite {current}'s table has all 16 tasks.")


def _chosen_on_test(r: dict) -> bool:
    """Whether ``r`` is READ refined (N > 0) with a setting not chosen on a validation split."""
    return r.get("method") == "read" and eval_config_of(r)["N"] != 0 and r.get("chosen_on") != "val"


def _suite_results(results: list[dict], suite: int) -> list[dict]:
    return [r for r in of_suite(results, suite) if not r.get("_sweep_cell")]


def _suite_line(suite: int, results: list[dict]) -> str:
    """What the rows' suite is beside the current tasks, and whether any trained result of the current
    suite exists yet."""
    current = tasks.SUITE_VERSION
    if suite == current:
        return f"Suite {suite} is the current version of the tasks ([docs/tasks.md](docs/tasks.md))."
    n_current = sum(tasks.suite_of(r) == current for r in results)
    have = "no trained result of suite " + str(current) + " exists yet" if n_current == 0 else (
        f"{n_current} evaluations of suite {current} exist so far")
    return (f"Suite {suite} is an earlier, easier version of the 16 tasks; the tasks are now suite {current}, "
            f"placed as RLBench's task files place them ([docs/tasks.md](docs/tasks.md)), and {have}.")


def _episodes(cells) -> str:
    """``"100 test episodes each"`` (or a range) over the evaluations ``cells``."""
    n = sorted({len(r["success"]) for r in cells})
    return "no test episodes" if not n else f"{n[0]}{'' if len(n) == 1 else f'-{n[-1]}'} test episodes each"


def _spread(cell: dict, groups: list[dict]) -> str | None:
    """``"91 / 73 / 80 % over 3 trainings (mean 81.3, range 73-91)"`` where ``cell`` is one of several trainings of its recipe."""
    label = row_label(cell)
    for g in groups:
        if g["task"] == cell["task"] and label in g["rows"]:
            rates = " / ".join(f"{x:.0f}" for x in g["rates"])
            return f"{rates} % over {len(g['rates'])} trainings (mean {g['mean']:.1f}, range {g['min']:.0f}-{g['max']:.0f})"
    return None


def main_lines(results: list[dict], read_run: str, det_run: str, suite: int, preset_name: str = "cpu") -> list[str]:
    """The compact main table: Avg12 / Avg16 of READ (N = 100), retrieval only, Deterministic and the
    paper's READ, each row with its suite and runs, and a note on the suite and on trainings;
    comma-separated runs (several trainings per role): :func:`trainings_lines`."""
    mine = _suite_results(results, suite)
    if "," in read_run or "," in det_run:
        return trainings_lines(results, mine, main_table_seeds.split_runs(read_run),
                               main_table_seeds.split_runs(det_run), suite, preset_name)
    rows, _ = main_table.select(mine, read_run, det_run, main_table.refinement_of(preset_name))
    table = main_table.rates(rows)
    n_tasks = len(rows[main_table.READ_ROW])
    labels = {main_table.READ_ROW: ("READ, N = 100", f"`{read_run}`"),
              main_table.RETRIEVAL_ROW: ("READ, retrieval only (N = 0)", f"`{read_run}`"),
              main_table.DET_ROW: ("Deterministic", f"`{det_run}`")}

    def fmt(r: dict, c: str) -> str:
        return f"{r[c]:.1f}" if c in r else "–"

    cells = [r for by_task in rows.values() for r in by_task.values()]
    out = [f"| success % ({n_tasks} tasks, {_episodes(cells)}) | suite | Avg12 | Avg16 | run |",
           "|---|---|---|---|---|"]
    unverified = []
    for key, (name, run) in labels.items():
        mark = "‡" if any(not r.get("_verified", False) for r in rows[key].values()) else ""
        unverified += [name] if mark else []
        out.append(f"| {name} | {suite} | {fmt(table[key], 'Avg12')}{mark} | {fmt(table[key], 'Avg16')}{mark} | {run} |")
    p = table[paper.READ_LABEL]
    out += [f"| READ, the paper (Table 7, setting A) | the paper's | {fmt(p, 'Avg12')} | {fmt(p, 'Avg16')} | – |", ""]
    groups = across_trainings(mine)
    spreads: dict[str, list[str]] = {}
    for key, (name, _) in labels.items():
        for code in tasks.AVG16:
            cell = rows[key].get(tasks.canonical_name(code))
            s = _spread(cell, groups) if cell is not None else None
            if s:
                spreads.setdefault(code, []).append(f"{name} {s}")
    seeds = "The averages: one training per task" + "".join(
        f"; {code}'s rows, trained again with other seeds: " + ", ".join(parts) for code, parts in spreads.items()) + "."
    out += [_suite_line(suite, results) + " " + seeds
            + (" ‡ a test split with no 100 % ground-truth replay on record: " + ", ".join(unverified) + "."
               if unverified else "")
            + (" " + TEST_CHOSEN.format(current=tasks.SUITE_VERSION) if any(map(_chosen_on_test, cells)) else "")
            + " Per task, paired tests, failures by mode: [docs/results.md](docs/results.md)."]
    return out


def trainings_lines(results: list[dict], mine: list[dict], read_runs: list[str], det_runs: list[str], suite: int,
                    preset_name: str = "cpu", recipe_runs: list[str] = (), plan=None) -> list[str]:
    """The compact main table over several trainings per role (``mine``: the suite's results): each
    row's Avg12 / Avg16 as the mean and range over its trainings' own averages, as docs/results.md's;
    ``recipe_runs``: the paper's recipe, a row of its own. A training not measured yet is said so.
    Below it, the count of the goals against the paper's (:mod:`readjax.lab.grid_goals`, ``plan``: run ->
    the tasks it is planned on)."""
    refinement = main_table.refinement_of(preset_name)
    trainings, _ = main_table_seeds.select_trainings(mine, read_runs, det_runs, refinement, list(recipe_runs))
    means = main_table_seeds.summary(trainings, main_table_seeds.common_tasks(trainings))
    names = {main_table.READ_ROW: "READ, N = 100", main_table.RETRIEVAL_ROW: "READ, retrieval only (N = 0)",
             main_table.DET_ROW: "Deterministic", main_table_seeds.RECIPE_ROW: "READ, the paper's recipe (N = 100)"}
    cells = [r for runs in trainings.values() for _, by_task in runs for r in by_task.values()]
    n_tasks = len({t for _, by_task in trainings[main_table.READ_ROW] for t in by_task})
    any_row = len({r["task"] for r in cells})  # tasks with a cell in any row
    out = [f"| success % ({any_row} tasks, {_episodes(cells)}) | suite | Avg12 | Avg16 | runs |",
           "|---|---|---|---|---|"]
    unverified = []
    for row, runs in trainings.items():
        name = names[row]
        mark = "‡" if any(not r.get("_verified", False) for _, by_task in runs for r in by_task.values()) else ""
        unverified += [name] if mark else []
        avgs = [main_table_seeds.spread(*means[row][c], len(runs)) + mark if c in means[row] else "–"
                for c in ("Avg12", "Avg16")]
        out.append(f"| {name} | {suite} | {avgs[0]} | {avgs[1]} | " + ", ".join(f"`{r}`" for r, _ in runs) + " |")
    p = main_table.with_averages(dict(paper.READ_TABLE7_A), [])
    out += [f"| READ, the paper (Table 7, setting A) | the paper's | {p['Avg12']:.1f} | {p['Avg16']:.1f} | – |", ""]
    waiting = main_table_seeds.unmeasured(trainings)
    if n_tasks < len(tasks.AVG16) or waiting:
        out += [f"Still running: {n_tasks} of {len(tasks.AVG16)} tasks have a READ training measured at N = 100"
                + (", no evaluation yet of " + ", ".join(f"`{r}`" for r in waiting) if waiting else "")
                + "; Avg12 / Avg16 appear once a training has all their tasks.", ""]
    return out + [_suite_line(suite, results) + " The averages: the mean over a row's trainings (one per "
                  "`train.seed`) of each training's own average, their range in brackets, `n=k` where only k "
                  "trainings have every task of it; "
                  f"{main_table_seeds.TASK_MEANS}: where some trainings run on fewer tasks (other seeds), the mean "
                  "over the tasks of each task's mean over its trainings."
                  + (" ‡ a test split with no 100 % ground-truth replay on record: " + ", ".join(unverified) + "."
                     if unverified else "")
                  + " Per task, each training's row, paired tests pooled over trainings, failures by mode: "
                  "[docs/results.md](docs/results.md).", "", goals_line(trainings, plan)]


def goals_line(trainings, plan=None) -> str:
    """How many of the goals against the paper's READ are met, missed and pending, naming the met and
    missed ones."""
    rows = grid_goals.goals(trainings, plan)
    by = {v: [g["goal"].split(" (")[0] for g in rows if g["verdict"] == v] for v in ("met", "missed", "pending")}
    named = "; ".join(f"{v}: {', '.join(by[v])}" for v in ("met", "missed") if by[v])
    return (f"The goals against the paper's READ (Avg12 ≥ {grid_goals.AVG_GOALS['Avg12']:.0f}, Avg16 ≥ "
            f"{grid_goals.AVG_GOALS['Avg16']:.0f}, READ above Deterministic, refinement above retrieval on "
            f"{', '.join(grid_goals.REFINEMENT_TASKS)}): {len(by['met'])} met, {len(by['missed'])} missed, "
            f"{len(by['pending'])} pending until every training has its tasks" + (f" ({named})" if named else "")
            + "; each with its numbers in [docs/results.md](docs/results.md).")


def baselines_lines(results: list[dict], roles: dict[str, str], suite: int, preset_name: str = "cpu") -> list[str]:
    """The baselines and ablations grid: each method's success per task and its mean over the tasks
    present (as docs/baselines.md averages them), READ at N = 100 with the preset's refinement, the
    others as the claims pair them."""
    mine = sorted(_suite_results(results, suite), key=lambda r: r.get("_file", ""))
    refinement = main_table.refinement_of(preset_name)
    rows, cells, left_out = {}, [], []
    for role, name in BASELINE_ROWS.items():
        side = claims.Side(role, claims.TOP_N if role == "read" else None)
        picked: dict[str, dict] = {}
        for r in mine:
            if side.matches(r, roles, refinement):
                picked.setdefault(r["task"], r)
        if any(map(_chosen_on_test, picked.values())):
            left_out.append(f"{name} (`{roles[role]}`)")
            continue
        cells += picked.values()
        table = success_table({t: r["success_rate"] for t, r in picked.items()})
        if picked and "Avg" not in table:  # a row with every Avg12 task: its mean over the tasks present
            table["Avg"] = float(np.mean([v for c, v in table.items() if c in tasks.AVG16]))
        rows[f"{name} (`{roles[role]}`)"] = table
    cols = [c for c in tasks.AVG16 if any(c in r for r in rows.values())]
    out = ["| success % | suite | " + " | ".join(cols) + " | Avg |", "|---" * (len(cols) + 3) + "|"]
    for label, r in rows.items():
        out.append(f"| {label} | {suite} | " + " | ".join(f"{r[c]:.0f}" if c in r else "–" for c in cols)
                   + (f" | {r['Avg']:.1f} |" if "Avg" in r else " | – |"))
    gone = (f" {' and '.join(left_out)}: in docs/baselines.md only, as READ's refinement there was chosen by comparing "
            "success on reach_target's test episodes (BENCHMARKS 8k-8l)." if left_out else "")
    return out + ["", (f"One training per method, {_episodes(cells)}.{gone} How each trained, the paper's claims "
                       "tested on this grid, READ-O with the EM sampler, the oracle and perturbed-image protocols: "
                       "[docs/baselines.md](docs/baselines.md).")]


def splice(text: str, marker: str, lines: list[str]) -> str:
    """``text`` with the block after ``marker`` (up to the next END) replaced by ``lines``."""
    pattern = re.compile(re.escape(marker) + r"\n.*?" + re.escape(END), re.DOTALL)
    if not pattern.search(text):
        raise ValueError(f"README.md has no block {marker} ... {END}")
    return pattern.sub(lambda _: "\n".join([marker, *lines, END]), text, count=1)


def grid_lines(results: list[dict], grid: dict[str, tuple[str, ...]], suite: int, preset_name: str = "cpu",
               plan=None) -> list[str]:
    """The compact main table of a grid of trainings on ``suite`` (``grid``: ``read`` / ``deterministic`` /
    ``recipe`` -> run names, one per ``train.seed``), or nothing while no READ training of it is measured."""
    mine = _suite_results(results, suite)
    if not main_table_seeds.any_measured(mine, grid["read"]):
        return []
    return trainings_lines(results, mine, list(grid["read"]), list(grid["deterministic"]), suite, preset_name,
                           list(grid.get("recipe", ())), plan)


def grid_has_all_tasks(results: list[dict], grid: dict[str, tuple[str, ...]], suite: int,
                       preset_name: str = "cpu") -> bool:
    """Whether a READ training of ``grid`` has all 16 tasks measured at N = 100 on ``suite``: from then on
    the README shows that suite's table alone."""
    trainings, _ = main_table_seeds.select_trainings(_suite_results(results, suite), list(grid["read"]),
                                                     list(grid["deterministic"]), main_table.refinement_of(preset_name),
                                                     list(grid.get("recipe", ())))
    return any(len(by_task) == len(tasks.AVG16) for _, by_task in trainings[main_table.READ_ROW])


def readme(path, results_root: str, main_runs: tuple[str, str], baseline_roles: dict[str, str], suite: int,
           grid: dict[str, tuple[str, ...]] | None = None, grid_suite: int | None = None, grid_plan=None) -> str:
    """Rewrite the generated blocks of the README at ``path`` from ``results_root``; returns its text.
    ``grid`` (on ``grid_suite``): the current suite's trainings, its table first, ``main_runs``'s below it
    until a READ training of the grid has all 16 tasks (then in docs/results.md only); ``grid_plan``: run -> the
    tasks it is planned on, for the goals' count."""
    results = collect(results_root)
    roles = {**{r: r for r in claims.ROLES}, **baseline_roles}
    text = path.read_text()
    current = grid_lines(results, grid, grid_suite, plan=grid_plan) if grid else []
    comparable = difficulty.comparability_line(difficulty.load_records(results_root, grid_suite)) if current else ""
    current += ["", comparable] if comparable else []
    older = [] if grid and grid_has_all_tasks(results, grid, grid_suite) else main_lines(results, *main_runs, suite)
    text = splice(text, MAIN_BLOCK, current + ([""] if current and older else []) + older)
    text = splice(text, BASELINES_BLOCK, baselines_lines(results, roles, suite))
    path.write_text(text)
    return text
