"""Replay a split's own recorded expert motions through exactly the evaluation path.

Loads DATA/<task>/<split>, checks that every stored scene renders to its stored image (the scene
guard evaluation runs), converts each recorded motion to world poses, solves IK, executes it in
MJX in the episode's stored scene and applies the task's predicate: the path a planner's motions
take in `experiments.evaluate`. The ground truth must succeed 100 %; anything less means an
evaluation on this split would not measure what it says. Prints the success rate, writes a JSON
(default DATA/<task>/<split>/verify.json) and exits with status 1 below --min. With --results DIR the
record is also kept as DIR/<task>/verify/<split>_<fingerprint>.json: one per version of the split
(its content hash), which the pipeline and `experiments.report` match to the evaluations that ran on it.

examples:
  python -m experiments.verify --task push_button --data data/
  python -m experiments.verify --task RT --data data/ --split train --episodes 50 --min 100
  python -m experiments.verify --task PB --data data/ --results results/   # commit results/push_button/verify/
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.verify", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    _cli.add_split_arguments(p)
    p.add_argument("--min", type=float, default=100.0, help="lowest acceptable success, percent")
    p.add_argument("--out", default=None, help="JSON path (default DATA/<task>/<split>/verify.json)")
    p.add_argument("--results", default=None,
                   help="also keep the record as RESULTS/<task>/verify/<split>_<fingerprint>.json (commit it)")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    if not 0.0 <= args.min <= 100.0:
        raise ValueError(f"--min is a percentage in [0, 100], got {args.min}")
    from readjax import tasks
    from readjax.lab import verification
    from readjax.data import store
    from readjax.evaluation import replay_ground_truth

    task = tasks.canonical_name(args.task)
    split_dir = store.split_dir(args.data, task, args.split)
    ds = store.load_dataset(split_dir, limit=args.episodes)
    result = replay_ground_truth(tasks.make(task), ds, batch_size=args.batch_size)
    result["data"] = str(split_dir)
    out = Path(args.out) if args.out else split_dir / "verify.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    if args.results:
        kept = verification.write(args.results, dict(result, data=str(split_dir)))
        out = f"{out} and {kept}"
    pct = 100.0 * result["success_rate"]
    print(f"{task} ({result['code']}) {args.split}: ground truth replayed {result['successes']}/{result['episodes']} "
          f"= {pct:.1f} %; results in {out}")
    if pct < args.min:
        print(f"FAIL: below --min {args.min:g} %; failed seeds {result['failed_seeds'][:20]}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(_cli.run(main))
