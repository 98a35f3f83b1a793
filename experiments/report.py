"""Collect every evaluation under a runs folder into the paper's tables (methods x tasks,
Avg12/Avg16 where present), a chart PNG (bars; a heat map beyond 8 rows), sweep tables, software versions and seeds.

Evaluations are grouped by protocol: the main methods x tasks table (with its chart), oracle
retrieval (cheat<i>_N<N>: Tables 4, 5, 8) and perturbed test images (Table 9).

examples:
  python -m experiments.report --runs runs/ --out docs/results.md
  python -m experiments.report --runs runs/ --exclude 'read_try*' --out docs/results.md
  python -m experiments.report --runs results/ --include read_v3_5k_rep '*_conv' table7 --out docs/baselines.md   # one grid's runs
  python -m experiments.report --runs runs/ --compare 'read: spe_N100'   # paired tests vs that row
  python -m experiments.report --runs results/ --compare 'read: retrieval only (N=0)' deterministic
  python -m experiments.report --runs results/ --main read_v3_5k deterministic_v3_5k   # the paper's main table
  python -m experiments.report --runs results/ --main read_s2,read_s2_seed1,read_s2_seed2 deterministic_s2,deterministic_s2_seed1,deterministic_s2_seed2   # over 3 trainings
  python -m experiments.report --runs results/ --claims read=read_v3_5k deterministic=deterministic_v3_5k
  python -m experiments.report --pages    # rebuild every generated page (docs/results.md, baselines.md, ...)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from experiments import _cli
from readjax.config import preset_names


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.report", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--runs", default="runs", help="runs root to scan for */eval/*.json and sweep.json")
    p.add_argument("--out", default="docs/results.md", help="markdown output (the chart goes beside it)")
    p.add_argument("--include", nargs="*", default=[], metavar="PATTERN",
                   help="only runs (and sweeps) whose folder name or table name matches one of these glob "
                        "patterns, e.g. a focused report of one grid's runs: --include read_v3_5k_rep '*_conv' table7")
    p.add_argument("--exclude", nargs="*", default=[], metavar="PATTERN",
                   help="leave out runs whose folder name or table name (path below --runs without the task "
                        "folder, e.g. runs3/read) matches a glob pattern")
    p.add_argument("--compare", nargs="+", default=[], metavar="ROW",
                   help="add, for each ROW, a table of every row's difference to it (a method label of the "
                        "tables, e.g. 'read: spe_N100') on the same test episodes, with exact McNemar p-values")
    p.add_argument("--main", nargs=2, default=None, metavar=("READ_RUNS", "DET_RUNS"),
                   help="open the report with the paper's main table: READ at N = 100 (with the --main-preset refinement) "
                        "and N = 0 from run READ_RUNS, Deterministic from run DET_RUNS, on every task that has "
                        "them, Avg12 / Avg16, the paper's READ beside them, and paired tests per task. Each of the "
                        "two may be a comma-separated list of runs, the trainings of one recipe with different "
                        "train.seed (e.g. read_s2,read_s2_seed1,read_s2_seed2): each cell is then the mean over the "
                        "trainings that have the task with their range (n=k where only k have it), Avg12 / Avg16 "
                        "the mean and range of each training's own average, every training's row below, and the "
                        "paired tests pooled over the trainings (READ's i-th against Deterministic's i-th, in "
                        "the lists' order; N = 100 against N = 0 of the same training); then the goals held "
                        "against the paper's READ (Avg12 / Avg16, READ above Deterministic, refinement above "
                        "retrieval), each met, missed or pending")
    p.add_argument("--paper-recipe", default=None, metavar="RUNS",
                   help="with --main: a row of READ trained with the paper's recipe (every cpu-preset departure "
                        "reverted; run(s) of the pipeline's --fixed-refinement, comma-separated for several "
                        "trainings), at N = 100 refined with its own config's update and rounds, chosen on nothing; "
                        "paired against READ's i-th training")
    p.add_argument("--claims", nargs="+", default=None, metavar="ROLE=RUN",
                   help="test the paper's claims (READ above each baseline, READ-O above READ-L, refinement above "
                        "retrieval, recovery from a poor retrieval, robustness to noise and brightness) with paired "
                        "tests, naming the run of each role: read, deterministic, vpsde, vpsde_cg, read_o, read_l, "
                        "read_o_em (READ-O trained with the other sampler, EM: Table 6) "
                        "(a role not named: the run of its own name), e.g. read=read_v3_5k")
    p.add_argument("--pages", action="store_true",
                   help="rebuild every generated page of the repository (docs/results.md, docs/baselines.md, "
                        "docs/difficulty.md, results/README.md) from results/, as committed; other options ignored")
    p.add_argument("--main-preset", default="cpu", choices=preset_names(),
                   help="READ's cells in --main and --claims are evaluations with this preset's refinement "
                        "(sde.update, sde.rounds)")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    if args.pages:
        from readjax.lab import pages

        for page in pages.regenerate("."):
            print(f"wrote {page}")
        return
    from readjax.lab import claims, grid_goals, main_table_seeds
    from readjax.lab.report import write_report

    if args.claims is not None and any("=" not in c for c in args.claims):
        raise ValueError(f"--claims takes ROLE=RUN pairs, got {args.claims}")
    roles = {**{role: role for role in claims.ROLES}, **dict(c.split("=", 1) for c in args.claims or ())}
    sections = []
    if args.paper_recipe and not args.main:
        raise ValueError("--paper-recipe is a row of the main table: give --main READ_RUNS DET_RUNS too")
    if args.main:
        read_run, det_run = args.main
        sections.append(lambda results, chart: main_table_seeds.section(results, read_run, det_run, chart,
                                                                preset_name=args.main_preset,
                                                                recipe_run=args.paper_recipe,
                                                                goals=grid_goals.lines))
    claims_plot = Path(args.out).with_name(Path(args.out).stem + "_claims.png")
    if args.claims is not None:
        sections.append(lambda results, chart: claims.lines(results, roles, preset_name=args.main_preset,
                                                            doc_dir=chart.parent, plot=claims_plot))

    def main_section(results, chart):  # the sections shown first: the main table, then the claims
        return [line for section in sections for line in section(results, chart)]

    text = write_report(args.runs, args.out, tuple(args.exclude), tuple(args.compare), include=tuple(args.include),
                        main=main_section if sections else None)
    print(text.split("## Provenance")[0])
    print(f"wrote {args.out}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
