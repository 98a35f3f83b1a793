"""One step's run (skipped if done, its command, its output checked, its time recorded) and the
in-order runner; each step's wall clock and CPU time recorded beside the task's results."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from readjax.lab import cost_table, steps, timing


def _timing(tmp_path):
    return tmp_path / "results" / "reach_target" / timing.TIMING_FILE


def test_a_steps_command_runs_as_a_process_with_its_own_log(tmp_path):
    """A step's output is appended to its log file; a step that is done is skipped, not run."""
    out = tmp_path / "out"
    step = steps.Step("generate", "reach_target", "make a", [sys.executable, "-c", f"print('made a'); open(r'{out}', 'w')"],
                      made=out.exists)
    log = steps.step_log_path(tmp_path / "logs", step)
    assert log == tmp_path / "logs" / "reach_target" / "make_a.log"
    assert steps.run_step(step, log_path=log)["ran"] and log.read_text() == "made a\n"
    assert steps.run_step(step, log_path=log) == {"ran": False, "status": "done", "seconds": 0.0}
    failing = steps.Step("train", "reach_target", "fail", [sys.executable, "-c", "print('the error'); raise SystemExit(3)"],
                         made=lambda: False)
    with pytest.raises(steps.PipelineError, match="(?s)`fail` failed \\(exit 3\\).*the error"):
        steps.run_step(failing, log_path=tmp_path / "fail.log")


def test_a_steps_command_dies_with_the_process_that_runs_it(tmp_path):
    """A Ray worker lost with its node takes its step's command with it (PR_SET_PDEATHSIG), so a retry
    elsewhere never runs beside a leftover of the lost try."""
    child_pid = tmp_path / "child.pid"
    code = ("import sys; from readjax.lab.steps import launch; "
            f"launch([sys.executable, '-c', \"import os, time; open(r'{child_pid}', 'w').write(str(os.getpid())); "
            "time.sleep(120)\"])")
    parent = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.time() + 120
    while not child_pid.exists() or not child_pid.read_text():
        assert time.time() < deadline and parent.poll() is None
        time.sleep(0.1)
    pid = int(child_pid.read_text())
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.time() + 10
    while _alive(pid):
        assert time.time() < deadline, "the step's command outlived the process that ran it"
        time.sleep(0.1)


def _alive(pid: int) -> bool:
    try:
        state = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited (its parent, gone, no longer reaps it)


def test_a_steps_cpu_time_is_recorded_beside_its_wall_clock(tmp_path):
    """The timing record holds the step process's CPU time: a step that computes records about its
    work, one that waits records far less than its wall clock (a pause or a job beside it inflates
    the wall clock, not the CPU time)."""
    busy = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.6: pass"
    todo = [steps.Step("train", "reach_target", name, [sys.executable, "-c", code + f"\nopen(r'{tmp_path / name}', 'w')"],
                       made=(tmp_path / name).exists, timing=_timing(tmp_path))
            for name, code in (("busy", busy), ("idle", "import time; time.sleep(1.5)"))]
    steps.run_in_order(todo, log=lambda m: None)
    rec = json.loads(_timing(tmp_path).read_text())["steps"]
    assert rec["busy"]["cpu_seconds"] >= 0.5
    assert rec["idle"].get("cpu_seconds", 0.0) < 0.5 * rec["idle"]["seconds"]
    row = next(ln for ln in cost_table.cost_lines(tmp_path / "results") if ln.startswith("| RT"))
    cpu = rec["busy"]["cpu_seconds"] + rec["idle"].get("cpu_seconds", 0.0)
    share = "" if "cpu_seconds" in rec["idle"] else " (1/2)"
    assert f" | {cpu / 60:.1f}{share} | " in row


def _busy_step(tmp_path, name: str, seconds: float, resumes: bool) -> steps.Step:
    """A step that computes for ``seconds`` of CPU time, then marks itself done."""
    code = (f"import time\nt = time.process_time()\nwhile time.process_time() - t < {seconds}: pass\n"
            f"open(r'{tmp_path / name}', 'w')")
    return steps.Step("train", "reach_target", name, [sys.executable, "-c", code], made=(tmp_path / name).exists,
                      timing=_timing(tmp_path), resumes=resumes)


def _stopped_after(seconds: float, step: steps.Step, heartbeat: float) -> None:
    """Run ``step`` and stop it with a KeyboardInterrupt after ``seconds`` (Ctrl-C, a cancelled Ray task)."""
    import _thread
    import threading

    # interrupt_main() does nothing while SIGINT is ignored or left to the OS, as something earlier in the same
    # pytest-xdist worker may have set it (twice in fresh-clone runs, DID NOT RAISE): Python's own handler here
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(seconds, _thread.interrupt_main)  # as Ctrl-C, or Ray's cancel of a task
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            steps.run_step(step, heartbeat=heartbeat)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, handler)


