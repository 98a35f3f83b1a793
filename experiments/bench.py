"""Benchmarks. Timings here are wall-clock on a shared machine: compare ratios within one run.

  python -m experiments.bench sim      MJX batched expert episodes vs sequential C MuJoCo
                                        (same scene, same recorded controls), compile time,
                                        MJX/C trajectory parity
  python -m experiments.bench planner  READ planner latency (see its --help)
  python -m experiments.bench train    READ's two train steps timed, by parts, and profiled
  python -m experiments.bench malloc   READ's train steps under glibc's malloc and readjax's tuning

Results are printed and written as JSON (--out).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import _cli, bench_malloc, bench_train
from readjax.lab.bench_compare import original_ratios, run_original, slower_than
from readjax.lab.bench_planner import bench_planner
from readjax.lab.bench_sim import bench_sim


def parser() -> argparse.ArgumentParser:
    from readjax import config

    p = argparse.ArgumentParser(prog="python -m experiments.bench", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("sim", help="simulation throughput and parity", formatter_class=_cli.HelpFormatter)
    s.add_argument("--tasks", nargs="+", default=["pick_up_cup"], help="task names/codes, or 'all'")
    s.add_argument("--batch-sizes", nargs="+", type=_cli.positive_int, default=[8, 32, 128])
    s.add_argument("--repeats", type=_cli.positive_int, default=3)
    s.add_argument("--c-episodes", type=_cli.positive_int, default=8, help="episodes replayed in C MuJoCo")
    s.add_argument("--out", default="runs/bench/sim.json")
    m = sub.add_parser("malloc", help="READ's train steps: glibc's malloc as it is vs readjax's tuning",
                       description=bench_malloc.__doc__, formatter_class=_cli.HelpFormatter)
    m.add_argument("--steps", type=_cli.positive_int, default=20, help="timed steps per stage and process")
    m.add_argument("--batch", type=_cli.positive_int, default=32, help="batch size (the cpu preset trains at 32)")
    m.add_argument("--rounds", type=_cli.positive_int, default=2, help="processes per setting, in turn")
    m.add_argument("--out", default="runs/bench/malloc.json")
    pl = sub.add_parser("planner", help="planner latency (READ)", formatter_class=_cli.HelpFormatter)
    presets = sorted(config.preset_names())
    pl.add_argument("--presets", nargs="+", default=list(presets), choices=presets)
    pl.add_argument("--batch-sizes", nargs="+", type=_cli.positive_int, default=[1, 64])
    pl.add_argument("--N", nargs="+", type=int, default=[1, 10, 100], help="refinement steps")
    pl.add_argument("--database", type=_cli.positive_int, default=200, help="retrieval database size")
    pl.add_argument("--repeats", type=_cli.positive_int, default=3)
    pl.add_argument("--max-seconds", type=float, default=120.0,
                    help="skip a cell whose single call would exceed this (e.g. the paper preset on a CPU)")
    pl.add_argument("--out", default="runs/bench/planner.json")
    pl.add_argument("--vs-original", metavar="READ_DIR",
                    help="also time the original PyTorch READ (an exported copy of Obat2343/READ at the harness's "
                         "commit) right after, with ../shared/tools/orig_read_timing.py, and report the speed-ups "
                         "(paper preset cells)")
    pl.add_argument("--original-python", default=sys.executable,
                    help="the Python that runs the harness (needs torch, einops, yacs, timm: see the harness)")
    pl.add_argument("--original-harness", default=str(Path(__file__).resolve().parents[2] / "shared" / "tools"
                                                      / "orig_read_timing.py"))
    pl.add_argument("--threads", type=_cli.positive_int, default=2, help="torch threads for the original")
    pl.add_argument("--original-variants", nargs="+", choices=("as_is", "cached"), default=["as_is", "cached"],
                    help="the original's variants to time: as released (its UNet re-run at every step: at batch 64 "
                         "and N = 100 about an hour on 2 cores) and/or with its UNet map cached")
    pl.add_argument("--compare", metavar="JSON",
                    help="a previous planner JSON (e.g. docs/bench/planner_paper.json): list every cell or part "
                         "that got >= --slower x slower, and exit 1 if any did")
    pl.add_argument("--slower", type=float, default=2.0, help="the ratio --compare flags")
    tr = sub.add_parser("train", help="READ's train steps (autoencoder, denoiser): timed, by parts, profiled",
                        description=bench_train.__doc__, formatter_class=_cli.HelpFormatter)
    tr.add_argument("--presets", nargs="+", default=["cpu"], choices=presets)
    tr.add_argument("--batch", type=_cli.positive_int, default=32, help="batch size (the cpu preset trains at 32)")
    tr.add_argument("--repeats", type=_cli.positive_int, default=20, help="timed calls per figure (median)")
    tr.add_argument("--profile", action="store_true",
                    help="also trace the READ step and attribute its XLA ops to the model's parts")
    tr.add_argument("--out", default="runs/bench/train.json")
    tr.add_argument("--compare", metavar="JSON", help="a previous train JSON (e.g. docs/bench/train_cpu.json): list "
                                                      "every timing >= --slower x slower, and exit 1 if any is")
    tr.add_argument("--slower", type=float, default=2.0, help="the ratio --compare flags")
    return p


def read_compare(path: str | None, what: str, section: str) -> dict | None:
    """The --compare JSON of a ``what`` benchmark (None without one); a missing or unreadable file,
    or one without ``section``, is a one-line error before any timing."""
    if not path:
        return None
    return _cli.read_json_record(path, section, f"{what} benchmark JSON (--compare)")


def check_planner_inputs(args) -> dict | None:
    """Fail before any timing (minutes to hours) on a bad --compare or --vs-original: a missing or
    unreadable file is a one-line error. Returns the --compare JSON (None without it)."""
    previous = read_compare(args.compare, "planner", "cells")
    if args.vs_original:
        for what, path, ok in (("--vs-original", args.vs_original, Path(args.vs_original).is_dir()),
                               ("--original-harness", args.original_harness, Path(args.original_harness).is_file()),
                               ("--original-python", args.original_python, Path(args.original_python).is_file())):
            if not ok:
                raise FileNotFoundError(f"{what}: {path} does not exist")
    return previous


def write_json(result: dict, out: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(f"wrote {out}")


def main(argv=None) -> int | None:
    args = parser().parse_args(argv)
    out = Path(args.out)
    if args.what == "sim":
        from readjax import tasks

        args.tasks = list(tasks.names()) if args.tasks == ["all"] else [tasks.canonical_name(t) for t in args.tasks]
        write_json(bench_sim(args), out)
        return None
    if args.what == "malloc":
        write_json(bench_malloc.bench_malloc(args), out)
        return None
    if args.what == "train":
        previous = read_compare(args.compare, "train", "parts")
        result = bench_train.bench_train(args)
        write_json(result, out)
        return report_slower(previous, result, args)
    previous = check_planner_inputs(args)
    result = bench_planner(args)
    write_json(result, out)  # kept even if the original's harness fails below
    if args.vs_original:
        orig = run_original(args, out.with_suffix(".original.json"))
        result["original"] = {"harness": args.original_harness, "repo": args.vs_original,
                              "threads": args.threads, "plans": orig.get("plans", [])}
        result["vs_original"] = original_ratios(result["cells"], orig.get("plans", []), args.threads)
        for r in result["vs_original"]:
            print(f"B={r['batch']:<3} N={r['N']:<4} readjax {r['readjax_ms']:9.1f} ms  original ({r['variant']}) "
                  f"{r['original_ms']:9.1f} ms  -> {r['speedup']:.2f}x", flush=True)
        write_json(result, out)
    return report_slower(previous, result, args)


def report_slower(previous: dict | None, result: dict, args) -> int | None:
    """Print what got >= --slower x slower than the --compare JSON; 1 (the exit status) if anything did."""
    if previous is None:
        return None
    flagged = slower_than(previous, result, args.slower)
    for line in flagged:
        print(f"SLOWER: {line}")
    print(f"{len(flagged)} cells/parts >= {args.slower}x slower than {args.compare}")
    return 1 if flagged else None


if __name__ == "__main__":
    sys.exit(_cli.run(main))
