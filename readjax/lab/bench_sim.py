"""MJX batched expert episodes against sequential C MuJoCo (``python -m experiments.bench sim``): the
same scene and recorded controls, physics steps and demos per second, compile time, and the MJX / C
trajectory parity (the TCP's deviation).
"""

from __future__ import annotations

import statistics
import time

from readjax.lab.bench_common import time_calls


def bench_sim(args) -> dict:
    """Per task (``args.tasks``): MJX at each of ``args.batch_sizes``, then C MuJoCo replaying the first
    ``args.c_episodes`` of the same episodes one by one, and the TCP's deviation between the two."""
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
            times = time_calls(lambda: jax.block_until_ready(fn(seeds)), args.repeats)
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
