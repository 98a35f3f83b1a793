"""Helpers of tests/test_distributed.py: a tiny synthetic training split (no simulation), the tiny
READ training it runs, and the driver that starts a training as several ``experiments.train
--distributed`` processes on the CPU (one device each, coordinator 127.0.0.1), optionally kills
them all once a checkpoint appears and starts them again.

The driver is meant to run inside a private network namespace, where only the loopback exists:
``unshare -n python -m tests.multiprocess ...`` (root, as in CI); it brings ``lo`` up itself, so
no byte of the training leaves 127.0.0.1.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TASK = "reach_target"
IMAGE = 32
# READ at the smallest sizes its config allows, checkpointed every 2 steps; 2 of the 12 demos held out
# and validated every 2 steps, where no 90 % gain within 2 steps ends each stage at step 4 of its 6
TINY = ["vae_steps=6", "steps=6", "vae_batch=4", "batch=4", "ckpt_every=2", "log_every=2", "val_episodes=2",
        "val_every=2", "stop_patience=2", "stop_min_delta=0.9",
        "denoiser.image_size=32", "denoiser.conv_dims=8,8,8,8", "denoiser.enc_depths=0,0,0,0",
        "denoiser.dec_depths=0,0,0", "denoiser.feature_channels=8", "denoiser.d_model=16", "denoiser.ffn=32",
        "denoiser.layers=1", "denoiser.heads=2", "vae.width=16", "vae.layers=1", "vae.heads=2", "vae.ffn=32",
        "vae.latent_dim=16", "K=3"]


def write_split(root: Path, n: int = 12, seed: int = 0) -> Path:
    """A training split of ``n`` random demos in the store's format (``root/reach_target/train``)."""
    from readjax import tasks
    from readjax.camera import CameraParams
    from readjax.data import store
    from readjax.sim.env import Scene

    rng = np.random.default_rng(seed)
    path = store.split_dir(root, TASK, "train")
    k = np.array([[40.0, 0.0, IMAGE / 2], [0.0, 40.0, IMAGE / 2], [0.0, 0.0, 1.0]])
    cam_to_world = np.eye(4)
    cam_to_world[:3, 3] = [0.0, 0.0, 1.5]
    store.write_meta(path, {"task": TASK, "split": "train", "image_size": IMAGE, "suite": tasks.SUITE_VERSION,
                            "camera": CameraParams(k, cam_to_world, IMAGE, IMAGE).to_dict(),
                            "format_version": store.FORMAT_VERSION})
    # straight camera-frame tracks: uv in the image, 1 m deep, a fixed orientation, the grip closing
    t = np.linspace(0.0, 1.0, 101)[None, :, None]
    base = np.array([0, 0, 1.0, 1, 0, 0, 0, 1, 0, 1.0])
    start = base + rng.normal(0, 0.3, (n, 1, 10)) * np.array([1, 1, 0.1, 0, 0, 0, 0, 0, 0, 0])
    end = start + rng.normal(0, 0.3, (n, 1, 10)) * np.array([1, 1, 0.1, 0, 0, 0, 0, 0, 0, 0])
    end[..., 9] = 0.0
    motion = (start + (end - start) * t).astype(np.float32)
    store.write_shard(path, 0, rgb=rng.integers(0, 256, (n, IMAGE, IMAGE, 3), dtype=np.uint8),
                      depth01=rng.uniform(size=(n, IMAGE, IMAGE)), motion=motion,
                      joints=rng.normal(0, 0.1, (n, 101, 7)).astype(np.float32),
                      seeds=np.arange(n, dtype=np.int64), raw_frames=np.full(n, 150, np.int32),
                      scenes=Scene(qpos=rng.normal(size=(n, 9)), mocap_pos=rng.normal(size=(n, 1, 3)),
                                   mocap_quat=rng.normal(size=(n, 1, 4)), rgba=rng.uniform(size=(n, 1, 4)),
                                   params={"target": rng.normal(size=(n, 3))}),
                      attempted_seeds=np.arange(n, dtype=np.int64), failed_seeds=np.zeros(0, np.int64))
    return root


def train_argv(data: Path, out: Path) -> list[str]:
    """The tiny training's ``experiments.train`` arguments."""
    return ["--task", TASK, "--data", str(data), "--out", str(out), "--quiet"] + sum((["--set", s] for s in TINY), [])


