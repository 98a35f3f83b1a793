"""READ's planner latency (``python -m experiments.bench planner``): ms per plan call (encoding, SPE
retrieval, N refinement steps, decoding + IK) at each preset, batch and N, with random parameters
(latency does not depend on training), and each fixed part of a plan timed alone.
"""

from __future__ import annotations

import statistics
import time

from readjax.lab.bench_common import synthetic_dataset, time_calls


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
        out[name + "_ms"] = round(1e3 * statistics.median(time_calls(fn, repeats)), 2)
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
        db = synthetic_dataset(cam, args.database, size)
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
                times = time_calls(lambda: planner.plan(images, key, N=n, rounds=1), args.repeats)
                t = statistics.median(times)
                timed.setdefault(b, []).append((n, t))
                cell = {"preset": preset, "batch": b, "N": n, "ms_per_call": round(1e3 * t, 1),
                        "ms_per_plan": round(1e3 * t / b, 2), "compile_s": round(first - t, 2),
                        "setup_s": round(setup, 2)}
                results["cells"].append(cell)
                print(f"{preset} B={b:<3} N={n:<4} {1e3 * t:9.1f} ms/call {1e3 * t / b:8.2f} ms/plan  "
                      f"compile {first - t:5.1f}s", flush=True)
    return results
