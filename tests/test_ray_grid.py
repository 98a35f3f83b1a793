"""The grid on Ray, on local clusters whose every byte stays on loopback: each scenario
(tests/ray_cluster.py) runs in a private network namespace, where only 127.0.0.1 exists, and a private
PID namespace, so that whatever it starts (GCS, raylets, workers, the steps' commands) ends with it;
Ray's files go to a temporary folder of the test's own (RAY_TMPDIR). Needs root (CI runs as root) and
util-linux's ``unshare``; skipped elsewhere."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NAMESPACES = ["unshare", "--net", "--pid", "--fork", "--mount-proc"]


def _namespaces_work() -> bool:
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    try:
        return subprocess.run(NAMESPACES + ["ip", "link", "set", "lo", "up"], capture_output=True,
                              timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


pytestmark = [pytest.mark.timeout(1200),
              pytest.mark.skipif(not _namespaces_work(), reason="needs root and unshare (a private network namespace)")]


def _scenario(name: str, folder: Path, *args, timeout: float = 900) -> dict:
    """Run tests/ray_cluster.py's scenario ``name`` in its own network and PID namespaces; its report."""
    ray_tmp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths must fit 107 bytes
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    env["RAY_TMPDIR"] = ray_tmp
    command = f"ip link set lo up && {sys.executable} -m tests.ray_cluster {name} {folder} " + " ".join(map(str, args))
    try:
        proc = subprocess.run(NAMESPACES + ["bash", "-c", command], cwd=ROOT, env=env, capture_output=True,
                              text=True, timeout=timeout)
    finally:
        shutil.rmtree(ray_tmp, ignore_errors=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-6000:]
    return json.loads((folder / "report.json").read_text())


def _one_record_per_step(record: dict, labels) -> None:
    """Each task's timing record: every step once, none repeated, nothing left unfinished."""
    for task, rec in record["timing"].items():
        assert sorted(rec["steps"]) == sorted(labels), task
        assert rec["repeats"] == {} and rec["unfinished"] == {}, task


def test_a_two_node_cluster_runs_the_grid_as_an_embedded_ray_does(tmp_path):
    """A local cluster of two nodes (one CPU each) runs a tiny grid end to end, both nodes running
    steps, each after the steps it needs; its results equal those of the same grid on an embedded Ray
    (no address) and those of the steps run one after the other without Ray. A failing step fails the
    steps that need it, and only those: the rest of the grid runs and the error names both. With a deadline, a
step that would end after it with the steps that need it is not started, nor are those steps."""
    report = _scenario("two_nodes", tmp_path)
    assert report["ips"] == ["127.0.0.1", "127.0.0.1"]  # every byte on loopback
    assert set(report["placement"].values()) == set(report["nodes"])  # both nodes ran steps
    labels = {s.split(": ")[1] for s in report["placement"]}
    assert len(report["placement"]) == 14
    expected = report["in_order"]
    for run in ("cluster", "local"):
        assert report[run]["files"] == expected["files"] and len(expected["files"]) == 4
        _one_record_per_step(report[run], labels)
        for task, ledger in report[run]["ledger"].items():  # each step ran once, after what it needs
            assert sorted(ledger) == sorted(f"{w} {label}" for label in labels for w in ("start", "done"))
            assert ledger.index("done generate test") < ledger.index("start verify test") < \
                ledger.index("done verify test") < ledger.index("start train read") < ledger.index("start evaluate read")
    assert "push_button: `train read` failed (exit 3)" in report["failure"] and "the error" in report["failure"]
    assert "push_button: `evaluate read` not run: it needs `train read`, which failed" in report["failure"]
    assert sorted(report["failing"]["files"]) == sorted(f for f in expected["files"] if f != "results/push_button/evaluate_read")
    assert report["sigterm_kept"]  # `kill` reaches the CLI's handler, which stops the steps under way
    # with a deadline closer than one task's training: nothing of that task starts (what it would make lands only
    # with the steps that need it), the other task runs whole
    assert report["deadline_error"].startswith("7 steps not started: they would end after the deadline")
    assert sorted(report["deadline"]["files"]) == sorted(f for f in expected["files"] if "reach_target" in f)
    assert report["deadline"]["ledger"]["push_button"] == []
    assert sorted(report["deadline"]["ledger"]["reach_target"]) == sorted(report["local"]["ledger"]["reach_target"])


def test_a_node_lost_during_a_step_loses_that_step_only(tmp_path):
    """The node running a generation is killed 1.25 s into it: Ray runs the step again on the node left
    (its command died with its worker), the grid finishes, and results/ and the timing records hold
    every step once: the lost step's record counts both its runs (its heartbeat kept the first one's
    time), and nothing else ran twice."""
    report = _scenario("node_killed", tmp_path)
    assert report["victim"], "the driver attached to the worker node: there was no node to kill"
    killed = report["killed_step"]
    task, label = killed.split(": ")
    assert report["grid"]["files"] == report["in_order"]["files"]
    labels = {s.split(": ")[1] for s in report["placement"]}
    _one_record_per_step(report["grid"], labels)
    assert report["grid"]["timing"][task]["steps"][label]["pieces"] == 2
    for t, ledger in report["grid"]["ledger"].items():
        assert sorted(ln for ln in ledger if ln.startswith("done")) == sorted(f"done {lb}" for lb in labels)
        assert ledger.count(f"start {label}") == (2 if t == task else 1)
    runs = [ln for ln in report["killed_log"].splitlines() if ln.startswith("===")]
    assert len(runs) == 2 and report["victim"] in runs[0] and report["victim"] not in runs[1]
    assert report["placement"][killed] != report["victim"]


@pytest.mark.slow
def test_the_pipeline_command_runs_real_steps_on_a_two_node_cluster(tmp_path):
    """``experiments.pipeline --ray-address`` on a local two-node cluster: reach_target's test and
    training splits generated side by side, one on each node, then its replay, a tiny training of the
    regressor and its evaluation, each published to results/ (about 3 CPU minutes, most of it XLA
    compiling the steps' programs)."""
    report = _scenario("real_steps", tmp_path)
    assert report["returncode"] == 0, report["stderr"]
    out = report["stdout"]
    assert "pipeline: ran 5 steps, skipped 0" in out
    ran_on = {ln.split(" on node 127.0.0.1 ")[1].split()[0] for ln in out.splitlines() if " on node " in ln}
    assert ran_on == {n[:8] for n in report["nodes"]}
    results = tmp_path / "grid" / "results" / "reach_target"
    record = json.loads((results / "deterministic" / "eval" / "direct.json").read_text())
    assert record["episodes"] == 4 and record["run"] == "runs/reach_target/deterministic"  # the grid's relative paths
    timing = json.loads((results / "pipeline_timing.json").read_text())
    assert len(timing["steps"]) == 5 and "repeats" not in timing
