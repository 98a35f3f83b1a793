"""The quick demo (`make demo`): generate demonstrations for a task, render its first frames,
and print the dataset summary. Sized for a laptop CPU: a few minutes.

examples:
  python -m experiments.demo
  python -m experiments.demo --task PB --episodes 64 --out demo_runs
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.demo", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--task", default="reach_target", help="task name or paper code")
    p.add_argument("--episodes", type=_cli.positive_int, default=64, help="training demos to generate")
    p.add_argument("--image-size", type=_cli.positive_int, default=64)
    p.add_argument("--out", default="demo_runs", help="where data/ and the pictures go")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from PIL import Image

    from readjax import tasks
    from readjax.data.generate import GenerateConfig, generate
    from readjax.viz import first_frame, label_grid

    out = Path(args.out)
    task = tasks.canonical_name(args.task)
    print(f"[1/2] generating {args.episodes} expert demos of {task} (batched MJX rollouts)", flush=True)
    summary = generate(GenerateConfig(task=task, split="train", episodes=args.episodes, out=str(out / "data"),
                                      batch_size=16, image_size=args.image_size))
    print("[2/2] rendering the first frame of every task", flush=True)
    frames, labels = [], []
    for name in tasks.names():
        env = tasks.make(name)
        frames.append(first_frame(env, 0, 128))
        labels.append(f"{env.code} {name}")
    grid_path = out / "first_frames.png"
    label_grid(frames, labels).save(grid_path)
    keys = ("episodes_kept", "episodes_attempted", "expert_success_rate", "seconds")
    print(json.dumps({k: summary[k] for k in keys}, indent=2))
    print(f"dataset: {out / 'data' / task / 'train'}   first frames: {grid_path}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