def environment(devices: int) -> dict:
    """A training process's environment: ``devices`` host devices, the persistent cache it shares."""
    env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={devices}", PYTHONPATH=str(ROOT))
    env.pop("JAX_PLATFORMS", None)
    return env


def train_command(argv: list[str]) -> list[str]:
    """``experiments.train`` with ``argv``, caching every compile (the eager model initialisation compiles
    hundreds of sub-second programs the persistent cache skips by default): the processes of a test
    then compile each program once between them."""
    return [sys.executable, "-m", "tests.multiprocess", "train", *argv]


def start(argv: list[str], rank: int, count: int, port: int, log: Path) -> subprocess.Popen:
    cmd = train_command([*argv, "--distributed", "--coordinator", f"127.0.0.1:{port}", "--num-processes",
                         str(count), "--process-id", str(rank)])
    return subprocess.Popen(cmd, cwd=ROOT, env=environment(1), stdout=open(log, "w"), stderr=subprocess.STDOUT)


def run(argv: list[str], count: int, port: int, logs: Path, kill_at: Path | None = None,
        timeout: float = 600) -> dict:
    """Train with ``count`` processes; with ``kill_at``, SIGKILL them all once that path exists and
    start them again (another port). Returns what happened (for the test's assertions)."""
    logs.mkdir(parents=True, exist_ok=True)
    record = {"killed": False}
    for attempt in range(2 if kill_at is not None else 1):
        procs = [start(argv, r, count, port + attempt, logs / f"attempt{attempt}_process{r}.log") for r in range(count)]
        t0 = time.time()
        while any(p.poll() is None for p in procs):
            if attempt == 0 and kill_at is not None and kill_at.exists():
                for p in procs:
                    os.kill(p.pid, signal.SIGKILL)  # the whole training dies at once, mid-run
                out = Path(argv[argv.index("--out") + 1])
                record.update(killed=True, killed_after_s=round(time.time() - t0, 1),
                              finished_at_kill=sorted(str(f.relative_to(out)) for f in out.rglob("stop.json")))
                break
            if time.time() - t0 > timeout:
                for p in procs:
                    p.kill()
                raise TimeoutError(f"the {count} processes ran past {timeout} s (logs in {logs})")
            time.sleep(0.05)
        for p in procs:
            p.wait()
        record[f"attempt{attempt}_rc"] = [p.returncode for p in procs]
        record[f"attempt{attempt}_s"] = round(time.time() - t0, 1)
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)  # the processes' CPU time, all attempts so far
        record[f"attempt{attempt}_cpu_s"] = round(usage.ru_utime + usage.ru_stime, 1)
        if kill_at is not None and attempt == 0 and not record["killed"]:
            raise RuntimeError(f"the training finished before {kill_at} appeared (logs in {logs})")
    return record


def checkpoint(stage_dir: Path, step: int | None = None) -> dict:
    """The train state (step, params, opt_state) of a stage's checkpoint ``step`` (default: the
    latest), as numpy arrays."""
    import jax
    import orbax.checkpoint as ocp

    ckpts = Path(stage_dir) / "checkpoints"
    step = max(int(p.name) for p in ckpts.iterdir() if p.name.isdigit()) if step is None else step
    path = ckpts / str(step) / "state"
    checkpointer = ocp.PyTreeCheckpointer()
    tree = checkpointer.metadata(path).item_metadata.tree
    args = jax.tree.map(lambda _: ocp.RestoreArgs(restore_type=np.ndarray), tree)
    return checkpointer.restore(path, args=ocp.args.PyTreeRestore(restore_args=args))


def max_abs_difference(a, b) -> float:
    """The largest |a - b| over every leaf of two trees of the same structure."""
    import jax

    assert jax.tree.structure(a) == jax.tree.structure(b)
    return max(float(np.max(np.abs(np.asarray(x, np.float64) - np.asarray(y, np.float64)), initial=0.0))
               for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["train"]:
        import readjax  # noqa: F401  (its JAX settings first)
        import jax

        from experiments import _cli
        from experiments import train

        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        sys.exit(_cli.run(train.main, argv[1:]))
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--data", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--processes", type=int, default=2)
    p.add_argument("--port", type=int, default=23456)
    p.add_argument("--kill-at", default=None, help="a path: kill every process once it exists, then restart")
    args = p.parse_args(argv)
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    out = Path(args.out)
    record = run(train_argv(Path(args.data), out), args.processes, args.port, out / "logs",
                 Path(args.kill_at) if args.kill_at else None)
    print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
