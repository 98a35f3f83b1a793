"""The step runner: steps run in order or J at once, each after what it needs, with their own logs;
each step's wall clock and CPU time recorded beside the task's results."""

from __future__ import annotations

import json
import sys

import pytest

from readjax import report, scheduler


def test_parallel_steps_run_as_processes_with_their_own_logs(tmp_path):
    """The default starter: real processes, each step's output in its own log file."""
    out = tmp_path / "out"
    out.mkdir()
    first = scheduler.Step("generate", "reach_target", "make a", [sys.executable, "-c", f"print('made a'); open(r'{out}/a', 'w')"],
                           made=(out / "a").exists)
    second = [scheduler.Step("train", "reach_target", f"use a {k}", [
        sys.executable, "-c", f"import os, time; assert os.path.exists(r'{out}/a'); time.sleep(0.2); "
                              f"print('used'); open(r'{out}/b{k}', 'w')"],
        made=(out / f"b{k}").exists, needs=[first]) for k in range(3)]
    first.users = second
    lines = []
    summary = scheduler.run_steps([first, *second], log=lines.append, jobs=2, log_dir=tmp_path / "logs", poll=0.05)
    assert summary["ran"] == 4 and all((out / f"b{k}").exists() for k in range(3))
    assert (tmp_path / "logs" / "reach_target" / "make_a.log").read_text() == "made a\n"
    assert (tmp_path / "logs" / "reach_target" / "use_a_2.log").read_text() == "used\n"
    with pytest.raises(ValueError, match="jobs"):
        scheduler.run_steps([first], jobs=0)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_steps_cpu_time_is_recorded_beside_its_wall_clock(tmp_path, jobs):
    """The timing record holds the step process's CPU time: a step that computes records about its
    work, one that waits records far less than its wall clock (a pause or a job beside it inflates
    the wall clock, not the CPU time)."""

    timing = tmp_path / "results" / "reach_target" / scheduler.TIMING_FILE
    busy = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.6: pass"
    steps = [scheduler.Step("train", "reach_target", name, [sys.executable, "-c", code + f"\nopen(r'{tmp_path / name}', 'w')"],
                            made=(tmp_path / name).exists, timing=timing)
             for name, code in (("busy", busy), ("idle", "import time; time.sleep(1.5)"))]
    scheduler.run_steps(steps, log=lambda m: None, jobs=jobs, log_dir=tmp_path / "logs", poll=0.05)
    rec = json.loads(timing.read_text())["steps"]
    assert rec["busy"]["cpu_seconds"] >= 0.5
    assert rec["idle"].get("cpu_seconds", 0.0) < 0.5 * rec["idle"]["seconds"]
    row = next(ln for ln in report.cost_lines(tmp_path / "results") if ln.startswith("| RT"))
    cpu = rec["busy"]["cpu_seconds"] + rec["idle"].get("cpu_seconds", 0.0)
    share = "" if "cpu_seconds" in rec["idle"] else " (1/2)"
    assert f" | {cpu / 60:.1f}{share} | " in row
