"""The generated pages: every table page under docs/ (and results/README.md, and the result tables of
README.md, :mod:`readjax.lab.readme_tables`) is built from results/ only, by one function here, so a page
cannot drift from what results/ says.

``regenerate(root)`` rebuilds each page under a repository root (``experiments.report --pages``);
``tests/test_pages.py`` rebuilds them in a copy of the repository and fails on any difference from the
committed text. Charts (PNG) are rebuilt beside them but not compared (their pixels depend on the
plotting library's version).
"""

from __future__ import annotations

import json
import os
from contextlib import contextmanager
from functools import partial
from pathlib import Path

from readjax import tasks
from readjax.lab import (claims, cost_table, difficulty, difficulty_why, grid_goals, main_table,
                         main_table_seeds, protocol_tables, readme_tables)
from readjax.lab.grid_plan import GRID, GRID_SUITE, GRID_TASKS  # the current suite's main table (issue 52)
from readjax.lab.report import write_report
from readjax.tables import of_suite, suite_mark, suite_note

RESULTS = "results"
# the runs each page reports (committed under results/<task>/<run>/)
MAIN_RUNS = ("read_v3_5k", "deterministic_v3_5k")  # the main table of suite 1
MAIN_SUITE = 1
MARK = suite_mark({"suite": MAIN_SUITE})  # how the tables' row labels mark the pages' suite (" [suite 1]")
BASELINE_ROLES = {"read": "read_v3_5k_rep", "deterministic": "deterministic_conv", "vpsde": "vpsde_conv",
                  "vpsde_cg": "vpsde_cg_conv", "read_o": "read_o_cd_conv", "read_l": "read_l_conv",
                  "read_o_em": "read_o_em_conv"}


@contextmanager
def _cwd(path: Path):
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def results_page() -> str:
    """docs/results.md: the main table (READ N = 100, retrieval only, Deterministic) and every result."""
    read_run, det_run = MAIN_RUNS
    out = Path("docs/results.md")
    roles = {**{r: r for r in claims.ROLES}, "read": read_run, "deterministic": det_run}

    def main(results, chart):
        return (grid_section(results, chart.with_name(chart.stem + f"_s{GRID_SUITE}.png"))
                + main_table.lines(results, read_run, det_run, chart, preset_name="cpu", suite=MAIN_SUITE)
                + claims.lines(results, roles, preset_name="cpu", doc_dir=out.parent,
                               plot=out.with_name(out.stem + "_claims.png"), suite=MAIN_SUITE))

    return write_report(RESULTS, out, main=main, compare=(f"{read_run}{MARK}: retrieval only (N=0)",
                                                           det_run + MARK), cost_suite=MAIN_SUITE)


def grid_section(results: list[dict], chart: Path) -> list[str]:
    """The current suite's main table over the grid's trainings (:data:`GRID`), what is measured so far."""
    mine = of_suite(results, GRID_SUITE)
    if not main_table_seeds.any_measured(mine, GRID["read"]):
        return [f"## Main table (the paper's layout), suite {GRID_SUITE}", "", suite_note(GRID_SUITE), "",
                "No READ training of the grid (" + ", ".join(f"`{r}`" for r in GRID["read"]) + ") has a test "
                "evaluation yet; `experiments.pipeline` runs it ([usage.md](usage.md)).", ""]
    refinement = main_table.refinement_of("cpu")
    return (main_table_seeds.lines(mine, list(GRID["read"]), list(GRID["deterministic"]), chart, "cpu", refinement,
                                   GRID_SUITE, list(GRID["recipe"]), in_progress=True,
                                   goals=partial(grid_goals.lines, plan=GRID_TASKS))
            + [line for run in GRID["read"] for line in protocol_tables.lines(mine, run, refinement)]
            + [line for run in GRID["recipe"]
               for line in protocol_tables.lines(mine, run, main_table.refinement_of("paper"))]
            + cost_table.grid_cost_lines(RESULTS, [run for runs in GRID.values() for run in runs], GRID_SUITE))


def baselines_page() -> str:
    """docs/baselines.md: the baselines and ablations grid and the paper's claims tested on it."""
    out = Path("docs/baselines.md")
    plot = out.with_name(out.stem + "_claims.png")
    roles = {**{r: r for r in claims.ROLES}, **BASELINE_ROLES}
    return write_report(RESULTS, out, include=(BASELINE_ROLES["read"], "*_conv", "read_kin", "table7"),
                        cost_suite=MAIN_SUITE, compare=(f"{BASELINE_ROLES['read']}{MARK}: retrieval only (N=0)",),
                        main=lambda results, chart: claims.lines(results, roles, preset_name="cpu",
                                                                 doc_dir=out.parent, plot=plot, suite=MAIN_SUITE))


