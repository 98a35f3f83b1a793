"""Scenarios of the grid on Ray, each run by tests/test_ray_grid.py in its own private network namespace
(only 127.0.0.1 exists there) and PID namespace (whatever it starts ends with it):

    python -m tests.ray_cluster SCENARIO FOLDER [NODES]     # writes FOLDER/report.json

``two_nodes``: a tiny grid (:func:`fake_grid`) on a local two-node cluster (one CPU each), then the same
grid on an embedded Ray (no address), then a grid with a failing step on the cluster, then the grid on an
embedded Ray with a deadline closer than a step's price. ``node_killed``: the tiny grid on two nodes,
the node running a step killed during it. ``real_steps``: ``experiments.pipeline --ray-address`` with
real readjax steps (a tiny grid of reach_target) on two nodes. The steps of
:func:`fake_grid` are short processes without JAX, each writing a file made from the files it reads (so
results depend on what ran before them) and a line to a ledger as it starts and as it ends.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

from readjax.lab import ray_grid, steps, timing
from readjax.lab.deadline import DeadlineError

TASKS = ("reach_target", "push_button")
# a fake step's command: argv = LEDGER LABEL SECONDS OUTPUT [INPUT ...]
COMMAND = """
import hashlib, os, sys, time
ledger, label, seconds, out, *inputs = sys.argv[1:]
def note(what):
    with open(ledger, "a") as f:
        f.write(f"{what} {label}\\n")
note("start")
time.sleep(float(seconds))
digest = hashlib.sha256(label.encode())
for name in inputs:
    digest.update(open(name, "rb").read())