def test_a_resumed_steps_record_adds_the_time_of_its_every_run(tmp_path):
    """A training stopped (Ctrl-C, a cancelled task) and finished by a later run is recorded with the
    time of both runs; a step that starts over keeps its last run's only. While it runs, a heartbeat
    keeps its run so far (what a node lost without a word leaves)."""
    resumed, restarted = _busy_step(tmp_path, "resumed", 1.0, resumes=True), _busy_step(tmp_path, "restarted", 1.0, False)
    for step in (resumed, restarted):
        _stopped_after(0.8, step, heartbeat=0.3)
    assert not resumed.made() and not restarted.made()
    pieces = json.loads(_timing(tmp_path).read_text())[timing.UNFINISHED]
    assert list(pieces) == ["resumed"]  # a step that starts over leaves no piece
    (first,) = pieces["resumed"].values()  # the heartbeat's pieces of one run: one, under its start
    assert first["seconds"] >= 0.7 and first["cpu_seconds"] > 0
    outcomes = [steps.run_step(step, heartbeat=0.2) for step in (resumed, restarted)]
    record = json.loads(_timing(tmp_path).read_text())
    assert timing.UNFINISHED not in record  # this run's own heartbeat pieces are not counted twice
    done, again = record["steps"]["resumed"], record["steps"]["restarted"]
    assert done["pieces"] == 2 and "pieces" not in again  # the restarted one's lost run is not its cost
    assert done["seconds"] >= first["seconds"] + 0.9 and done["cpu_seconds"] >= first["cpu_seconds"] + 0.9
    # what prices the same step elsewhere is its whole cost (its CPU time where recorded), not its last run's
    assert outcomes[0]["cost"] == timing.price(done) == done["cpu_seconds"] >= first["cpu_seconds"] + 0.9
    assert outcomes[1]["cost"] == timing.price(again)
    assert timing.price({"seconds": 90.0, "cpu_seconds": 60.0}) == 60.0 and timing.price({"seconds": 90.0}) == 90.0


def test_the_in_order_runner_records_the_piece_of_a_stopped_resumed_step(tmp_path):
    """The same bookkeeping where a stand-in runs the command: the run that Ctrl-C stopped is a piece."""
    step = _busy_step(tmp_path, "resumed", 0.3, resumes=True)

    def stopped(argv):
        time.sleep(0.1)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        steps.run_in_order([step], log=lambda m: None, runner=stopped)
    finished = []
    steps.run_in_order([step], log=lambda m: None, on_finished=finished.append)
    record = json.loads(step.timing.read_text())
    assert record["steps"]["resumed"]["pieces"] == 2 and timing.UNFINISHED not in record
    assert record["steps"]["resumed"]["seconds"] >= 0.1 + 0.3 and finished == [step]


def test_a_step_that_exits_0_without_its_result_stops_the_grid_saying_what_is_missing(tmp_path):
    """An evaluation whose record does not match what the step asked for is named as such (not as a
    failed replay, the verify step's reason)."""
    step = steps.Step("evaluate", "reach_target", "evaluate x", [sys.executable, "-c", "pass"], made=lambda: False)
    with pytest.raises(steps.PipelineError, match=r"evaluate x` ran but its result is not there \(no record"):
        steps.run_in_order([step], log=lambda m: None)


def test_the_train_command_is_one_that_experiments_train_reads_back_field_for_field():
    """The grid and the sweep start their trainings through ``train_command``: what it writes must be
    what ``experiments.train`` parses, each ``--set`` kept in order and the extra flags passed on."""
    from experiments import train

    argv = steps.train_command("py", task="RT", model="read", preset="cpu", name="table7/K3_L0.5_T2",
                               data="d", out="o", overrides=["retrieval.k=3", "refine.N=10"],
                               extra=["--vae-from", "o/RT/ref", "--stage", "read"])
    assert argv[:3] == ["py", "-m", "experiments.train"]
    args = train.parser().parse_args(argv[3:])
    assert (args.task, args.model, args.preset, args.name, args.data, args.out) == (
        "RT", "read", "cpu", "table7/K3_L0.5_T2", "d", "o")
    assert args.set == ["retrieval.k=3", "refine.N=10"]
    assert (args.vae_from, args.stage, args.quiet) == ("o/RT/ref", "read", True)


def _record_many(timing_file: str, prefix: str, n: int) -> None:
    """A second grid's process: ``n`` steps of one task finishing, each recorded in the shared file."""
    from pathlib import Path

    for k in range(n):
        step = steps.Step("evaluate", "reach_target", f"{prefix} {k}", [], made=lambda: True, timing=Path(timing_file))
        timing.record_timing(step, float(k), None)


