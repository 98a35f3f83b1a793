"""Render the task gallery: the first frames of every task for several episode seeds (one labelled
PNG grid, so a reader sees how far each task's placement varies) and a short video of an expert
demonstration per task (the first seed; MP4, or GIF with --gif).

examples:
  python -m experiments.gallery --out docs/                  # all tasks, grid + videos
  python -m experiments.gallery --out docs/ --no-video       # first frames only (seconds)
  python -m experiments.gallery --out /tmp/g --tasks RT PC --seeds 0 --size 256
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
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3],
                   help="episode seeds shown for every task (one column each; the video uses the first)")
    p.add_argument("--size", type=_cli.positive_int, default=160, help="image size in pixels")
    p.add_argument("--tasks-per-row", type=_cli.positive_int, default=2,
                   help="tasks side by side in the grid (columns = tasks-per-row x seeds)")
    p.add_argument("--no-video", action="store_true", help="only the first-frame grid and per-task PNGs")
    p.add_argument("--gif", action="store_true", help="write GIFs instead of MP4s")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    import numpy as np

    from readjax import tasks
    from PIL import Image

    from readjax.viz import expert_video, first_frames, label_grid, save_video

    names = list(tasks.names()) if args.tasks == ["all"] else [tasks.canonical_name(t) for t in args.tasks]
    out = Path(args.out)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    frames, labels = [], []
    for name in names:
        env = tasks.make(name)
        imgs = first_frames(env, args.seeds, args.size)
        Image.fromarray(imgs[0]).save(out / "frames" / f"{name}.png")
        frames.extend(imgs)
        labels.extend([f"{env.code} {name}" if i == 0 else f"{env.code} seed {s}"
                       for i, s in enumerate(args.seeds)])
        print(f"{name}: first frames of seeds {args.seeds} -> {out / 'frames' / (name + '.png')} (seed "
              f"{args.seeds[0]})", flush=True)
        if not args.no_video:
            video = expert_video(env, args.seeds[0], args.size)
            path = out / "videos" / f"{name}.{'gif' if args.gif else 'mp4'}"
            save_video(path, video, fps=25)
            print(f"{name}: expert demo ({len(video)} frames) -> {path}", flush=True)
    grid = label_grid(frames, labels, cols=args.tasks_per_row * len(args.seeds))
    Image.fromarray(np.asarray(grid)).save(out / "gallery.png")
    print(f"wrote {out / 'gallery.png'}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
