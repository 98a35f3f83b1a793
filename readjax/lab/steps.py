"""A step of a grid: one command with a test for "done" on disk, and the whole of one step's run.

A :class:`Step` is a subprocess (its ``argv``) with a test for "done" on disk (``made``), what it
publishes once it exits 0 (``after``), the steps it ``needs`` finished first and the steps that use its
output (``users``: a step whose users are all finished is not needed). :func:`run_step` runs one
step wherever it is called (this process, or a Ray task on any node of a cluster,
:mod:`readjax.lab.ray_grid`): skipped if done, else its command, its output published and checked,
its wall clock and CPU time recorded (:mod:`readjax.lab.timing`). :func:`run_in_order` runs a list of
steps one after the other in this process (the tests' runner, with a stand-in for the commands).
``readjax.lab.pipeline`` plans the grid's steps; this module knows nothing of tasks, methods or datasets.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from readjax import _runtime
from readjax.lab.timing import eta, hms, load_average, record_piece, record_timing


def train_command(python: str, *, task: str, model: str, preset: str, name: str, data, out,
                  overrides=(), extra=()) -> list[str]:
    """The ``experiments.train`` process of one run (output quiet: its log is the step's log file).
    The one home of that command line, for the grid's and the sweep's trainings alike: ``overrides``
    are the ``--set`` fields of the run's recipe, ``extra`` other flags (``--stage``, ``--vae-from``)."""
    sets = [a for s in overrides for a in ("--set", s)]
    return [python, "-m", "experiments.train", "--task", task, "--model", model, "--preset", preset,
            "--name", name, "--data", str(Path(data)), "--out", str(Path(out)), "--quiet", *sets, *extra]


class PipelineError(RuntimeError):
    """A step failed, or a split's ground truth does not replay at 100 %."""


@dataclass
class Step:
    kind: str  # generate / verify / train / evaluate / media / choose
    task: str
    label: str
    argv: list[str]
    made: Callable[[], bool]  # whether its output is there
    after: Callable[[], None] = field(default=lambda: None)
    timing: Path | None = None  # the task's pipeline_timing.json, where its wall clock is recorded
    users: list["Step"] = field(default_factory=list)  # the steps that need its output (none: a final one)
    wanted: Callable[[], bool] = field(default=lambda: True)  # a final step run only on a condition
    # the steps that must be finished before this one starts (on Ray: the tasks whose results it takes);
    # the listed order respects them (``run_in_order``)
    needs: list["Step"] = field(default_factory=list)
    # how far a running step has got, for the periodic "running:" lines (a training: its stages' steps)
    progress: Callable[[], str] | None = None
    # a re-run continues the work of a stopped one (a training, from its checkpoints): the time of every
    # run of it adds up to its cost (``timing.record_piece``). A step that starts over does not: its
    # record is its last run's.
    resumes: bool = False
    # its own estimate of the seconds it has left (a training under way: its pace times the steps to its
    # cap), None where it has none; the ETA prices the step by it before any other step's time
    seconds_left: Callable[[], float | None] | None = None

    def run_name(self) -> str | None:
        """The run folder the step trains, evaluates or chooses for, read from its command (``--name`` of
        ``experiments.train``, ``--run`` of ``experiments.evaluate``, ``--run-name`` of
        ``experiments.choose``); None for a data step. Its timing record names it, so a grid's cost
        counts its own runs' steps."""
        for flag, last_part in (("--name", False), ("--run-name", False), ("--run", True)):
            if flag in self.argv[:-1]:
                value = self.argv[self.argv.index(flag) + 1]
                return Path(value).name if last_part else value
        return None

    def needed(self) -> bool:
        """Whether this step is wanted and, unless it is a final step, a step that uses its output is
        still to run."""
        return self.wanted() and (not self.users or not all(u.done() for u in self.users))

    def done(self) -> bool:
        """Its output is there, or nothing wants it."""
        return self.made() or not self.needed()

    def status(self) -> str:
        """``done`` (its output is there), ``skip`` (not needed: what it feeds is finished, or its
        condition does not hold) or ``todo``."""
        return "done" if self.made() else "skip" if not self.needed() else "todo"


# why a step that exited 0 may still not count as done, by kind (what ``Step.made`` checks)
MISSING = {
    "generate": "the split holds fewer kept episodes than asked",
    "verify": "the ground truth did not replay at 100 %",
    "train": "its finished marker was not written",
    "evaluate": "no record under results/ is the evaluation asked for: its method, N, start, images and "
                "refinement (update, rounds, or the run's choice file) on a test (or val) split whose replay is "
                "on record at 100 %; check result_record.is_eval against the record the log names",
    "media": "no rollout video was published",
    "choose": "no choice file over the grid's settings, N and val episodes, on a val split whose replay is on "
              "record at 100 % (readjax.lab.choice.finished_choice)",
}


def run_step(step: Step, runner=None, log_path: Path | None = None, heartbeat: float = 600.0,
             env: dict | None = None) -> dict:
    """Run one step here, unless it is done (its output there, or nothing wants it: checked now, as
    the steps it needs have just finished): its command, then its ``after``, then ``made`` must hold;
    its time goes to its task's timing record. Returns {"ran": bool, "status", "seconds"} and, for a step
    that ran, "cost": its recorded seconds, every run of a resumed one (what prices it elsewhere).

    The command runs as a child process that dies with this one (:func:`launch`; output appended to
    ``log_path``, else on this process's own), every ``heartbeat`` seconds its run so far kept as a piece
    of a resumed step's cost; ``runner(argv)`` (a ``CompletedProcess``) stands in for it in tests.
    A failure, a stop (KeyboardInterrupt: Ctrl-C, a cancelled Ray task) or a missing result keeps the
    run's piece and raises; nothing of it is recorded as finished."""
    if step.done():
        return {"ran": False, "status": step.status(), "seconds": 0.0}
    t0, load, cpu0 = time.time(), load_average(), _children_cpu()
    try:
        if runner is not None:
            code = runner(step.argv).returncode
        else:
            code = launch(step.argv, log_path, heartbeat, env=env,
                          on_beat=lambda seconds, cpu: record_piece(step, t0, seconds, cpu))
    except BaseException:  # stopped: the child is gone (``launch``), its run so far is a piece of its cost
        record_piece(step, t0, time.time() - t0, _children_cpu() - cpu0)
        raise
    cpu = _children_cpu() - cpu0  # the child was reaped here: the difference is its CPU time
    if code != 0:
        record_piece(step, t0, time.time() - t0, cpu)
        raise PipelineError(f"{step.task}: `{step.label}` failed (exit {code}){tail(log_path)}")
    step.after()
    if not step.made():
        record_piece(step, t0, time.time() - t0, cpu)
        why = MISSING.get(step.kind, "its output check failed")
        raise PipelineError(f"{step.task}: `{step.label}` ran but its result is not there ({why})")
    seconds = time.time() - t0
    cost = record_timing(step, seconds, load, cpu, started=t0)
    return {"ran": True, "status": "done", "seconds": seconds, "cost": cost}


def launch(argv: list[str], log_path: Path | None = None, heartbeat: float = 600.0, on_beat=None,
           env: dict | None = None) -> int:
    """Run ``argv`` to its end and return its exit status; its output appended to ``log_path`` (None:
    this process's own). On Linux the child is told to die with this process (``PR_SET_PDEATHSIG``):
    a Ray worker lost with its node takes its step's command with it, so a retry elsewhere never runs
    beside it. ``on_beat(seconds, cpu_seconds)`` every ``heartbeat`` seconds while it runs; ``env``:
    variables set for it, beside glibc's malloc tuning (``readjax._runtime.MALLOC_TUNABLES``). Any
    exception here (KeyboardInterrupt) stops the child before it is raised."""
    out = None
    if log_path is not None:
        log_path.parent.mkdir(parents=True, exist_ok=True)
        out = open(log_path, "a")
    parent = os.getpid()
    proc = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT if out else None,
                            env=_runtime.with_malloc_tunables({**os.environ, **(env or {})}),
                            preexec_fn=(lambda: _die_with(parent)) if sys.platform == "linux" else None)
    t0 = time.time()
    try:
        while True:
            try:
                return proc.wait(timeout=heartbeat)
            except subprocess.TimeoutExpired:
                if on_beat is not None:
                    on_beat(time.time() - t0, _process_cpu(proc.pid))
    except BaseException:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        raise
    finally:
        if out is not None:
            out.close()


