"""Collect every evaluation under a runs folder into the paper's tables (methods x tasks,
Avg12/Avg16 where present), a bar chart PNG, sweep tables, software versions and seeds.

Evaluations are grouped by protocol: the main methods x tasks table (with its bar chart), oracle
retrieval (cheat<i>_N<N>: Tables 4, 5, 8) and perturbed test images (Table 9).

examples:
  python -m experiments.report --runs runs/ --out docs/results.md
  python -m experiments.report --runs runs/ --exclude 'read_try*' --out docs/results.md
  python -m experiments.report --runs runs/ --compare 'read: spe_N100'   # paired tests vs that row
  python -m experiments.report --runs results/ --compare 'read: retrieval only (N=0)' deterministic
"""

from __future__ import annotations

import argparse
import sys

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.report", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--runs", default="runs", help="runs root to scan for */eval/*.json and sweep.json")
    p.add_argument("--out", default="docs/results.md", help="markdown output (the chart goes beside it)")
    p.add_argument("--exclude", nargs="*", default=[], metavar="PATTERN",
                   help="leave out runs whose folder name or table name (path below --runs without the task "
                        "folder, e.g. runs3/read) matches a glob pattern")
    p.add_argument("--compare", nargs="+", default=[], metavar="ROW",
                   help="add, for each ROW, a table of every row's difference to it (a method label of the "
                        "tables, e.g. 'read: spe_N100') on the same test episodes, with exact McNemar p-values")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax.report import write_report

    text = write_report(args.runs, args.out, tuple(args.exclude), tuple(args.compare))
    print(text.split("## Provenance")[0])
    print(f"wrote {args.out}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