open(out + ".part", "w").write(digest.hexdigest())
os.replace(out + ".part", out)
note("done")
"""


def fake_grid(seconds: float = 0.5, generate_seconds: float | None = None) -> list[steps.Step]:
    """Per task, as the grid: generate test and train -> verify test -> train two methods -> evaluate each
    (published to results/<task>/ by its ``after``); each step's time in the task's timing record. Paths
    are relative, read from the folder the grid runs from (:func:`prepare` makes its folders)."""
    grid = []
    for task in TASKS:
        work, results = Path("work") / task, Path("results") / task
        made = {}

        def step(kind, label, reads=(), needs=(), publish=False, slow=None):
            out = work / label.replace(" ", "_")
            dest = results / out.name

            def after(out=out, dest=dest):
                if publish:
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    dest.write_text(out.read_text())

            argv = [sys.executable, "-c", COMMAND, str(work / "ledger.txt"), label, str(slow or seconds), str(out),
                    *[str(made[r]) for r in reads]]
            s = steps.Step(kind, task, label, argv, made=(dest if publish else out).exists, after=after,
                           timing=results / timing.TIMING_FILE, needs=[n for n in grid if n.label in needs
                                                                       and n.task == task], resumes=kind != "verify")
            made[label] = out
            grid.append(s)

        step("generate", "generate test", slow=generate_seconds)
        step("generate", "generate train", slow=generate_seconds)
        step("verify", "verify test", reads=("generate test",), needs=("generate test",))
        for method in ("read", "deterministic"):
            step("train", f"train {method}", reads=("generate train", "verify test"),
                 needs=("generate train", "verify test"))
            step("evaluate", f"evaluate {method}", reads=(f"train {method}", "generate test"),
                 needs=(f"train {method}", "generate test"), publish=True)
    return grid


def prepare(root: Path) -> None:
    """The folders the fake grid writes to (its commands do not create them)."""
    for task in TASKS:
        (root / "work" / task).mkdir(parents=True, exist_ok=True)


def results_of(root: Path) -> dict:
    """What a grid left: each result file's content, each task's timing labels (and anything left
    unfinished or repeated) and ledger lines."""
    out = {"files": {}, "timing": {}, "ledger": {}}
    for f in sorted((root / "results").rglob("*")):
        # the timing file's lock, and a replacement left half-written by a killed node (never read): no results
        if f.is_file() and f.name != timing.TIMING_FILE and not f.name.endswith(".lock") and ".json.tmp" not in f.name:
            out["files"][str(f.relative_to(root))] = f.read_text()
    for task in TASKS:
        ledger = root / "work" / task / "ledger.txt"
        out["ledger"][task] = ledger.read_text().splitlines() if ledger.exists() else []  # none: no step ran
        if not ledger.exists():
            continue
        record = json.loads((root / "results" / task / timing.TIMING_FILE).read_text())
        out["timing"][task] = {"steps": {k: {"seconds": v["seconds"], "pieces": v.get("pieces", 1)}
                                         for k, v in record["steps"].items()},
                               "repeats": record.get("repeats", {}), "unfinished": record.get(timing.UNFINISHED, {})}
    return out


NODE_MEMORY = 4 * 1024 ** 3  # what each node offers the steps (the largest asks 3 GiB): fixed, so that where
# the steps run does not depend on how much memory the machine has free when a node starts (busy machines
# gave the second node less than a step asks, and every step ran on the head)


def _cluster(n_nodes: int = 2):
    """A local cluster of ``n_nodes`` nodes of one CPU and :data:`NODE_MEMORY` each (the first its head) on
    127.0.0.1."""
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "memory": NODE_MEMORY})
    for _ in range(n_nodes - 1):
        cluster.add_node(num_cpus=1, memory=NODE_MEMORY)
    cluster.wait_for_nodes()
    return cluster


def _one_machine(fn):
    """``fn()`` on a Ray of this machine alone, as ``ray_grid.connect`` starts one, but offering
    :data:`NODE_MEMORY` per CPU whatever is free: started by ``connect`` itself, the node offers the memory
    free at its start, and on a busy machine (a grid beside the tests) that was less than a training step
    asks, so the grid refused to start (``ray_resources.check_fits``)."""
    import logging

    import ray

    ray.init(address="local", include_dashboard=False, num_cpus=2, _memory=2 * NODE_MEMORY,
             logging_level=logging.WARNING)
    try:
        return fn()
    finally:
        ray.shutdown()


def _in(root: Path, fn):
    """Run ``fn()`` with ``root`` as the working folder (a grid's relative paths are read from there)."""
    import os

    here = os.getcwd()
    root.mkdir(parents=True, exist_ok=True)
    os.chdir(root)
    try:
        return fn()
    finally:
        os.chdir(here)


def in_order(folder: Path) -> dict:
    """The tiny grid run one step after the other in this process, without Ray: what any run must leave."""
    prepare(folder)
    _in(folder, lambda: steps.run_in_order(fake_grid(), log=lambda m: None))
    return results_of(folder)


def two_nodes(folder: Path) -> dict:
    cluster = _cluster(2)
    report = {"nodes": [n.node_id for n in cluster.list_all_nodes()], "ips": [n.node_ip_address for n in
                                                                              cluster.list_all_nodes()]}
    logs = []
    t0 = time.time()
    for name in ("cluster", "failing"):
        prepare(folder / name)
    summary = _in(folder / "cluster", lambda: ray_grid.run_on_ray(
        fake_grid(), log=logs.append, address=cluster.address, log_dir=Path("logs"), heartbeat=5.0))
    report["cluster_seconds"] = time.time() - t0
    report["placement"] = {f"{task}: {label}": node for (task, label), node in summary["nodes"].items()}
    report["cluster"] = results_of(folder / "cluster")

    def failing():  # train read fails: its evaluation is not run, everything else is
        grid = fake_grid()
        for s in grid:
            if s.label == "train read" and s.task == "push_button":
                s.argv = [sys.executable, "-c", "print('the error'); raise SystemExit(3)"]
        try:
            ray_grid.run_on_ray(grid, log=logs.append, address=cluster.address, log_dir=Path("logs"))
        except steps.PipelineError as e:
            return str(e)
        return None

    report["failure"] = _in(folder / "failing", failing)
    report["failing"] = {k: v for k, v in results_of(folder / "failing").items() if k == "files"}
    cluster.shutdown()
    prepare(folder / "local")
    t0 = time.time()
    _in(folder / "local", lambda: _one_machine(lambda: ray_grid.run_on_ray(fake_grid(), log=logs.append,
                                                                           log_dir=Path("logs"))))
    report["local_seconds"] = time.time() - t0
    report["local"] = results_of(folder / "local")

    def with_deadline():  # push_button's train read priced at a day, the deadline an hour away
        grid = fake_grid()
        for s in grid:
            if s.task == "push_button" and s.label == "train read":
                s.seconds_left = lambda: 86400.0
        try:
            _one_machine(lambda: ray_grid.run_on_ray(grid, log=logs.append, log_dir=Path("logs"),
                                                     deadline=time.time() + 3600))
        except DeadlineError as e:
            return str(e)
        return None

    report["sigterm_kept"] = _sigterm_kept()
    prepare(folder / "deadline")
    report["deadline_error"] = _in(folder / "deadline", with_deadline)
    report["deadline"] = {k: v for k, v in results_of(folder / "deadline").items() if k in ("files", "ledger")}
    report["in_order"] = in_order(folder / "in_order")
    report["log"] = logs
    return report


def _sigterm_kept() -> bool:
    """Whether a SIGTERM handler set before an embedded Ray starts (the CLI's) still gets the signal."""
    import os
    import signal

    got = []
    old = signal.signal(signal.SIGTERM, lambda signum, frame: got.append(signum))
    ray, _ = ray_grid.connect(None)
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.5)
    finally:
        ray.shutdown()
        signal.signal(signal.SIGTERM, old)
    return got == [signal.SIGTERM]


