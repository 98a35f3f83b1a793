"""How precise must a plan be on a task? Replay a split's ground truth with a known error.

Every test episode's recorded expert motion is shifted (every waypoint moved by D cm in a direction
drawn from the episode's seed) or turned (every waypoint's orientation turned by A degrees about an
axis drawn from its seed), then executed through exactly the evaluation path in the episode's stored
scene. The success rate against D and against A is the task's tolerance: set it beside a planner's
key-frame errors (the `failures` record of experiments.evaluate) to see whether precision limits
the planner on that task. Writes a JSON and a plot (default DATA/<task>/<split>/tolerance.json).

examples:
  python -m experiments.tolerance --task WP --data data/
  python -m experiments.tolerance --task PC --data data/ --shift-cm 1 2 4 8 --turn-deg 5 10 20 40 \\
      --out results/pick_up_cup/tolerance.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.tolerance", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    _cli.add_split_arguments(p)
    p.add_argument("--shift-cm", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0],
                   help="shifts of every waypoint to replay, cm (0, the plain replay, is always included)")
    p.add_argument("--turn-deg", type=float, nargs="+", default=[2.5, 5.0, 10.0, 20.0],
                   help="turns of every waypoint's orientation to replay, degrees")
    p.add_argument("--out", default=None, help="JSON path (default DATA/<task>/<split>/tolerance.json); "
                                               "the plot goes beside it (.png)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    if any(d < 0 for d in args.shift_cm) or any(a < 0 for a in args.turn_deg):
        raise ValueError(f"--shift-cm and --turn-deg are magnitudes >= 0, got {args.shift_cm} and {args.turn_deg}")
    from tqdm import tqdm

    from readjax import provenance, tasks
    from readjax.lab import tolerance
    from readjax.data import store
    from readjax.data.guard import check_scene_images

    task = tasks.canonical_name(args.task)
    split_dir = store.split_dir(args.data, task, args.split)
    ds = store.load_dataset(split_dir, limit=args.episodes)
    env = tasks.make(task)
    check_scene_images(env, ds)  # the stored scenes are the ones the images show
    levels = [("shift_cm", 0.0)] + [("shift_cm", d) for d in sorted(set(args.shift_cm) - {0.0})] + \
             [("turn_deg", a) for a in sorted(set(args.turn_deg) - {0.0})]
    result = {"task": task, "code": tasks.code_of(task), "split": args.split, "episodes": len(ds),
              "seeds": ds.seeds.tolist(), "dataset_fingerprint": ds.fingerprint, "shift_cm": {}, "turn_deg": {}}
    t0 = time.time()
    for kind, x in tqdm(levels, desc=f"{task}: replays with a known error", disable=args.quiet, unit="replay"):
        ok = tolerance.replay(env, ds, shift_m=x / 100 if kind == "shift_cm" else 0.0,
                              turn_deg=x if kind == "turn_deg" else 0.0, batch_size=args.batch_size)
        result[kind][f"{x:g}"] = {"success_rate": float(ok.mean()), "success": ok.astype(int).tolist()}
    result["turn_deg"] = {"0": result["shift_cm"]["0"], **result["turn_deg"]}
    result.update(seconds=round(time.time() - t0, 1), commit=provenance.commit(), versions=provenance.versions(),
                  machine=provenance.machine())
    out = Path(args.out) if args.out else split_dir / "tolerance.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    tolerance.plot(result, out.with_suffix(".png"))
    print("\n".join(tolerance.curve_lines(result)))
    print(f"results in {out} and {out.with_suffix('.png')}")
    if result["shift_cm"]["0"]["success_rate"] < 1.0:
        print("WARNING: the plain replay is below 100 %: run experiments.verify; the curve does not measure "
              "tolerance", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(_cli.run(main))
