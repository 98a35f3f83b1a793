"""READ's two train steps under glibc's own malloc and under readjax's tuning of it
(``python -m experiments.bench malloc``).

XLA:CPU allocates each step's temporaries afresh; glibc's malloc maps every buffer above its mmap
threshold (32 MiB at most) from the kernel and unmaps it when freed, so each step page-faults its
temporaries in again and the kernel zeroes them. ``readjax._runtime.MALLOC_TUNABLES`` keeps freed
memory in the process, and every command of ours runs with it. glibc reads its tunables only when a
process starts, so each setting runs in its own process (the cpu preset's steps, as
``experiments.bench train`` builds them, on the same synthetic batch from the same parameters), in
turn, ``--rounds`` times. Per setting and stage: ms per step (median over rounds), page faults and
kernel CPU seconds per step, and a hash of the parameters after the steps: equal hashes mean the
tuning changed no bit of the training.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import statistics
import subprocess
import sys
import time

SETTINGS = ("system", "tuned")


def child(steps: int, batch: int) -> dict:
    """This process's figures (its malloc set at its start): each stage stepped ``steps`` times."""
    from experiments.bench_train import build  # readjax (its XLA flags) before jax

    import jax
    import numpy as np

    b = build("cpu", batch)
    out = {}
    for stage in ("vae", "read"):
        stepper = b[stage]
        jax.block_until_ready(stepper())  # compile
        r0, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
        for _ in range(steps):
            jax.block_until_ready(stepper())
        seconds, r1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_SELF)
        digest = hashlib.sha256()
        for leaf in jax.tree.leaves(stepper.state.params):
            digest.update(np.asarray(leaf).tobytes())
        out[stage] = {"ms": 1e3 * seconds / steps, "faults": (r1.ru_minflt - r0.ru_minflt) / steps,
                      "sys_s": (r1.ru_stime - r0.ru_stime) / steps, "params_sha256": digest.hexdigest()[:16]}
    return out


def run_setting(setting: str, steps: int, batch: int) -> dict:
    from readjax import _runtime

    env = {k: v for k, v in os.environ.items() if k not in ("GLIBC_TUNABLES", _runtime.MALLOC_OPT_OUT)}
    env = _runtime.with_malloc_tunables(env) if setting == "tuned" else {**env, _runtime.MALLOC_OPT_OUT: "system"}
    proc = subprocess.run([sys.executable, "-m", "experiments.bench_malloc", str(steps), str(batch)], env=env,
                          capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def bench_malloc(args) -> dict:
    """Each setting ``args.rounds`` times, in turn; the rows and the tuned / system ratios."""
    runs = {s: [] for s in SETTINGS}
    for k in range(args.rounds):
        for setting in SETTINGS:
            runs[setting].append(run_setting(setting, args.steps, args.batch))
            print(f"round {k + 1}/{args.rounds} {setting}: " + ", ".join(
                f"{st} {r['ms']:.0f} ms/step, {r['faults']:.0f} faults/step" for st, r in runs[setting][-1].items()),
                flush=True)
    rows = []
    for stage in ("vae", "read"):
        row = {"stage": stage}
        for setting in SETTINGS:
            rs = [r[stage] for r in runs[setting]]
            row[setting] = {"ms": round(statistics.median(r["ms"] for r in rs), 1),
                            "faults_per_step": round(statistics.median(r["faults"] for r in rs)),
                            "sys_s_per_step": round(statistics.median(r["sys_s"] for r in rs), 4)}
        row["speedup"] = round(row["system"]["ms"] / row["tuned"]["ms"], 2)
        row["same_parameters"] = len({r[stage]["params_sha256"] for s in SETTINGS for r in runs[s]}) == 1
        rows.append(row)
        print(f"{stage}: {row['system']['ms']} -> {row['tuned']['ms']} ms/step ({row['speedup']}x), page faults "
              f"{row['system']['faults_per_step']} -> {row['tuned']['faults_per_step']} per step, same parameters: "
              f"{row['same_parameters']}", flush=True)
    return {"steps": args.steps, "batch": args.batch, "rounds": args.rounds, "stages": rows, "runs": runs}


if __name__ == "__main__":  # one setting's process (run_setting)
    print(json.dumps(child(int(sys.argv[1]), int(sys.argv[2]))))
