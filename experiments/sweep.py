"""Sweep Table 7's hyper-parameters for one task and print the table in the paper's layout.

N (refinement steps) is test-time only and reuses a trained model; K, L (lambda) and T (theta1)
retrain (the autoencoder is shared). Finished cells are kept and skipped when re-run.
Writes OUT/<task>/<name>/sweep.json, table.md and sweep.png.

examples:
  python -m experiments.sweep --task reach_target --grid N=0,1,10,100 L=0.1,0.5,1.0
  python -m experiments.sweep --task PB --grid N=1,10,100 --episodes 50
  python -m experiments.sweep --task RT --grid N=0,1,10,100 --results results/   # committed, with paired tests vs A
"""

from __future__ import annotations

import argparse
import sys

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    from readjax import config, methods

    p = argparse.ArgumentParser(prog="python -m experiments.sweep", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--task", required=True)
    p.add_argument("--grid", nargs="+", required=True, metavar="KEY=v1,v2", help="N, K, L and/or T values")
    p.add_argument("--model", default="read", choices=methods.names())
    p.add_argument("--preset", default="cpu", choices=sorted(config.preset_names()))
    p.add_argument("--data", default="data")
    p.add_argument("--out", default="runs")
    p.add_argument("--name", default="sweep", help="sweep folder name under OUT/<task>/")
    p.add_argument("--episodes", type=_cli.positive_int, default=100)
    p.add_argument("--batch-size", type=_cli.positive_int, default=50)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="fixed config override")
    p.add_argument("--results", default=None,
                   help="also write sweep.json, table.md and sweep.png to RESULTS/<task>/<name>/ (small; commit them: "
                        "`experiments.report --runs RESULTS` shows the sweep)")
    p.add_argument("--quiet", action="store_true")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax.sweep import SweepConfig, format_table7, parse_grid, run_sweep

    cfg = SweepConfig(task=args.task, grid=parse_grid(args.grid), model=args.model, preset=args.preset,
                      data=args.data, out=args.out, name=args.name, episodes=args.episodes,
                      sets=tuple(args.set), batch_size=args.batch_size, results=args.results)
    result = run_sweep(cfg, progress=not args.quiet)
    print(format_table7(result))


if __name__ == "__main__":
    sys.exit(_cli.run(main))
