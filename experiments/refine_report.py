"""Diagnose READ's refinement against the dataset's own ground truth (no simulator).

Plans for the first --images training images (retrieval returns their own demonstration: the
exact answer) and test images at N = 0, 1, 10, 100, and prints the final-frame error against the
ground truth -- uv in pixels, depth in mm, 3D in cm, share within 3 cm -- plus, along the largest
N, the mean end-depth error of each step's M̂0 and each step's drift |M̂0(k+1) - M̂0(k)|.
A sound refinement keeps the training error near 0 as N grows and brings the test error below
N = 0's. Writes a JSON (default RUN/diagnostics/refine_<update>.json: not under eval/, which
holds success results only). The report ends with the refinement issue's two checks: on training
images the largest N's median 3D end error at most N = 1's, on test images at most N = 0's, each
also per image (worse / better by more than 0.1 mm, exact sign test). --summary prints those checks
for several saved reports side by side (one row per task or run).

examples:
  python -m experiments.refine_report --run runs/reach_target/read --data data/
  python -m experiments.refine_report --run runs/RT/read --refine cold --images 32 --N 0 1 10
  python -m experiments.refine_report --run runs/RT/read --out results/reach_target/read/refine_cold.json --refine cold
  python -m experiments.refine_report --run runs/RT/read --retrieval cheat --rank 500 --N 0 100  # Table 8's start
  python -m experiments.refine_report --run runs/RT/read --retrieval cheat --rank 1 10 50 200 500 --N 0 100
      # how far from the answer refinement can start: end error against start error, and the training pairs' range
  python -m experiments.refine_report --summary results/*/read_v3_5k_rep/diagnostics/refine_cold_anchor_rounds2.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import _cli
from readjax.config import REFINE_UPDATES


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.refine_report", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--run", default=None, help="a READ run folder from experiments.train")
    p.add_argument("--summary", nargs="+", default=None, metavar="JSON",
                   help="instead of --run: saved reports (this command's JSONs), their checks as one table")
    p.add_argument("--data", default=None, help="dataset root (default: the one the run was trained on)")
    p.add_argument("--images", type=_cli.positive_int, default=100, help="images per split")
    p.add_argument("--N", type=int, nargs="+", default=[0, 1, 10, 100], help="refinement steps to compare")
    p.add_argument("--refine", default=None, choices=REFINE_UPDATES,
                   help="refinement update (default: the run's sde.update)")
    p.add_argument("--retrieval", default="spe", choices=("spe", "cheat"),
                   help="where refinement starts: SPE retrieval (the planner's) or the oracle's nearest "
                        "neighbour of the ground truth (Tables 4-5: refinement from the best start)")
    p.add_argument("--rank", type=_cli.positive_int, nargs="+", default=[1],
                   help="with --retrieval cheat: start from the oracle's RANK-th nearest demonstration (1: the "
                        "best start, Tables 4-5; 500: a poor one, Table 8). Several ranks: each one's report, "
                        "then the correction range (readjax.lab.correction_range): every plan's end error against "
                        "its start's, binned, beside the distances READ's training pairs span, with a plot")
    p.add_argument("--rounds", type=_cli.positive_int, default=None,
                   help="refinements of N steps in a row, each from the previous one's plan (default: the "
                        "run's sde.rounds, 2 in the cpu preset)")
    p.add_argument("--batch-size", type=_cli.positive_int, default=50)
    p.add_argument("--out", default=None, help="JSON path")
    p.add_argument("--quiet", action="store_true")
    return p


def load_report(path) -> dict:
    """A saved report (a single-start JSON of this command), with a clear error for anything else."""
    return _cli.read_json_record(path, "rows", "refine_report JSON of one start (a correction-range report "
                                               "of several ranks has no checks)")


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    if (args.run is None) == (args.summary is None):
        raise ValueError("give either --run (diagnose a run) or --summary (tabulate saved reports), not both or neither")
    if args.summary:
        from readjax.lab import refine_report
        print(refine_report.format_checks_table([load_report(f) for f in args.summary]))
        return
    if any(n < 0 for n in args.N):
        raise ValueError(f"--N values must be >= 0, got {args.N}")
    from readjax.lab import refine_report
    from readjax.data import store
    from readjax.methods.base import read_run, train_size
    from readjax.planner import Planner

    if args.rank != [1] and args.retrieval != "cheat":
        raise ValueError(f"--rank {' '.join(map(str, args.rank))} needs --retrieval cheat (SPE's start has no rank)")
    if len(args.rank) > 1 and (0 not in args.N or len(args.N) < 2):
        raise ValueError("several --rank values compare N = 0 (the start) with a larger N: give --N 0 and one more")
    spec = read_run(args.run)
    root = args.data or spec["data_root"]
    planner = Planner.load(args.run, data_root=root)
    refine_report.require_read(planner)
    if args.refine:
        planner.model.set_refine_update(args.refine)
    test = store.load_dataset(store.split_dir(root, spec["task"], "test"))
    splits = {}
    for name, ds in (("train", planner.database), ("test", test.resized(planner.image_size))):
        n = min(args.images, len(ds))
        splits[name] = (ds.rgbd[:n], ds.motion[:n])
    say = None if args.quiet else (lambda msg: print(f"  {msg}", flush=True))
    reports = []
    for rank in args.rank:
        result = refine_report.report(planner, splits, ns=tuple(args.N), batch_size=args.batch_size, progress=say,
                                      retrieval=args.retrieval, rounds=args.rounds, rank=rank,
                                      clean_input=rank == args.rank[0])  # it does not depend on the start
        result.update(run=str(args.run), task=spec["task"], images=args.images)
        print(refine_report.format_report(result))
        reports.append(result)
    rounds = f"_rounds{result['rounds']}" if result["rounds"] > 1 else ""
    if len(reports) == 1:
        suffix = ("" if args.retrieval == "spe" else f"_{args.retrieval}" + (f"{args.rank[0]}" if args.rank[0] > 1 else ""))
        out = Path(args.out) if args.out else Path(args.run) / "diagnostics" / f"refine_{result['update']}{suffix}{rounds}.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2))
        print(f"results in {out}")
        return
    from readjax.lab import correction_range

    train = planner.model.configs["train"]  # the pairs it trained on: among the demos not held out
    pairs = correction_range.pair_distances(planner.camera, planner.database.motion, train.K,
                                            train_size(len(planner.database), train))
    combined = {"run": str(args.run), "task": spec["task"], "images": args.images, "update": result["update"],
                "rounds": result["rounds"], "split": "test", "reports": reports, "training_pairs": pairs,
                "by_rank": correction_range.by_rank(reports), "by_start": correction_range.by_start(reports)}
    ranks = "-".join(map(str, sorted(args.rank)))
    out = Path(args.out) if args.out else (Path(args.run) / "diagnostics" /
                                           f"correction_range_{result['update']}{rounds}_ranks{ranks}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(combined) + "\n")  # every report with each image's errors: compact
    correction_range.plot(reports, out.with_suffix(".png"), pairs=pairs)
    print("\n".join(correction_range.format_lines(combined)))
    print(f"results in {out} (plot {out.with_suffix('.png')})")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
