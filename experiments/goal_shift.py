"""Does a READ-family planner read the goal from the image, and from how far? (no simulator)

Renders each test scene twice -- as generated, and with its goal object (RT's sphere, PB's button)
moved --SHIFT-CM in a random horizontal direction -- and plans on both from the same start: the
oracle's i-th nearest demonstration of the original ground truth (--rank; 1 is the best start,
500 Table 8's poor one). The plan's end should move with the goal: sensitivity 1. Prints, and writes
as JSON with a plot (default RUN/diagnostics/goal_shift_<cm>cm_ranks<...>.json):
  - sensitivity by start rank and by the start's distance from the goal in the image (px);
  - how far the move reaches into the denoiser's image features (change by pixel distance).
Read beside `refine_report --retrieval cheat --rank 1 10 50 200 500`: where refinement stops
correcting a start, does the plan still see the goal?

examples:
  python -m experiments.goal_shift --run runs/reach_target/read
  python -m experiments.goal_shift --run runs/push_button/read --rank 1 200 500 --shift-cm 2 --images 50
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    from readjax.lab.goal_shift import DEFAULT_RANKS

    p = argparse.ArgumentParser(prog="python -m experiments.goal_shift", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--run", required=True, help="a READ-family run folder (read, read_o, read_l) from experiments.train")
    p.add_argument("--data", default=None, help="dataset root (default: the one the run was trained on)")
    p.add_argument("--images", type=_cli.positive_int, default=100, help="test scenes (the split's first)")
    p.add_argument("--rank", type=_cli.positive_int, nargs="+", default=list(DEFAULT_RANKS),
                   help="starts: the oracle's RANK-th nearest demonstration of each scene's ground truth")
    p.add_argument("--shift-cm", type=float, default=4.0, help="how far the goal moves (cm, > 0)")
    p.add_argument("--N", type=_cli.positive_int, default=100, help="refinement steps (the run's rounds of them)")
    p.add_argument("--seed", type=int, default=0, help="the moves' directions and the planner's noise")
    p.add_argument("--batch-size", type=_cli.positive_int, default=50)
    p.add_argument("--out", default=None, help="JSON path (the plot beside it, .png)")
    p.add_argument("--quiet", action="store_true")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    if not args.shift_cm > 0:
        raise ValueError(f"--shift-cm must be > 0, got {args.shift_cm}")
    from readjax import tasks
    from readjax.lab import goal_shift
    from readjax.data import store
    from readjax.methods.base import read_run
    from readjax.planner import Planner

    spec = read_run(args.run)
    root = args.data or spec["data_root"]
    env = tasks.make(spec["task"])
    if env.goal(env.default_scene()) is None:
        raise ValueError(f"{spec['task']} defines no single goal object to move (the diagnostic needs "
                         f"TaskEnv.goal / move_goal: reach_target and push_button have them)")
    planner = Planner.load(args.run, data_root=root)
    if not planner.model.uses_retrieval or not planner.model.iterative:
        raise ValueError(f"{spec['method']} does not refine a retrieved start; the diagnostic is for "
                         "READ-family runs (read, read_o, read_l)")
    test = store.load_dataset(store.split_dir(root, spec["task"], "test"))
    test = test.subset(list(range(min(args.images, len(test)))))
    say = None if args.quiet else (lambda msg: print(f"  {msg}", flush=True))
    result = goal_shift.report(planner, env, test, ranks=tuple(args.rank), shift_m=args.shift_cm / 100,
                               n_steps=args.N, seed=args.seed, batch_size=args.batch_size, progress=say)
    result["run"] = str(args.run)
    ranks = "-".join(map(str, sorted(args.rank)))
    out = Path(args.out) if args.out else (Path(args.run) / "diagnostics" /
                                           f"goal_shift_{args.shift_cm:g}cm_N{args.N}_ranks{ranks}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result) + "\n")
    goal_shift.plot(result, out.with_suffix(".png"))
    print("\n".join(goal_shift.format_lines(result)))
    print(f"results in {out} (plot {out.with_suffix('.png')})")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