def node_killed(folder: Path) -> dict:
    """The grid on two nodes; once a generation (3 s, resumed: its time so far kept every 0.5 s) has run
    1.25 s on the node the driver is not attached to, that node is killed."""
    import ray

    cluster = _cluster(2)
    root = folder / "grid"
    prepare(root)
    logs, report = [], {}
    killed = threading.Event()

    def kill_when_a_step_runs_there():
        driver = None
        while driver is None:
            time.sleep(0.1)
            node = ray._private.worker.global_worker.node if ray.is_initialized() else None
            driver = getattr(node, "unique_id", None)
        victim = next(n for n in cluster.worker_nodes if n.unique_id != driver) \
            if cluster.head_node.unique_id == driver else None
        report["victim"] = victim.node_id if victim else None
        if victim is None:  # the driver attached to the worker node: nothing to kill without killing it
            return
        while not killed.is_set():
            for log in sorted((root / "logs").rglob("*.log")):
                if victim.node_id in log.read_text() and "generate" in log.name:
                    time.sleep(1.25)  # between two heartbeats (every 0.5 s) of its run
                    report["killed_step"] = f"{log.parent.name}: {log.stem.replace('_', ' ')}"
                    report["killed_at"] = time.time()
                    cluster.remove_node(victim, allow_graceful=False)
                    killed.set()
                    return
            time.sleep(0.05)

    killer = threading.Thread(target=kill_when_a_step_runs_there, daemon=True)
    killer.start()
    t0 = time.time()
    summary = _in(root, lambda: ray_grid.run_on_ray(fake_grid(generate_seconds=3.0), log=logs.append,
                                                    address=cluster.address, log_dir=Path("logs"), heartbeat=0.5))
    report["seconds"] = time.time() - t0
    killed.set()
    report["placement"] = {f"{task}: {label}": node for (task, label), node in summary["nodes"].items()}
    report["nodes"] = [n.node_id for n in cluster.list_all_nodes()]
    report["grid"] = results_of(root)
    if report.get("killed_step"):
        task, _, label = report["killed_step"].partition(": ")
        report["killed_log"] = (root / "logs" / task / f"{label.replace(' ', '_')}.log").read_text()
    report["log"] = logs
    cluster.shutdown()
    report["in_order"] = in_order(folder / "in_order")
    return report


def real_steps(folder: Path, nodes: int = 2) -> dict:
    """``experiments.pipeline`` on a cluster of ``nodes`` nodes: reach_target, the deterministic regressor,
    tiny (5 steps: the two generations side by side where two nodes are free, then the replay, the
    training, the evaluation)."""
    cluster = _cluster(nodes)
    report = {"nodes": [n.node_id for n in cluster.list_all_nodes()]}
    tiny = ["steps=4", "batch=4", "ckpt_every=2", "log_every=2", "val_episodes=0"]
    argv = [sys.executable, "-m", "experiments.pipeline", "--tasks", "RT", "--methods", "deterministic",
            "--train-episodes", "8", "--test-episodes", "4", "--gen-batch", "4", "--media-episodes", "0",
            "--diagnose-below", "0", "--ray-address", cluster.address] + [a for s in tiny for a in ("--set", s)]
    (folder / "grid").mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    proc = subprocess.run(argv, cwd=folder / "grid", capture_output=True, text=True)
    report.update(seconds=time.time() - t0, returncode=proc.returncode, stdout=proc.stdout, stderr=proc.stderr[-5000:])
    cluster.shutdown()
    return report


if __name__ == "__main__":
    scenario, out, *more = sys.argv[1], Path(sys.argv[2]).resolve(), *sys.argv[3:]
    out.mkdir(parents=True, exist_ok=True)
    result = {"two_nodes": two_nodes, "node_killed": node_killed, "real_steps": real_steps}[scenario](
        out, *[int(x) for x in more])
    (out / "report.json").write_text(json.dumps(result, indent=1, default=str))
