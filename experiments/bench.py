"""Benchmarks. Timings here are wall-clock on a shared machine: compare ratios within one run.

  python -m experiments.bench sim      MJX batched expert episodes vs sequential C MuJoCo
                                        (same scene, same recorded controls), compile time,
                                        MJX/C trajectory parity
  python -m experiments.bench planner  READ planner latency (see its --help)

Results are printed and written as JSON (--out).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from experiments import _cli


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


def parser() -> argparse.ArgumentParser:
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
    pl.add_argument("--out", default="runs/bench/planner.json")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    if args.what == "sim":
        from readjax import tasks

        args.tasks = list(tasks.names()) if args.tasks == ["all"] else [tasks.canonical_name(t) for t in args.tasks]
        result = bench_sim(args)
    else:
        from readjax.bench_planner import bench_planner  # noqa: F401  (added with the planner)

        result = bench_planner(args)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