def _die_with(parent: int) -> None:
    """In the child before it starts its command: SIGTERM when the parent dies (Linux)."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1: PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent died before the call
        os._exit(1)


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's children that have exited and been waited for:
    its difference across one child's reaping is that child's CPU time."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _process_cpu(pid: int) -> float | None:
    """CPU seconds (user + system, its waited-for children's included) of a running process, from
    ``/proc`` (Linux); None where it cannot be read (another platform, a process already gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    # after the command name: state is field 3; utime, stime, cutime, cstime are fields 14-17
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def step_log_path(log_dir: str | Path, step: Step) -> Path:
    """Where a step's output goes: LOG_DIR/<task>/<label as a file name>.log."""
    name = "".join(c if c.isalnum() or c in "-_." else "_" for c in step.label).strip("_")
    return Path(log_dir) / step.task / f"{name}.log"


def tail(path: Path | None, lines: int = 15) -> str:
    """The last ``lines`` of a step's log, indented (empty where there is none)."""
    if path is None or not Path(path).exists():
        return ""
    text = Path(path).read_text(errors="replace").splitlines()[-lines:]
    return "\n" + "\n".join("    " + ln for ln in text)


def run_in_order(steps: list[Step], log: Callable[[str], None] = print, runner=None,
                 prior: dict | None = None, on_finished: Callable[[Step], None] | None = None) -> dict:
    """Run the steps not yet done one after the other in their listed order, in this process
    (``runner``: see :func:`run_step`; output on this terminal), each line with the elapsed time and
    an ETA (``prior``: :func:`readjax.lab.timing.prior_costs`); ``on_finished(step)`` after each step
    that ran. The first failure stops the list. Returns {"ran": k, "skipped": s, "seconds": {kind: s}}.
    The grid and the sweeps run their steps on Ray (:mod:`readjax.lab.ray_grid`); this is their
    runner in tests, where a stand-in replaces the commands."""
    todo = [s for s in steps if not s.done()]
    skipped = len(steps) - len(todo)
    log(f"pipeline: {len(steps)} steps, {skipped} already done, {len(todo)} to run")
    by_kind: dict[str, list[float]] = {}
    by_label: dict[str, list[float]] = {}
    t_start, ran = time.time(), 0
    for k, step in enumerate(todo, 1):
        outcome = run_step(step, runner)
        if not outcome["ran"]:  # its condition no longer holds, or what it feeds finished meanwhile
            log(f"[{k}/{len(todo)}] {step.task}: {step.label}  (skipped: {outcome['status']})")
            skipped += 1
            continue
        ran += 1
        by_kind.setdefault(step.kind, []).append(outcome["cost"])  # a resumed step: every run of it
        by_label.setdefault(step.label, []).append(outcome["cost"])
        left = eta(todo[k:], by_label, by_kind, prior)
        log(f"[{k}/{len(todo)}] {step.task}: {step.label}  (done in {hms(outcome['seconds'])}, elapsed "
            f"{hms(time.time() - t_start)}{', ETA ' + hms(left) if left is not None else ''})")
        if on_finished is not None:
            on_finished(step)
    return {"ran": ran, "skipped": skipped, "seconds": {k: sum(v) for k, v in by_kind.items()}}
