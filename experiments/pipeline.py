"""Run a grid of tasks x methods end to end, resumably: generate, verify, train, evaluate.

For each task (in the paper's order), each step runs only if its output is missing:
  1. generate the test split (--test-episodes) and replay its ground truth through the evaluation
     path (experiments.verify): anything below 100 % stops that task -- its numbers would not count;
  2. generate the training split (--train-episodes, the paper's 1000 by default);
  3. train each method (--preset), then evaluate it on the test split: READ at each --read-N,
     the others once;
  4. copy the evaluation JSONs to RESULTS/<task>/<method>/eval/ (commit them; build tables with
     `python -m experiments.report --runs results/`);
  5. render READ's first --media-episodes test episodes at its largest N (motion overlay + rollout
     video, RESULTS/<task>/<run>/media/), checking their outcomes equal the full evaluation's;
  6. where READ scores below --diagnose-below %, evaluate it from the oracle's start too (cheat1_N<N>):
     the evidence of whether retrieval or refinement limits the task;
  7. --protocols: READ's evaluations for the paper's other tables (oracle retrieval, poor retrieval,
     perturbed images).
With --val-episodes N > 0 (default 100) READ's refinement setting is chosen on a validation split, never
on the test episodes: the val split (seeds from 2,000,000) is generated and its ground truth replayed at
100 % (RESULTS/<task>/verify/val_<fingerprint>.json); each READ run (and READ variant) is evaluated on it at
its largest --read-N once per setting of the choice grid (--choice-rounds x --choice-refine x
--choice-candidates; records in RUN/val/ and RESULTS/<task>/<run>/val/, which no table reads); the
setting with the highest val success (ties: the one closest to the paper's rounds 1, renoise,
candidates 1) is written to RESULTS/<task>/<run>/choice.json (experiments.choose); and every test
evaluation of that run that refines (N > 0: steps 3, 5, 6, 7) takes it (experiments.evaluate --choice),
its record saying so ("chosen_on": "val"). A choice on record over the same settings, N and val episodes,
on a val split whose replay is on record, is not made again. --val-episodes 0: no validation split, READ
refined with its preset's setting (how the committed grids were evaluated).
--variant trains a method with its own config overrides in its own run folder (READ-O's two samplers,
READ with the kinematics-aware autoencoder): a row of its own.
The steps run on Ray (docs/cluster.md): with no --ray-address (nor RAY_ADDRESS) an embedded Ray on this
machine runs as many at once as it has cores; --ray-address joins a cluster started with `ray start`,
where each step is a task on whichever node has what it asks (--resources: a CPU each, a share of a GPU
for a training where the cluster has GPUs, memory), started once the steps it needs have finished (a
task's data and replay before its trainings, a training before its evaluations) and a CPU is free, in the
grid's order (one task's steps before the next task's). The same
command gives the same results/ either way. On a cluster every node must see --data, --runs and
--results (and the folder the command is started from) at the same paths: a shared folder (NFS, a
mounted bucket). Each step's output goes to RUNS/pipeline_logs/<task>/<step>.log (which node ran it
heads each run), a line per finished step says where it ran with the elapsed time and an ETA, and every
10 minutes a line says what is under way and how far it has got (a training: its stages' steps). A
step whose worker or node is lost is run again by Ray elsewhere (resuming what it left); a step that
fails fails the steps that need it, the others run on, and the grid ends naming every failure.
A kill loses at most the steps in progress; running the same command again skips what is done. A job with a
wall-clock limit gives it as --deadline: no step starts that would, with the steps that need it, end after it. An
evaluation counts as done when RESULTS holds it on a test split whose replay is on record
(RESULTS/<task>/verify/), so a fresh machine with only the committed results/ regenerates, verifies and
trains only what an unfinished evaluation needs.

A run name whose evaluations in RESULTS were trained with another recipe (preset, --set, --variant)
is refused before any work: name the grid's runs apart with --run-name.

examples:
  python -m experiments.pipeline --tasks all --run-name read=read_v3_5k --run-name deterministic=deterministic_v3_5k
  cd /shared/readjax && python -m experiments.pipeline --tasks all --ray-address 10.0.0.1:6379   # a cluster
      # (`ray start --head` on 10.0.0.1, `ray start --address 10.0.0.1:6379` on each node; /shared on every node)
  python -m experiments.pipeline --tasks RT PB --resources train:num_gpus=0.25,memory=6   # 4 trainings a GPU
  python -m experiments.pipeline --tasks RT --methods read --read-N 0 10 100 --results my_results --dry-run
  python -m experiments.pipeline --tasks RT PB PC CB --methods read deterministic vpsde vpsde_cg read_l \
      --variant read_o_cd read_o read_o.sampler=cd --variant read_o_em read_o \
      read_o.sampler=em --protocols oracle poor perturbed --read-N 0 1 10 100 \
      --run-name read=read_v3_5k --run-name deterministic=deterministic_v3_5k
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    from readjax import methods
    from readjax.config import REFINE_UPDATES, preset_names
    from readjax.lab.pipeline_config import PROTOCOL_EVALUATIONS, PipelineConfig

    p = argparse.ArgumentParser(prog="python -m experiments.pipeline", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--tasks", nargs="+", required=True, help="task names or codes, or 'all' (the 16)")
    p.add_argument("--methods", nargs="+", default=["read", "deterministic"], choices=methods.names(),
                   help="methods, in the order they run (each --variant runs after them)")
    p.add_argument("--variant", nargs="+", action="append", default=[], metavar="ARG",
                   help="LABEL METHOD [KEY=VALUE ...]: METHOD trained with these config overrides (after --set) "
                        "in its own run folder LABEL, then evaluated as METHOD is: a row of its own, e.g. "
                        "--variant read_o_em read_o read_o.sampler=em --variant read_kin read vae.kinematic=true")
    p.add_argument("--preset", default="cpu", choices=preset_names())
    p.add_argument("--data", default="data", help="dataset root")
    p.add_argument("--runs", default="runs", help="runs root")
    p.add_argument("--results", default="results", help="where evaluation JSONs are mirrored (commit them)")
    p.add_argument("--train-episodes", type=_cli.positive_int, default=1000)
    p.add_argument("--test-episodes", type=_cli.positive_int, default=100)
    p.add_argument("--val-episodes", type=int, default=PipelineConfig.val_episodes,
                   help="validation episodes (DATA/<task>/val, seeds from 2,000,000) on which each READ run's "
                        "refinement setting is chosen before its test evaluations use it; 0: no validation, READ "
                        "refines with its preset's setting. Not the training's held-out demos (--set "
                        "train.val_episodes)")
    p.add_argument("--choice-rounds", nargs="+", default=["1", "preset"], metavar="R",
                   help="the choice grid's --rounds values: positive integers, or 'preset' (the run's sde.rounds)")
    p.add_argument("--choice-refine", nargs="+", default=["renoise", "preset"], choices=REFINE_UPDATES + ("preset",),
                   metavar="UPDATE",
                   help=f"the choice grid's --refine values: {', '.join(REFINE_UPDATES)}, or 'preset' (the run's "
                        f"sde.update)")
    p.add_argument("--choice-candidates", nargs="+", type=_cli.positive_int, default=[1], metavar="C",
                   help="the choice grid's --candidates values (SPE's top C refined; 1: the paper's top-1)")
    p.add_argument("--fixed-refinement", nargs="+", default=[], metavar="LABEL",
                   help="READ runs (a method's name or a --variant's label) that refine with their own config's "
                        "setting, chosen on nothing: a recipe reported as it is, e.g. the paper's row "
                        "(--variant read_paper read sde.update=renoise sde.rounds=1 ... --fixed-refinement read_paper)")
    p.add_argument("--image-size", type=_cli.positive_int, default=64)
    p.add_argument("--gen-batch", type=_cli.positive_int, default=32, help="episodes simulated together")
    p.add_argument("--read-N", type=int, nargs="+", default=[0, 100], help="READ's refinement steps to evaluate")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override for training")
    p.add_argument("--run-name", action="append", default=[], metavar="METHOD=NAME",
                   help="the run folder of a method on every task (default: the method's name), e.g. "
                        "read=read_v3_5k to keep a recipe's runs apart from older ones")
    p.add_argument("--media-episodes", type=int, default=8,
                   help="READ's first k test episodes rendered at its largest --read-N: a motion overlay and a "
                        "rollout video in RESULTS/<task>/<run>/media/ (0: none)")
    p.add_argument("--diagnose-below", type=float, default=80.0,
                   help="where READ at its largest --read-N succeeds on fewer than this %% of the test episodes, "
                        "evaluate it again at each --read-N from the oracle's start (the episode's own "
                        "demonstration): retrieval or refinement, which one limits the task (0: never)")
    p.add_argument("--protocols", nargs="+", default=[], choices=sorted(PROTOCOL_EVALUATIONS),
                   metavar="PROTOCOL",
                   help="READ's evaluations beyond the main table: "
                        + "; ".join(f"{k}: {v}" for k, v in PROTOCOL_EVALUATIONS.items()))
    p.add_argument("--protocol-runs", nargs="+", default=[], metavar="LABEL",
                   help="READ variants (--variant labels) evaluated under --protocols too, beside READ itself, e.g. "
                        "the paper's recipe from a poor start (--protocols poor --protocol-runs read_paper)")
    p.add_argument("--noise", type=float, default=PipelineConfig.noise,
                   help="the perturbed protocol's Gaussian noise std on the test RGB in [0, 1] (the paper does not "
                        "state its level)")
    p.add_argument("--brightness", type=float, default=PipelineConfig.brightness,
                   help="the perturbed protocol's brightness factor on the test RGB")
    _cli.add_ray_arguments(p, "step")
    p.add_argument("--deadline", default=None, metavar="WHEN",
                   help="a wall-clock limit (a SLURM --time, a lent machine): start a step only where it and the "
                        "steps that need it (shared among the steps run at once) are expected to end before it, "
                        "priced as --dry-run prices them; the grid ends when the rest is done, naming how many "
                        "were left, and a re-run goes on. WHEN: +DURATION (+90m, "
                        "+3h), HH:MM (its next occurrence, local time) or an ISO date and time (2026-12-07T23:40)")
    p.add_argument("--dry-run", action="store_true",
                   help="list the steps, each done / skip (not needed) / todo, a todo step with its expected "
                        "time (from the timing records under --results) and a training under way with how far "
                        "it has got, then the work left in all; run nothing (and start no Ray)")
    return p


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def dry_run(steps, prior, results) -> None:
    """List the steps, each done / skip / todo; a todo step with its expected time (a training under
    way: its own pace to its cap; else the timing records under ``results``: the same step on another
    task or run, else the mean of its kind) and, for a training under way, how far it has got; then
    the work left in all."""
    from readjax.lab import timing

    total, priced, todo = 0.0, True, 0
    for s in steps:
        status = s.status()
        line = f"{status}  {s.task}: {s.label}"
        if status == "todo":
            todo += 1
            cost = timing.step_cost(s, {}, {}, prior)
            priced &= cost is not None
            total += cost or 0.0
            line = f"{status}  ~{timing.hms(cost) if cost is not None else '?'}  {s.task}: {s.label}"
            so_far = s.progress() if s.progress is not None else ""
            if so_far:
                line += f"  (so far: {so_far})"
        print(line)
    print("(skip: not needed here: everything that would use its output is finished, or its condition "
          "does not hold)")
    if todo and priced:
        print(f"to run: {todo} steps, about {timing.hms(total)} of work (divide by the steps a machine or "
              f"cluster runs at once), priced from the timing records under {results}: the same step on another "
              f"task (its CPU time where recorded, from records made with the same malloc setting where there are "
              f"any), else the mean of its kind (rough for a training of a recipe not timed yet); a training "
              f"under way by its own pace to its step cap (an upper bound under the convergence rule)")
    elif todo:
        print(f"to run: {todo} steps (no timing records under {results} to price them yet)")


def config(args: argparse.Namespace):
    """The grid (a validated :class:`PipelineConfig`) that parsed arguments ask for."""
    from readjax import tasks
    from readjax.lab.pipeline_config import ChoiceGrid, PipelineConfig

    if any(n < 0 for n in args.read_N):
        raise ValueError(f"--read-N values must be >= 0, got {args.read_N}")
    names = tasks.names() if args.tasks == ["all"] else tuple(args.tasks)
    if any("=" not in r for r in args.run_name):
        raise ValueError(f"--run-name must look like METHOD=NAME, got {args.run_name}")
    run_names = tuple(tuple(r.split("=", 1)) for r in args.run_name)
    if any(len(v) < 2 for v in args.variant):
        raise ValueError(f"--variant takes LABEL METHOD [KEY=VALUE ...], got {[' '.join(v) for v in args.variant]}")
    variants = tuple((v[0], v[1], tuple(v[2:])) for v in args.variant)
    bad = [r for r in args.choice_rounds if r != "preset" and not r.isdigit()]
    if bad:
        raise ValueError(f"--choice-rounds takes positive integers or 'preset', got {bad}")
    grid = ChoiceGrid(rounds=tuple(None if r == "preset" else int(r) for r in args.choice_rounds),
                      refine=tuple(None if u == "preset" else u for u in args.choice_refine),
                      candidates=tuple(args.choice_candidates))
    cfg = PipelineConfig(
        tasks=names, methods=tuple(args.methods) + tuple(label for label, _, _ in variants), preset=args.preset,
        data=args.data, runs=args.runs,
        results=args.results, train_episodes=args.train_episodes, test_episodes=args.test_episodes,
        image_size=args.image_size, gen_batch=args.gen_batch, read_N=tuple(args.read_N),
        overrides=tuple(args.set), run_names=run_names,
        media_episodes=args.media_episodes, diagnose_below=args.diagnose_below, variants=variants,
        protocols=tuple(args.protocols), noise=args.noise, brightness=args.brightness,
        val_episodes=args.val_episodes, choice_grid=grid, fixed_refinement=tuple(args.fixed_refinement),
        protocol_runs=tuple(args.protocol_runs)).validate()
    return cfg


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from readjax.lab import deadline, pipeline, ray_grid, ray_resources, timing
    from readjax.lab.steps import PipelineError

    resources = ray_resources.parse_resources(args.resources)
    until = None if args.deadline is None else deadline.parse(args.deadline)
    cfg = config(args)
    try:
        steps = pipeline.plan_steps(cfg)
    except PipelineError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    if args.dry_run:
        dry_run(steps, timing.prior_costs(cfg.results), cfg.results)
        return 0
    try:
        # `kill` as Ctrl-C: the steps under way are stopped with the grid, not left running unwatched
        signal.signal(signal.SIGTERM, _interrupt)
        summary = ray_grid.run_on_ray(steps, log=lambda m: print(m, flush=True), prior=timing.prior_costs(cfg.results),
                                      address=args.ray_address, log_dir=Path(cfg.runs) / "pipeline_logs",
                                      resources=resources, deadline=until)
    except PipelineError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"pipeline: ran {summary['ran']} steps, skipped {summary['skipped']}; seconds by kind "
          f"{ {k: round(v) for k, v in summary['seconds'].items()} }")
    return 0


if __name__ == "__main__":
    sys.exit(_cli.run(main))
