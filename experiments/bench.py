"""Benchmarks. Timings here are wall-clock on a shared machine: compare ratios within one run.

  python -m experiments.bench sim      MJX batched expert episodes vs sequential C MuJoCo
                                        (same scene, same recorded controls), compile time,
                                        MJX/C trajectory parity
  python -m experiments.bench planner  READ planner latency (see its --help)
  python -m experiments.bench train    READ's two train steps timed, by parts, and profiled

Results are printed and written as JSON (--out).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from experiments import _cli, bench_train


def _time(fn, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def bench_sim(args) -> dict:
    import jax
    import jax.numpy as jnp
    import mujoco
    import numpy as np

    from readjax import provenance, tasks
    from readjax.data.generate import episode_fn
    from readjax.sim.reference import replay

    results = {"versions": provenance.versions(), "machine": provenance.machine(), "tasks": {}}
    for task in args.tasks:
        env = tasks.make(task)
        steps = env.episode_steps * env.substeps
        fn = episode_fn(env)
        row = {"physics_steps_per_episode": steps, "mjx": {}}
        for b in args.batch_sizes:
            seeds = jnp.arange(b, dtype=jnp.int32)
            t0 = time.perf_counter()
            jax.block_until_ready(fn(seeds))
            first = time.perf_counter() - t0
            times = _time(lambda: jax.block_until_ready(fn(seeds)), args.repeats)
            t = statistics.median(times)
            _, ok, _, _ = fn(seeds)
            row["mjx"][str(b)] = {
                "first_call_s": round(first, 2), "compile_s": round(first - t, 2), "call_s": round(t, 4),
                "physics_steps_per_s": round(b * steps / t), "demos_per_s": round(float(np.sum(ok)) / t, 2),
                "expert_success": float(np.mean(ok)),
            }
            print(f"{task:>14} MJX B={b:<4} compile {first - t:6.1f}s  {b * steps / t:9.0f} steps/s  "
                  f"{float(np.sum(ok)) / t:7.2f} demos/s", flush=True)
        # C MuJoCo: sequential replay of the same episodes' recorded controls
        n = args.c_episodes
        scenes, ok, _, trace = jax.tree.map(np.asarray, fn(jnp.arange(max(args.batch_sizes[0], n),
                                                                      dtype=jnp.int32)))
        data = mujoco.MjData(env.mj_model)
        devs, times = [], []
        for i in range(n):
            sc = jax.tree.map(lambda x: x[i], scenes)
            tr = jax.tree.map(lambda x: x[i], trace)
            t0 = time.perf_counter()
            tcp = replay(env, sc, tr, data)
            times.append(time.perf_counter() - t0)
            devs.append(float(np.abs(tcp - tr.tcp_pos).max()))
        t = statistics.median(times)
        row["c_mujoco"] = {"episodes": n, "episode_s": round(t, 4), "physics_steps_per_s": round(steps / t),
                           "demos_per_s": round(float(np.mean(ok[:n])) / t, 2)}
        row["parity_max_tcp_deviation_m"] = round(max(devs), 5)
        row["parity_median_tcp_deviation_m"] = round(statistics.median(devs), 5)
        print(f"{task:>14} C MuJoCo sequential      {steps / t:9.0f} steps/s  "
              f"{float(np.mean(ok[:n])) / t:7.2f} demos/s   MJX-vs-C tcp deviation max {max(devs) * 1e3:.2f} mm",
              flush=True)
        results["tasks"][task] = row
    return results


def _estimate_call_s(timed: list[tuple[int, float]], n: int) -> float:
    """Predicted seconds of one plan call with N = n from the calls timed so far at this batch:
    a fixed part (encoding, retrieval, IK) plus a per-step part, fitted through the last two
    timings (one timing: all of it counts as the fixed part, a lower bound)."""
    if not timed:
        return 0.0
    if len(timed) == 1:
        return timed[0][1]
    (n0, t0), (n1, t1) = timed[-2], timed[-1]
    per_step = max((t1 - t0) / max(n1 - n0, 1), 0.0)
    return t1 + per_step * (n - n1)


def slower_than(previous: dict, current: dict, factor: float = 2.0) -> list[str]:
    """The cells and parts of ``current`` that take >= ``factor`` x the time they took in ``previous``
    (two planner or two train bench JSONs; cells matched by preset, batch and N, parts by preset and
    batch; every ``*_ms`` figure compared).
    A regression check for a benchmark run, not a unit test: only ratios within one machine mean
    anything."""
    flagged = []

    def index(rows, keys):
        return {tuple(r.get(k) for k in keys): r for r in rows if not r.get("skipped")}

    for section, keys in (("cells", ("preset", "batch", "N")), ("parts", ("preset", "batch"))):
        old = index(previous.get(section, []), keys)
        for key, row in index(current.get(section, []), keys).items():
            if key not in old:
                continue
            for field, value in row.items():
                if not field.endswith("_ms") and field != "ms_per_call":
                    continue
                before = old[key].get(field)
                if before and value >= factor * before:
                    where = " ".join(f"{k}={v}" for k, v in zip(keys, key))
                    flagged.append(f"{where} {field}: {before} -> {value} ({value / before:.1f}x)")
    return flagged


def original_ratios(cells: list[dict], original_plans: list[dict], threads: int) -> list[dict]:
    """Our paper-preset planner cells against the original READ's plan timings (the ``plans`` of
    ``../shared/tools/orig_read_timing.py``) at the same batch, N and thread count: one row per
    cell and original variant (``as_is``, ``cached``), ``speedup`` = original ms / our ms per call."""
    orig = {(p["variant"], p["batch"], p["N"]): p for p in original_plans
            if p.get("measured") and p.get("threads") == threads}
    rows = []
    for c in cells:
        if c.get("skipped") or c.get("preset") != "paper":
            continue
        for variant in ("as_is", "cached"):
            o = orig.get((variant, c["batch"], c["N"]))
            if o:
                rows.append({"batch": c["batch"], "N": c["N"], "variant": variant, "readjax_ms": c["ms_per_call"],
                             "original_ms": o["median_ms"],
                             "speedup": round(o["median_ms"] / c["ms_per_call"], 2)})
    return rows


def original_command(args, out_json: Path) -> list[str]:
    """The shared harness's command line for this benchmark's batches, N, database size, cap on a
    cell's seconds and the original's variants (``as_is``, ``cached``)."""
    return [args.original_python, args.original_harness, args.vs_original, "--threads", str(args.threads),
            "--batches", *map(str, args.batch_sizes), "--steps", *map(str, sorted(args.N)),
            "--variants", *args.original_variants,
            "--repeats", str(args.repeats), "--db-size", str(args.database), "--max-cell-s", str(args.max_seconds),
            "--out", str(out_json)]


def run_original(args, out_json: Path) -> dict:
    """Time the original READ planner with the shared harness, in a subprocess (its own Python with
    torch, see the harness's docstring), at this benchmark's batches, N and database size."""
    import subprocess

    cmd = original_command(args, out_json)
    print("original READ:", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads(out_json.read_text())


def planner_parts(planner, images, repeats: int) -> dict:
    """Median ms per call of the plan's fixed parts, each timed alone after its compile: image
    encoding, SPE retrieval over the database, one refinement step, and decoding + IK of the
    result. (A plan = encode + retrieve + N steps + decode/IK, plus host glue.)"""
    import jax
    import numpy as np

    feats = jax.block_until_ready(planner.encode(images))
    idx = planner.retrieve(feats)
    m_r = planner.db_motion[idx]
    key = jax.random.key(0)
    m1 = np.asarray(planner.model.generate(feats, m_r, key, 1))
    fns = {"encode": lambda: jax.block_until_ready(planner.encode(images)),
           "retrieve": lambda: planner.retrieve(feats),
           "refine_N1": lambda: jax.block_until_ready(planner.model.generate(feats, m_r, key, 1)),
           "decode_ik": lambda: planner._finish(m1, np.asarray(m_r), idx)}
    out = {}
    for name, fn in fns.items():
        fn()
        out[name + "_ms"] = round(1e3 * statistics.median(_time(fn, repeats)), 2)
    return out


def bench_planner(args) -> dict:
    """ms per plan (encode + SPE retrieval + N refinement steps + IK) with random parameters:
    latency does not depend on training. Cells predicted to exceed --max-seconds are skipped."""
    import jax
    import numpy as np

    from readjax import config, provenance, tasks
    from readjax.methods.read import ReadModel
    from readjax.planner import Planner
    from readjax.sim.camera import camera_from_model

    env = tasks.make("reach_target")
    results = {"versions": provenance.versions(), "machine": provenance.machine(), "cells": []}
    for preset in args.presets:
        configs = config.presets(preset)
        size = configs["denoiser"].image_size
        cam = camera_from_model(env.mj_model, "front", size, size)
        model = ReadModel.random("reach_target", configs, cam, jax.random.key(0))
        rng = np.random.default_rng(0)
        db = bench_train.synthetic_dataset(cam, args.database, size)
        t0 = time.perf_counter()
        planner = Planner(model, db)
        setup = time.perf_counter() - t0
        print(f"{preset}: planner set-up (database features for {args.database}) {setup:.1f}s", flush=True)
        timed: dict[int, list[tuple[int, float]]] = {}  # batch -> [(N, seconds per call)]
        for b in args.batch_sizes:
            images = rng.uniform(size=(b, size, size, 4)).astype(np.float32)
            parts = planner_parts(planner, images, args.repeats)
            results["parts"] = results.get("parts", []) + [{"preset": preset, "batch": b, **parts}]
            print(f"{preset} B={b:<3} parts (ms per call): " + "  ".join(f"{k} {v:.1f}" for k, v in parts.items()),
                  flush=True)
            for n in sorted(args.N):
                est = _estimate_call_s(timed.get(b, []), n)
                if est > args.max_seconds:
                    print(f"{preset} B={b:<3} N={n:<4} skipped (estimated {est:.0f}s > --max-seconds)", flush=True)
                    results["cells"].append({"preset": preset, "batch": b, "N": n, "skipped": True,
                                             "estimated_s": round(est, 1)})
                    continue
                key = jax.random.key(1)
                t0 = time.perf_counter()
                # one refinement of N steps per plan (rounds=1): a run's sde.rounds = R costs R times the
                # refinement part of a cell, and cells stay comparable with earlier JSONs
                planner.plan(images, key, N=n, rounds=1)
                first = time.perf_counter() - t0
                times = _time(lambda: planner.plan(images, key, N=n, rounds=1), args.repeats)
                t = statistics.median(times)
                timed.setdefault(b, []).append((n, t))
                cell = {"preset": preset, "batch": b, "N": n, "ms_per_call": round(1e3 * t, 1),
                        "ms_per_plan": round(1e3 * t / b, 2), "compile_s": round(first - t, 2),
                        "setup_s": round(setup, 2)}
                results["cells"].append(cell)
                print(f"{preset} B={b:<3} N={n:<4} {1e3 * t:9.1f} ms/call {1e3 * t / b:8.2f} ms/plan  "
                      f"compile {first - t:5.1f}s", flush=True)
    return results


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
