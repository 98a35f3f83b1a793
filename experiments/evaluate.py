"""Evaluate a trained run: plan for the fixed test episodes, execute every plan in MJX (batched)
with the paper's protocol, and print the success table.

Writes RUN/eval/<name>.json (per-episode success, rates, config, seeds, versions, "split": "test"),
an overlay of retrieved / planned / ground-truth motions on the input images (<name>_overlay.png)
and a video of a few executed rollouts (<name>_rollouts.mp4). The split (DATA/<task>/test) is
generated first if it is missing.

--split val evaluates the validation episodes instead (DATA/<task>/val, seeds from 2,000,000, disjoint
from the training and test seeds; generated first if missing): the place to choose settings. Its
record ("split": "val") goes to RUN/val/<name>.json, never to RUN/eval/, so no table, report or
pipeline check of finished evaluations counts it. --choice FILE refines with the setting that
experiments.choose picked on the validation split (its --rounds, --refine, --candidates) and names
the file in the record ("chosen_on": "val").

examples:
  python -m experiments.evaluate --run runs/reach_target/read --episodes 100
  python -m experiments.evaluate --run runs/RT/read --no-refine                 # N = 0
  python -m experiments.evaluate --run runs/RT/read --retrieval cheat --rank 3 --N 10
  python -m experiments.evaluate --run runs/RT/read --split val --rounds 1 --refine renoise   # a candidate
  python -m experiments.evaluate --run runs/RT/read --choice results/reach_target/read/choice.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from experiments import _cli
from readjax.config import DEFAULT_N, REFINE_UPDATES


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.evaluate", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--run", required=True, help="a run folder from experiments.train")
    p.add_argument("--episodes", type=_cli.positive_int, default=100, help="episodes of the split (fixed seeds)")
    p.add_argument("--split", default="test", choices=("test", "val"),
                   help="the episodes evaluated: test (what tables report; record in RUN/eval/) or val, the "
                        "validation split to choose settings on (record in RUN/val/, which no table reads)")
    p.add_argument("--choice", default=None, metavar="FILE",
                   help="a choice file of experiments.choose (RESULTS/<task>/<run>/choice.json): refine with the "
                        "setting it chose on the validation split (instead of --rounds / --refine / "
                        "--candidates); the record names it (\"chosen_on\": \"val\")")
    p.add_argument("--N", type=int, default=None, help=f"refinement steps (default: {DEFAULT_N})")
    p.add_argument("--no-refine", action="store_true", help="execute the retrieved motion (N = 0)")
    p.add_argument("--refine", default=None, choices=REFINE_UPDATES,
                   help="READ's refinement update (default: the run's sde.update): renoise = the paper's loop, "
                        "cold = the improved cold-diffusion update, cold_anchor = cold after an anchoring first "
                        "step (readjax.diffusion.refine)")
    p.add_argument("--retrieval", default="spe", choices=("spe", "cheat"), help="SPE, or the oracle")
    p.add_argument("--rank", type=_cli.positive_int, default=1, help="oracle: the rank-th nearest neighbour")
    p.add_argument("--candidates", type=_cli.positive_int, default=1,
                   help="refine SPE's top-C retrievals and keep, per image, the plan that one more refinement "
                        "step moves least (1: the paper's top-1; beyond the paper, see README)")
    p.add_argument("--rounds", type=_cli.positive_int, default=None,
                   help="refine R times in a row, each round from the previous round's plan as the retrieved "
                        "motion (default: the run's sde.rounds, 2 in the cpu preset; 1: the paper's single "
                        "refinement; beyond the paper, see README)")
    p.add_argument("--noise", type=float, default=0.0, help="Gaussian noise std on test RGB (Table 9)")
    p.add_argument("--brightness", type=float, default=1.0, help="brightness factor on test RGB (Table 9)")
    p.add_argument("--data", default=None, help="dataset root (default: the one the run was trained on)")
    p.add_argument("--batch-size", type=_cli.positive_int, default=50)
    p.add_argument("--videos", type=int, default=4, help="rollouts rendered to the MP4 (0: none)")
    p.add_argument("--name", default=None, help="result name (default from the options)")
    p.add_argument("--out", default=None, help="folder for the JSON, overlay and video (default: RUN/eval, which "
                                               "experiments.report reads, or RUN/val with --split val; another "
                                               "folder keeps e.g. a few episodes rendered for show out of the "
                                               "tables)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--quiet", action="store_true")
    return p


def default_name(args, uses_retrieval: bool = True, iterative: bool = True, default_n: int | None = None,
                 refine_update: str | None = None, default_rounds: int = 1) -> str:
    """Result name from the options that apply to the method: the retrieval (when the method
    retrieves, or the oracle is asked for), N (when it samples iteratively; ``default_n`` when --N
    is not given; ``_cold`` / ``_cold_anchor`` when READ refines with a cold-diffusion update, ``refine_update``);
    ``direct`` for a one-pass method without retrieval."""
    n = 0 if args.no_refine else (args.N if args.N is not None else default_n)
    parts = []
    if uses_retrieval or args.retrieval == "cheat":
        parts.append(args.retrieval if args.retrieval == "spe" else f"cheat{args.rank}")
    if iterative:
        parts.append(f"N{'default' if n is None else n}")
    if not parts:
        parts.append("direct")
    if refine_update not in (None, "renoise") and iterative and n != 0:
        parts.append(refine_update)
    if args.candidates > 1:
        parts.append(f"top{args.candidates}")
    rounds = default_rounds if args.rounds is None else args.rounds
    if rounds > 1 and iterative and n != 0:
        parts.append(f"rounds{rounds}")
    if args.noise:
        parts.append(f"noise{args.noise:g}")
    if args.brightness != 1.0:
        parts.append(f"bright{args.brightness:g}")
    return "_".join(parts)


def output_folder(run, split: str, out: str | None) -> Path:
    """Where an evaluation's JSON and pictures go: ``out``, else RUN/eval (the test split) or RUN/val
    (the validation split). A validation evaluation is refused in RUN/eval, which the tables read."""
    folder = Path(out) if out else Path(run) / ("eval" if split == "test" else "val")
    if split != "test" and folder.resolve() == (Path(run) / "eval").resolve():
        raise ValueError(f"--split {split}: its record may not go to {folder}, which the tables read as test "
                         f"results; leave --out out (RUN/val)")
    return folder


def apply_choice(args, spec: dict) -> dict:
    """Set ``args``' refinement from the choice file ``args.choice``; returns the fields that name the
    choice in the record. Refused where the file is no choice, is another run's, or other
    refinement options are given too."""
    from readjax.lab import choice as choice_lib

    c = choice_lib.load(args.choice)
    if c is None:
        raise FileNotFoundError(f"--choice {args.choice}: no choice file there (experiments.choose writes one)")
    if (c.get("task"), c.get("run")) != (spec["task"], Path(args.run).name):
        raise ValueError(f"--choice {args.choice} chose for {c.get('task')}/{c.get('run')}, not for this run "
                         f"({spec['task']}/{Path(args.run).name})")
    if args.rounds is not None or args.refine is not None or args.candidates != 1:
        raise ValueError("--choice sets --rounds, --refine and --candidates: give either the choice or those")
    if args.no_refine or args.N == 0:
        raise ValueError("--choice sets how to refine; N = 0 refines nothing")
    setting = choice_lib.chosen_setting(c)
    args.rounds, args.refine, args.candidates = setting.rounds, setting.refine, setting.candidates
    return choice_lib.record_of(args.choice, c)


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax.methods.common import check_n_steps
    if args.N is not None:
        check_n_steps(args.N, name="--N")
    from readjax import evaluation, tables
    from readjax.data import store
    from readjax.data.generate import GenerateConfig, generate
    from readjax.methods.base import read_run
    from readjax.planner import Planner

    spec = read_run(args.run)
    out = output_folder(args.run, args.split, args.out)
    extra = apply_choice(args, spec) if args.choice else {}
    root = args.data or spec["data_root"]
    test_dir = store.split_dir(root, spec["task"], args.split)
    have = store.read_progress(test_dir).kept if test_dir.exists() else 0
    if have < args.episodes:
        train_meta = store.read_meta(store.split_dir(root, spec["task"], "train")) or {}
        size = train_meta.get("image_size", spec["image_size"])
        print(f"generating the {args.split} split ({args.episodes} episodes) in {test_dir}", flush=True)
        generate(GenerateConfig(task=spec["task"], split=args.split, episodes=args.episodes, out=str(root),
                                image_size=size), progress=not args.quiet)
    test_ds = store.load_dataset(test_dir, limit=args.episodes)
    planner = Planner.load(args.run, data_root=root)
    cfg = evaluation.EvalConfig(episodes=args.episodes, N=0 if args.no_refine else args.N,
                                retrieval=args.retrieval, rank=args.rank, batch_size=args.batch_size,
                                seed=args.seed, videos=args.videos, image_noise=args.noise,
                                brightness=args.brightness, candidates=args.candidates,
                                rounds=args.rounds)
    model = planner.model
    if args.refine is not None:
        model.set_refine_update(args.refine)  # a method without an update says so
    name = args.name or default_name(args, model.uses_retrieval, model.iterative, planner.n_steps,
                                     evaluation.refine_update(model), planner.default_rounds)
    result = evaluation.evaluate(planner, test_ds, cfg, out_dir=out, name=name, progress=not args.quiet,
                                 extra=extra)
    label = f"{result['method']} ({name})"
    print(tables.format_table({label: result["table"]}))
    print(f"success {100 * result['success_rate']:.1f}% over {result['episodes']} {args.split} episodes; "
          f"results in {out / (name + '.json')}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
