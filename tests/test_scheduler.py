"""The step runner: steps run in order or J at once, each after what it needs, with their own logs;
each step's wall clock and CPU time recorded beside the task's results."""

from __future__ import annotations

import json
import sys
import time

import pytest

from readjax import cost_table, scheduler


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
    row = next(ln for ln in cost_table.cost_lines(tmp_path / "results") if ln.startswith("| RT"))
    cpu = rec["busy"]["cpu_seconds"] + rec["idle"].get("cpu_seconds", 0.0)
    share = "" if "cpu_seconds" in rec["idle"] else " (1/2)"
    assert f" | {cpu / 60:.1f}{share} | " in row


def _busy_step(tmp_path, name: str, seconds: float, resumes: bool) -> scheduler.Step:
    """A step that computes for ``seconds`` of CPU time, then marks itself done."""
    code = (f"import time\nt = time.process_time()\nwhile time.process_time() - t < {seconds}: pass\n"
            f"open(r'{tmp_path / name}', 'w')")
    return scheduler.Step("train", "reach_target", name, [sys.executable, "-c", code], made=(tmp_path / name).exists,
                          timing=tmp_path / "results" / "reach_target" / scheduler.TIMING_FILE, resumes=resumes)


def _stop_at_first_heartbeat(message: str) -> None:
    if message.startswith("running"):
        raise KeyboardInterrupt  # as the grid's SIGTERM handler does


def test_a_resumed_steps_record_adds_the_time_of_its_every_run(tmp_path):
    """A training stopped with the grid (Ctrl-C, kill, a session's end) and finished by a later run is
    recorded with the time of both runs; a step that starts over keeps its last run's only."""
    timing = tmp_path / "results" / "reach_target" / scheduler.TIMING_FILE
    steps = [_busy_step(tmp_path, "resumed", 1.0, resumes=True), _busy_step(tmp_path, "restarted", 1.0, resumes=False)]
    with pytest.raises(KeyboardInterrupt):
        scheduler.run_steps(steps, log=_stop_at_first_heartbeat, jobs=2, log_dir=tmp_path / "logs", poll=0.05,
                            heartbeat=0.5)
    assert not any(s.made() for s in steps)
    pieces = json.loads(timing.read_text())[scheduler.UNFINISHED]
    assert list(pieces) == ["resumed"]  # a step that starts over leaves no piece
    (first,) = pieces["resumed"].values()
    assert first["seconds"] >= 0.5 and first["cpu_seconds"] > 0
    scheduler.run_steps(steps, log=lambda m: None, jobs=2, log_dir=tmp_path / "logs", poll=0.05, heartbeat=0.2)
    record = json.loads(timing.read_text())
    assert scheduler.UNFINISHED not in record  # this run's own heartbeat pieces are not counted twice
    resumed, restarted = record["steps"]["resumed"], record["steps"]["restarted"]
    assert resumed["pieces"] == 2 and "pieces" not in restarted  # the restarted one's lost run is not its cost
    assert resumed["seconds"] >= first["seconds"] + 0.9 and resumed["cpu_seconds"] >= first["cpu_seconds"] + 0.9


def test_one_job_records_the_piece_of_a_stopped_resumed_step(tmp_path):
    """The same bookkeeping on the one-at-a-time path: the run that Ctrl-C stopped is a piece."""
    step = _busy_step(tmp_path, "resumed", 0.3, resumes=True)

    def stopped(argv):
        time.sleep(0.1)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        scheduler.run_steps([step], log=lambda m: None, runner=stopped)
    scheduler.run_steps([step], log=lambda m: None)
    record = json.loads(step.timing.read_text())
    assert record["steps"]["resumed"]["pieces"] == 2 and scheduler.UNFINISHED not in record
    assert record["steps"]["resumed"]["seconds"] >= 0.1 + 0.3


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_step_that_exits_0_without_its_result_stops_the_grid_saying_what_is_missing(tmp_path, jobs):
    """An evaluation whose record does not match what the step asked for is named as such (not as a
    failed replay, the verify step's reason)."""
    step = scheduler.Step("evaluate", "reach_target", "evaluate x", [sys.executable, "-c", "pass"],
                          made=lambda: False)
    with pytest.raises(scheduler.PipelineError, match=r"evaluate x` ran but its result is not there \(no record"):
        scheduler.run_steps([step], jobs=jobs, log_dir=tmp_path / "logs", poll=0.05)


def test_the_train_command_is_one_that_experiments_train_reads_back_field_for_field():
    """The grid and the sweep start their trainings through ``train_command``: what it writes must be
    what ``experiments.train`` parses, each ``--set`` kept in order and the extra flags passed on."""
    from experiments import train

    argv = scheduler.train_command("py", task="RT", model="read", preset="cpu", name="table7/K3_L0.5_T2",
                                   data="d", out="o", overrides=["retrieval.k=3", "refine.N=10"],
                                   extra=["--vae-from", "o/RT/ref", "--stage", "read"])
    assert argv[:3] == ["py", "-m", "experiments.train"]
    args = train.parser().parse_args(argv[3:])
    assert (args.task, args.model, args.preset, args.name, args.data, args.out) == (
        "RT", "read", "cpu", "table7/K3_L0.5_T2", "d", "o")
    assert args.set == ["retrieval.k=3", "refine.N=10"]
    assert (args.vae_from, args.stage, args.quiet) == ("o/RT/ref", "read", True)


def _record_many(timing: str, prefix: str, n: int) -> None:
    """A second grid's process: ``n`` steps of one task finishing, each recorded in the shared file."""
    from pathlib import Path

    for k in range(n):
        step = scheduler.Step("evaluate", "reach_target", f"{prefix} {k}", [], made=lambda: True,
                              timing=Path(timing))
        scheduler.record_timing(step, float(k), None)


def test_two_grids_on_one_task_lose_no_timing_record(tmp_path):
    """Two pipelines on the same task (a second variant started beside a running grid) write the same
    ``pipeline_timing.json``: each read-modify-write holds a lock and replaces the file whole, so no
    step's record is lost to the other's write and no reader ever sees a half-written file."""
    import multiprocessing as mp

    timing = tmp_path / "results" / "reach_target" / scheduler.TIMING_FILE
    n = 60
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_record_many, args=(str(timing), p, n)) for p in ("a", "b", "c")]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0, 0, 0]  # a reader that met a half-written file would raise
    steps = json.loads(timing.read_text())["steps"]
    assert sorted(steps) == sorted(f"{p} {k}" for p in "abc" for k in range(n))
    assert not list(timing.parent.glob("*.tmp*"))  # no temporary file left behind