def difficulty_page() -> str:
    """docs/difficulty.md: the oracle rows (Table 5's Cheat) of the current suite beside the paper's."""
    records = difficulty.load_records(RESULTS)
    text = "\n".join([
        "# How hard the tasks are: the paper's oracle rows", "",
        f"Suite {tasks.SUITE_VERSION} ({tasks.SUITES[tasks.SUITE_VERSION]}).", "",
        "For every test episode, the i-th nearest training demonstration to its ground-truth motion is executed "
        "in the episode's scene through the evaluation path, without refinement (the paper's Table 5, "
        "\"Cheat (i)\"); no trained model is involved. Ours: 1000 training demonstrations, 100 test episodes "
        "per task, each test split's ground truth replayed through the same path (at 100 % except where marked ‡). Built by `python -m experiments.difficulty "
        "--tasks all` from `results/<task>/difficulty/`.", "",
        difficulty.table(records), "",
        "## Why: where the copies land against what the task tolerates", "",
        "A copy succeeds when its key frames (where the gripper opens or closes, and the end) land within what "
        "the task tolerates. Per task: the i = 1 copies' worst key-frame error against the ground truth "
        "(median; position, rotation), success against that error pooled over i = 1, 3 and 10 (copies in each "
        "bin in brackets), and how the i = 1 copies failed (`readjax.failure_modes`). A task easier than the "
        "paper's row has its copies inside its tolerance; the audit ([tasks.md](tasks.md)) says which of "
        "placement or sizes differs from RLBench's.", "",
        difficulty_why.table(records), "",
        "## How the splits were generated", "",
        "A seed is kept when its placement is valid (RLBench's rejection: the task fits the workspace and the "
        "expert's path is reachable, at most 40 placements per seed) and the scripted expert succeeds "
        "(RLBench's rule: an unsuccessful demo is not a demo). The test split's recorded motions are replayed "
        "through the evaluation path (`experiments.verify`).", "",
        difficulty.generation_table(records, RESULTS), ""])
    Path("docs/difficulty.md").write_text(text)
    return text


def results_readme() -> str:
    """results/README.md: what the folder holds, with the counts read from it."""
    root = Path(RESULTS)
    evals = sorted(root.glob("*/*/eval/*.json"))
    suites: dict[int, int] = {}
    for f in evals:
        try:
            suite = tasks.suite_of(json.loads(f.read_text()))
        except json.JSONDecodeError:
            continue
        suites[suite] = suites.get(suite, 0) + 1
    verify = sorted(root.glob("*/verify/*.json"))
    diff = sorted(root.glob("*/difficulty/*.json"))
    by_suite = ", ".join(f"{n} of suite {s}" for s, n in sorted(suites.items()))
    text = "\n".join([
        "# results/", "",
        "Small JSONs that outlive a machine (datasets and checkpoints stay out of git). This page is generated "
        "(`python -m experiments.report --pages`); the counts are read from the folder.", "",
        f"- `<task>/<run>/eval/<name>.json` ({len(evals)} files: {by_suite}): one evaluation "
        "(`experiments.evaluate` or the pipeline) with per-episode success, seeds, configs, versions, machine and "
        "the suite version of its test split (a file without one is suite 1).",
        f"- `<task>/verify/<split>_<fingerprint>.json` ({len(verify)} files): a split's recorded expert motions "
        "replayed through the evaluation path (`experiments.verify --results results/`), one per version of the "
        "split; a number counts only on a split with a 100 % record here.",
        f"- `<task>/difficulty/<fingerprint>.json` ({len(diff)} files): the oracle rows of a test split "
        "(`experiments.difficulty`).",
        "- `<task>/<run>/training/`: each training stage's stop record and loss curve.",
        "- `<task>/<run>/media/`: READ's first test episodes rendered (overlay and rollout video).",
        "- `<task>/<run>/diagnostics/`: refinement against the ground truth (`experiments.refine_report`), "
        "correction range and goal shift.",
        "- `<task>/table7/`, `<task>/sweep*/`: sweeps (`experiments.sweep`).",
        "- `<task>/pipeline_timing.json`: each grid step's wall clock and CPU time (the cost tables).", "",
        "The tables built from these files: [docs/results.md](../docs/results.md), "
        "[docs/baselines.md](../docs/baselines.md), [docs/difficulty.md](../docs/difficulty.md).", ""])
    (root / "README.md").write_text(text)
    return text


def readme_page() -> str:
    """README.md's generated blocks (the compact main table, the baselines); the rest of it is written by hand."""
    return readme_tables.readme(Path("README.md"), RESULTS, MAIN_RUNS, BASELINE_ROLES, MAIN_SUITE, GRID, GRID_SUITE,
                                GRID_TASKS)


PAGES = {
    "README.md": readme_page,
    "docs/results.md": results_page,
    "docs/baselines.md": baselines_page,
    "docs/difficulty.md": difficulty_page,
    "results/README.md": results_readme,
}


def regenerate(root: str | Path = ".", only=None) -> dict[str, str]:
    """Rebuild the generated pages under the repository ``root`` from its results/; returns
    {page: text}."""
    out = {}
    with _cwd(Path(root)):
        for page, build in PAGES.items():
            if only is None or page in only:
                out[page] = build()
    return out
