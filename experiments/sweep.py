"""Sweep Table 7's hyper-parameters for one task and print the table in the paper's layout.

N (refinement steps) is test-time only and reuses a trained model; K, L (lambda) and T (theta1)
retrain (the autoencoder is shared). Finished cells are kept and skipped when re-run.
Writes OUT/<task>/<name>/sweep.json, table.md and sweep.png. Each cell keeps its evaluation's failures by
mode and each episode's start (its retrieved motion's key-frame error): the table counts the episodes
solved from starts < 3 / 3-10 / > 10 cm beside the failures, so it says why a setting loses.

examples:
  python -m experiments.sweep --task reach_target --grid N=0,1,10,100 L=0.1,0.5,1.0
  python -m experiments.sweep --task PB --grid N=1,10,100 --episodes 50
  python -m experiments.sweep --task RT --grid N=0,1,10,100 --results results/   # committed, with paired tests vs A
  # Table 7: each key alone from A (A not retrained), the trainings on a Ray cluster
  python -m experiments.sweep --task PB --grid N=0,1,10,100 K=1,3,10 L=0.1,0.5,1.0 T=0.1,2.0,20.0 --vary one \\
      --reference-run runs/push_button/read --results results/ --ray-address 10.0.0.1:6379

The cells' trainings run on Ray (docs/cluster.md), each an `experiments.train` process (its output in
OUT/<task>/<name>/logs/), side by side as the machines allow: with no --ray-address (nor RAY_ADDRESS) an
embedded Ray on this machine, as many at once as it has cores; with one, the cluster's nodes (every node
must see --data and --out at the same paths, as this process does). This process evaluates each cell,
in the sweep's order, as soon as its training has finished, and writes the table after each cell.

A sweep is resumable across machines: with --results, a cell whose run is gone (a fresh machine) but
whose evaluations are committed there, on the same test episodes, is kept as committed; the others
train. Each cell records a digest of its autoencoder's training trace (vae_trace): cells with the same
trace decode with the same autoencoder.

Setting A is the preset's own (the paper preset: the paper's N = 100, K = 3, L = 0.5, T = 2.0; the cpu
preset trains on K = 50), with the --set overrides; every cell records the values it trained with.
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
    p.add_argument("--vary", choices=("all", "one"), default="all",
                   help="all: every combination of the grid's values; one: Table 7's layout, setting A and each "
                        "key varied alone from it (N at A's training only)")
    p.add_argument("--reference-run", default=None, metavar="RUN",
                   help="a finished run trained as setting A (same --preset, --set and data; checked): A's "
                        "cell evaluates it instead of training again, and takes the run's own evaluations of "
                        "the same episodes (the pipeline's, in RUN/eval/) where it has them")
    _cli.add_ray_arguments(p, "cell's training (KIND train)")
    p.add_argument("--other-split-versions", action="store_true",
                   help="with --results: also keep committed cells measured on the same test seeds but another "
                        "version of the split (generated on another CPU, whose float rounding moves the expert's "
                        "motions by ~1e-6 m; scenes and images are the same); the table marks those pairs. "
                        "Without it such cells are trained again")
    p.add_argument("--quiet", action="store_true")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax.lab.sweep import run_sweep
    from readjax.lab.sweep_grid import SweepConfig, parse_grid
    from readjax.lab.sweep_table import format_table7

    cfg = SweepConfig(task=args.task, grid=parse_grid(args.grid), model=args.model, preset=args.preset,
                      data=args.data, out=args.out, name=args.name, episodes=args.episodes,
                      sets=tuple(args.set), batch_size=args.batch_size, results=args.results,
                      reference_run=args.reference_run, vary=args.vary, ray_address=args.ray_address,
                      resources=tuple(args.resources),
                      other_split_versions=args.other_split_versions)
    result = run_sweep(cfg, progress=not args.quiet)
    print(format_table7(result))


if __name__ == "__main__":
    sys.exit(_cli.run(main))
