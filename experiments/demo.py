"""The quick demo (`make demo`): generate demonstrations, train a small READ, evaluate it on
fixed test episodes and print the success table — sized for a laptop CPU (~15-20 minutes).

Steps (each resumable; re-running skips what is done):
  1. expert demos for the task (batched MJX rollouts) + the fixed test episodes
  2. READ with the cpu preset: its 3000 autoencoder steps, 2000 of its 5000 denoiser steps (fewer
     and READ does not yet refine its retrieval: BENCHMARKS.md section 8e). 1000 demonstrations
     cost about a minute to generate and give retrieval (and the training pairs, K = 50
     neighbours) a dense database
  3. evaluation: plans executed in MJX, with and without refinement (N = 0), and the test
     split's own expert motions replayed through the same path (it must read 100 %: the check
     that the table measures what it says), success table, an overlay of the plans on the input
     images and a video of rollouts
  4. the first frame of every task, in one picture

examples:
  python -m experiments.demo
  python -m experiments.demo --task PB --episodes 200 --steps 1000 --out demo_runs
  python -m experiments.demo --set denoiser.layers=1 --set batch=16   # any experiments.train override
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from experiments import _cli

DEFAULT_EPISODES = 1000
DEFAULT_VAE_STEPS = 3000
DEFAULT_STEPS = 2000


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.demo", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--task", default="reach_target", help="task name or paper code")
    p.add_argument("--episodes", type=_cli.positive_int, default=DEFAULT_EPISODES,
                   help="training demos to generate")
    p.add_argument("--test-episodes", type=_cli.positive_int, default=50, help="test episodes to evaluate")
    p.add_argument("--vae-steps", type=_cli.positive_int, default=DEFAULT_VAE_STEPS,
                   help="training steps of the motion autoencoder")
    p.add_argument("--steps", type=_cli.positive_int, default=DEFAULT_STEPS, help="training steps of the denoiser")
    p.add_argument("--N", type=_cli.positive_int, default=10, help="refinement steps at test time")
    p.add_argument("--out", default="demo_runs", help="where data/, runs/ and the pictures go")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config field of the cpu preset, as in experiments.train")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax import config, evaluation, tables, tasks
    from readjax.data import store
    from readjax.data.generate import GenerateConfig, generate
    from readjax.methods import read
    from readjax.planner import Planner
    from readjax.viz import first_frame, label_grid

    out = Path(args.out)
    task = tasks.canonical_name(args.task)
    # overrides are checked before any work starts (a typo costs nothing)
    configs = config.override(config.presets("cpu"), [f"vae_steps={args.vae_steps}", f"steps={args.steps}",
                                                      *args.set])
    data = out / "data"
    print(f"[1/4] expert demos of {task}: {args.episodes} train + {args.test_episodes} test", flush=True)
    for split, n in (("train", args.episodes), ("test", args.test_episodes)):
        s = generate(GenerateConfig(task=task, split=split, episodes=n, out=str(data), batch_size=32, image_size=64))
        print(f"      {split}: kept {s['episodes_kept']}/{s['episodes_attempted']} "
              f"(expert success {100 * s['expert_success_rate']:.0f}%)", flush=True)
    print(f"[2/4] training READ (cpu preset, {args.vae_steps} autoencoder + {args.steps} denoiser steps)",
          flush=True)
    run_dir = out / "runs" / task / "read"
    read.train(task, data, run_dir, configs, "cpu")
    print(f"[3/4] evaluating on {args.test_episodes} fixed test episodes", flush=True)
    planner = Planner.load(run_dir)
    test = store.load_dataset(store.split_dir(data, task, "test"), limit=args.test_episodes)
    rows = {}
    for name, n, videos in ((f"READ (N={args.N})", args.N, 2), ("retrieval only (N=0)", 0, 0)):
        cfg = evaluation.EvalConfig(episodes=args.test_episodes, N=n, batch_size=min(args.test_episodes, 20),
                                    videos=videos)
        r = evaluation.evaluate(planner, test, cfg, out_dir=run_dir / "eval", name=f"demo_N{n}")
        rows[name] = r["table"]
    truth = evaluation.replay_ground_truth(planner.env, test)
    rows["expert motions replayed (must be 100)"] = tables.success_table({task: truth["success_rate"]})
    print("[4/4] rendering the first frame of every task", flush=True)
    frames, labels = [], []
    for name in tasks.names():
        env = tasks.make(name)
        frames.append(first_frame(env, 0, 128))
        labels.append(f"{env.code} {name}")
    label_grid(frames, labels).save(out / "first_frames.png")
    print()
    print(tables.format_table(rows))
    print(f"\nplans over the input images: {run_dir / 'eval' / f'demo_N{args.N}_overlay.png'}")
    print(f"rollout video: {run_dir / 'eval' / f'demo_N{args.N}_rollouts.mp4'}")
    print(f"loss curves: {run_dir / 'vae' / 'loss.png'}, {run_dir / 'read' / 'loss.png'}")
    print(f"first frames of all tasks: {out / 'first_frames.png'}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
