"""Generate scripted expert demonstrations for a task with batched MJX rollouts.

Each demo is a seed: the scene is sampled, its first frame rendered (RGB-D), the expert's
waypoints executed in MJX (IK + physics), and the demo kept only if the task's success
condition held. Kept demos are resampled to 101 frames in the front-camera frame and stored in
data/<task>/<split>/ (HDF5 shards). Interrupted runs resume where they stopped.

examples:
  python -m experiments.generate --task reach_target --split train --episodes 200 --out data/
  python -m experiments.generate --task PC --split test --episodes 100
"""

from __future__ import annotations

import argparse
import json
import sys

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    from readjax import tasks

    p = argparse.ArgumentParser(prog="python -m experiments.generate", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    names = ", ".join(f"{n} ({c})" for n, c in tasks.codes().items())
    p.add_argument("--task", required=True, help=f"task name or paper code: {names}")
    p.add_argument("--split", default="train", choices=["train", "test", "val"],
                   help="train seeds start at 0, test seeds at 1,000,000, validation seeds at 2,000,000 "
                        "(disjoint, fixed); choose settings on val, report test")
    p.add_argument("--episodes", type=_cli.positive_int, default=200, help="successful demos to keep")
    p.add_argument("--out", default="data", help="dataset root; the split goes to OUT/<task>/<split>/")
    p.add_argument("--batch-size", type=_cli.positive_int, default=32,
                   help="episodes simulated together (vmapped, sharded over devices)")
    p.add_argument("--image-size", type=_cli.positive_int, default=128,
                   help="first-frame resolution (square); the paper uses 256")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax.data.generate import GenerateConfig, generate

    cfg = GenerateConfig(task=args.task, split=args.split, episodes=args.episodes, out=args.out,
                         batch_size=args.batch_size, image_size=args.image_size)
    summary = generate(cfg, progress=not args.quiet)
    keys = ("task", "split", "episodes_kept", "episodes_attempted", "expert_success_rate", "seconds")
    print(json.dumps({k: summary[k] for k in keys}))


if __name__ == "__main__":
    sys.exit(_cli.run(main))
