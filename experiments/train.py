"""Train a motion planner for one task: the motion autoencoder, then the diffusion model.

Both stages checkpoint with orbax and resume from their latest checkpoint when the same command
is run again (a killed run loses at most `ckpt_every` steps and repeats none). Metrics go to
RUN/<stage>/metrics.jsonl and a loss curve to RUN/<stage>/loss.png; RUN/run.json records the
configs, the dataset fingerprint and the software versions.

examples:
  python -m experiments.train --task reach_target --model read --preset cpu --data data/ --out runs/
  python -m experiments.train --task PB --preset cpu --set steps=500 --set L=1.0 --name read_L1
  python -m experiments.train --task RT --preset paper --stage read      # only the diffusion stage
  python -m experiments.train --task RT --model vpsde --set val_episodes=100 --set stop_patience=2000
  python -m experiments.train --task RT --name read_sf0 --set sde.self_feed=0 --vae-from runs/reach_target/read  # the paper's loss

The convergence rule (every method, every stage): with train.val_episodes > 0 the last demos of
the training split are held out and their loss is logged every train.val_every steps (val_loss in
metrics.jsonl and loss.png); with train.stop_patience > 0 a stage stops once that loss has not
improved by more than train.stop_min_delta (relative) over the last stop_patience steps, the step
counts being caps. RUN/<stage>/stop.json records when and why each stage stopped.

One training across processes (--distributed; docs/cluster.md, "Multi-host training"): run the
same command once per process, on one machine or several; each process trains on its own devices
and together they train one model on the global batch (train.batch / train.vae_batch, split over
every device). The processes find each other through --coordinator HOST:PORT (process 0's
machine), --num-processes and --process-id, or the environment variables JAX_COORDINATOR_ADDRESS,
JAX_NUM_PROCESSES and JAX_PROCESS_ID, or, under SLURM's srun, SLURM's own variables (nothing to
set). --out must be a folder every process sees; process 0 writes the records, orbax writes each
checkpoint once, and a killed training resumes from the same command.
  python -m experiments.train --task RT --distributed --coordinator 10.0.0.1:1234 --num-processes 2 --process-id 0
  srun --ntasks=4 python -m experiments.train --task RT --preset paper --distributed --out /shared/runs

config keys for --set: train.* (vae_steps, steps, batch, lr, K, augment, episodes, val_episodes,
stop_patience, ...), vae.*
(width, layers, kinematic, kl_weight, ...), denoiser.* (image_size, conv_dims, d_model, ...),
sde.* (lam, theta1); L and T are Table 7's lambda and theta1.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import traceback
from pathlib import Path

from experiments import _cli

def parser() -> argparse.ArgumentParser:
    from readjax import config, methods

    p = argparse.ArgumentParser(prog="python -m experiments.train", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--task", required=True, help="task name or paper code")
    p.add_argument("--model", default="read", choices=methods.names(), help="method to train")
    p.add_argument("--preset", default="cpu", choices=sorted(config.preset_names()),
                   help="cpu: minutes on 2 cores; paper: the paper's sizes (GPU)")
    p.add_argument("--data", default="data", help="dataset root (DATA/<task>/train from experiments.generate)")
    p.add_argument("--out", default="runs", help="runs root; the run goes to OUT/<task>/<name>")
    p.add_argument("--name", default=None, help="run name (default: the model name)")
    p.add_argument("--stage", default="all", help="which stage to train (all, or one of the method's stages, "
                   "e.g. vae / read for READ)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config field")
    p.add_argument("--vae-from", default=None, metavar="RUN",
                   help="start from RUN's finished autoencoder stage instead of training one (READ, READ-L; "
                        "refused unless RUN's was trained with this run's autoencoder config on the same data)")
    p.add_argument("--restart", action="store_true", help="delete an existing run of this name first")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    g = p.add_argument_group("one training across processes (jax.distributed)")
    g.add_argument("--distributed", action="store_true",
                   help="join a multi-process training (each process: the same command; see above)")
    g.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                   help="process 0's address and a free port; unset: $JAX_COORDINATOR_ADDRESS, or SLURM's")
    g.add_argument("--num-processes", type=_cli.positive_int, default=None, metavar="N",
                   help="how many processes train together; unset: $JAX_NUM_PROCESSES, or SLURM's")
    g.add_argument("--process-id", type=int, default=None, metavar="I",
                   help="this process's index, 0..N-1 (0 writes the records); unset: $JAX_PROCESS_ID, or SLURM's")
    return p


def main(argv=None) -> int | None:
    args = parser().parse_args(argv)
    if not args.distributed:
        if (args.coordinator, args.num_processes, args.process_id) != (None, None, None):
            raise ValueError("--coordinator, --num-processes and --process-id go with --distributed")
        return train(args)
    import jax

    from readjax import distributed

    rank, count = distributed.initialize(args.coordinator, args.num_processes, args.process_id)
    print(f"process {rank} of {count}: {jax.local_device_count()} of {jax.device_count()} devices", flush=True)
    try:
        rc = _cli.run(lambda _: train(args))
    except BaseException:
        traceback.print_exc()
        rc = 1
    if rc:  # leave at once: JAX's exit hook would wait minutes for the others at its shutdown barrier
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(rc)  # the others stop once the coordination service misses this process
    jax.distributed.shutdown()  # waits for every process (process 0 serves the others until then)
    return None


def train(args) -> None:
    from readjax import config, distributed, methods, stage_folder, tasks

    task = tasks.canonical_name(args.task)
    configs = config.override(config.presets(args.preset), args.set)
    run_dir = Path(args.out) / task / (args.name or args.model)
    if args.restart and run_dir.exists() and distributed.is_primary():
        shutil.rmtree(run_dir)
    distributed.barrier("restart")  # nobody reads the run before it is gone
    all_stages = methods.stages(args.model)
    if args.stage != "all" and args.stage not in all_stages:
        raise ValueError(f"{args.model} has stages {', '.join(all_stages)}; got --stage {args.stage}")
    stages = all_stages if args.stage == "all" else (args.stage,)
    shared = {}
    if args.vae_from:
        if "vae" not in all_stages:
            raise ValueError(f"--vae-from shares an autoencoder stage; {args.model} has none ({', '.join(all_stages)})")
        if not (Path(args.vae_from) / "vae").is_dir():
            raise ValueError(f"--vae-from {args.vae_from}: no autoencoder stage there ({args.vae_from}/vae)")
        shared["vae_from"] = args.vae_from
    if not distributed.is_primary():  # the others train and write nothing
        methods.module(args.model).train(task, args.data, run_dir, configs, args.preset, stages=stages,
                                         progress=False, **shared)
        return
    print(f"training {args.model} on {task} ({args.preset} preset) -> {run_dir}", flush=True)
    spec = methods.module(args.model).train(task, args.data, run_dir, configs, args.preset, stages=stages,
                                            progress=not args.quiet, **shared)
    summary = {"run": str(run_dir), "task": task, "episodes": spec["episodes"]}
    for stage in stages:
        rows = stage_folder.read_metrics(run_dir / stage)
        if rows:
            summary[f"{stage}_final_loss"] = round(rows[-1]["loss"], 5)
            summary[f"{stage}_steps"] = rows[-1]["step"]
        stop = stage_folder.read_stop(run_dir / stage)
        if stop is not None:
            summary[f"{stage}_stopped"] = stop["reason"]
    print(json.dumps(summary))


if __name__ == "__main__":
    sys.exit(_cli.run(main))