def test_steps_finishing_side_by_side_lose_no_timing_record(tmp_path):
    """Steps of one task finishing at once (on several nodes, or two grids on one task) write the same
    ``pipeline_timing.json``: each read-modify-write holds a lock and replaces the file whole, so no
    step's record is lost to the other's write and no reader ever sees a half-written file."""
    import multiprocessing as mp

    n = 60
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_record_many, args=(str(_timing(tmp_path)), p, n)) for p in ("a", "b", "c")]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0, 0, 0]  # a reader that met a half-written file would raise
    recorded = json.loads(_timing(tmp_path).read_text())["steps"]
    assert sorted(recorded) == sorted(f"{p} {k}" for p in "abc" for k in range(n))
    assert not list(_timing(tmp_path).parent.glob("*.tmp*"))  # no temporary file left behind
    assert os.path.exists(str(_timing(tmp_path)) + ".lock")


def test_a_timing_record_names_its_run_and_suite_and_the_grid_cost_counts_its_own_runs(tmp_path):
    """Each record says which run the step worked for (read from its command) and the tasks' suite; the
    grid's cost table sums the grid's runs and the suite's data steps, a later run of a label included,
    and leaves out other runs and other suites."""
    from readjax import tasks

    def step(label, kind, argv):
        return steps.Step(kind, "reach_target", label, ["python", "-m", *argv], made=lambda: True,
                          timing=_timing(tmp_path))

    train = step("train read", "train", steps.train_command("python", task="reach_target", model="read", preset="cpu",
                                                             name="read_s2", data="data", out="runs")[2:])
    evaluate = step("evaluate read --N 100", "evaluate", ["experiments.evaluate", "--run", "runs/reach_target/read_s2"])
    choose = step("choose read's refinement", "choose", ["experiments.choose", "--task", "reach_target", "--run-name",
                                                          "read_s2"])
    other = step("train read_o", "train", ["experiments.train", "--name", "read_o"])
    data = step("generate val 100", "generate", ["experiments.generate", "--split", "val"])
    assert [s.run_name() for s in (train, evaluate, choose, other, data)] == ["read_s2"] * 3 + ["read_o", None]
    for s, seconds, cpu in ((train, 3600.0, 1800.0), (evaluate, 360.0, 180.0), (choose, 36.0, 36.0),
                            (other, 7200.0, 7200.0), (data, 720.0, 360.0), (train, 1800.0, 900.0)):
        timing.record_timing(s, seconds, None, cpu)
    record = json.loads(_timing(tmp_path).read_text())
    assert record["steps"]["train read"]["run"] == "read_s2" and record["steps"]["generate val 100"]["run"] is None
    assert {e["suite"] for e in record["steps"].values()} == {tasks.SUITE_VERSION}
    assert len(record["repeats"]["train read"]) == 1  # a second training of the label: kept, and counted
    lines = cost_table.grid_cost_lines(tmp_path / "results", ["read_s2", "det_s2"], tasks.SUITE_VERSION)
    assert "| RT | 2 | 0.20 | 1.50 | 0.11 | 1.81 | 0.91 |" in lines  # read_o's 2 h are not the grid's
    assert cost_table.grid_cost_lines(tmp_path / "results", ["read_s2"], tasks.SUITE_VERSION - 1) == []
    # the per-label table of one suite's steps: this suite's records, none of an older suite's
    assert any(ln.startswith("| RT |") for ln in cost_table.cost_lines(tmp_path / "results", suite=tasks.SUITE_VERSION))
    assert cost_table.cost_lines(tmp_path / "results", suite=tasks.SUITE_VERSION - 1) == []


def test_steps_are_priced_from_records_made_with_the_same_malloc_where_there_are_any(tmp_path):
    """Records from before glibc's malloc was tuned (no "malloc" field: "system") price a step only
    where no record of the same kind of process exists; either kind prices a key the other lacks."""
    import json

    from readjax.lab import timing

    entry = lambda s, **kw: {"kind": "train", "seconds": s, "run": "read_s2", **kw}  # noqa: E731
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / timing.TIMING_FILE).write_text(json.dumps({"task": "a", "steps": {
        "train read": entry(4000.0), "evaluate read": dict(entry(100.0), kind="evaluate")},
        "repeats": {"train read": [entry(5000.0), entry(2500.0, malloc="tuned")]}}))
    tuned, system = timing.prior_costs(tmp_path, "tuned"), timing.prior_costs(tmp_path, "system")
    assert tuned["label"]["train read"] == [2500.0] and tuned["run"]["read_s2: train read"] == [2500.0]
    assert system["label"]["train read"] == [4000.0, 5000.0] and tuned["kind"]["train"] == [2500.0]
    assert tuned["label"]["evaluate read"] == [100.0]  # none tuned yet: every record
    assert timing.malloc_setting({}) == "tuned" and timing.malloc_setting({"READJAX_MALLOC": "system"}) == "system"
