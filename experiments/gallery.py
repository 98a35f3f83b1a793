"""Render the task gallery: the first frame of every task (one labelled PNG grid) and a short
video of an expert demonstration per task (MP4, or GIF with --gif).

examples:
  python -m experiments.gallery --out docs/                  # all tasks, grid + videos
  python -m experiments.gallery --out docs/ --no-video       # first frames only (seconds)
  python -m experiments.gallery --out /tmp/g --tasks RT PC --size 256
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.gallery", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--out", default="docs", help="output folder")
    p.add_argument("--tasks", nargs="+", default=["all"], help="task names/codes, or 'all'")
    p.add_argument("--seed", type=int, default=0, help="episode seed shown for every task")
    p.add_argument("--size", type=_cli.positive_int, default=192, help="image size in pixels")
    p.add_argument("--no-video", action="store_true", help="only the first-frame grid and per-task PNGs")
    p.add_argument("--gif", action="store_true", help="write GIFs instead of MP4s")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    import numpy as np

    from readjax import tasks
    from readjax.viz import expert_video, first_frame, label_grid, save_video

    names = list(tasks.names()) if args.tasks == ["all"] else [tasks.canonical_name(t) for t in args.tasks]
    out = Path(args.out)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    frames, labels = [], []
    for name in names:
        env = tasks.make(name)
        img = first_frame(env, args.seed, args.size)
        from PIL import Image

        Image.fromarray(img).save(out / "frames" / f"{name}.png")
        frames.append(img)
        labels.append(f"{env.code}  {name}")
        print(f"{name}: first frame -> {out / 'frames' / (name + '.png')}", flush=True)
        if not args.no_video:
            video = expert_video(env, args.seed, args.size)
            path = out / "videos" / f"{name}.{'gif' if args.gif else 'mp4'}"
            save_video(path, video, fps=25)
            print(f"{name}: expert demo ({len(video)} frames) -> {path}", flush=True)
    grid = label_grid(frames, labels, cols=4)
    from PIL import Image

    Image.fromarray(np.asarray(grid)).save(out / "gallery.png")
    print(f"wrote {out / 'gallery.png'}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
