"""Running a list of dependent steps, each one command: in order, or up to J at once.

A :class:`Step` is a subprocess (its ``argv``) with a test for "done" on disk (``made``), what it
publishes once it exits 0 (``after``), the steps it ``needs`` finished first and the steps that use its
output (``users``: a step whose users are all finished is not needed). :func:`run_steps` runs the
steps not done, one after the other or ``jobs`` at once (each started as soon as what it needs is
finished, from the task with the fewest running steps first), with progress lines and an ETA priced
from earlier runs, and records each step's wall clock and CPU time beside the task's results
(``pipeline_timing.json``, read by the report's cost table); a step that ``resumes`` (a training)
is recorded with the time of every run it took, across stops and sessions. ``readjax.pipeline``
plans the grid's steps; this module knows nothing of tasks, methods or datasets.
"""

from __future__ import annotations

import json
import os
import platform
import resource
import subprocess
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

from readjax import atomic_write

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; one grid per task there
    fcntl = None


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
    kind: str  # generate / verify / train / evaluate / media
    task: str
    label: str
    argv: list[str]
    made: Callable[[], bool]  # whether its output is there
    after: Callable[[], None] = field(default=lambda: None)
    timing: Path | None = None  # the task's pipeline_timing.json, where its wall clock is recorded
    users: list["Step"] = field(default_factory=list)  # the steps that need its output (none: a final one)
    wanted: Callable[[], bool] = field(default=lambda: True)  # a final step run only on a condition
    # the steps that must be finished before this one starts (``run_steps`` with jobs > 1; one job
    # runs the steps in their listed order, which respects these)
    needs: list["Step"] = field(default_factory=list)
    # how far a running step has got, for the periodic "running:" lines (a training: its stages' steps)
    progress: Callable[[], str] | None = None
    # a re-run continues the work of a stopped one (a training, from its checkpoints): the time of every
    # run of it adds up to its cost (``record_piece``). A step that starts over does not: its record is
    # its last run's.
    resumes: bool = False
    # its own estimate of the seconds it has left (a training under way: its pace times the steps to its
    # cap), None where it has none; the ETA prices the step by it before any other step's time
    seconds_left: Callable[[], float | None] | None = None

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


TIMING_FILE = "pipeline_timing.json"


def record_timing(step: Step, seconds: float, load: float | None, cpu_seconds: float | None = None,
                  started: float | None = None) -> None:
    """Add a finished step's wall clock to its task's ``pipeline_timing.json`` (committed beside the
    results, read by ``experiments.report``): seconds, when, and the machine's core count and load
    average when it started (2-core timings beside another job are not idle-machine timings).
    A step that ran before under the same label (the same task regenerated on another machine, a
    replicate grid) keeps its first record, which the cost table reads: the cost of producing the
    task's results once; later runs are appended under ``repeats``, never overwriting it.
    ``cpu_seconds``: the CPU time (user + system) of the step's process, which neither another job
    beside it nor a pause (a stopped process) inflates as they do the wall clock.
    A step that ``resumes`` adds the earlier runs' pieces (:func:`record_piece`) to its seconds and CPU
    seconds and counts its runs in ``pieces``; ``started`` (its run's start, ``time.time()``) tells this
    run's own heartbeat piece from them."""
    if step.timing is None:
        return
    _update_timing(step, lambda record: _add_finished(record, step, seconds, load, cpu_seconds, started))


def _add_finished(record: dict, step: Step, seconds: float, load: float | None, cpu_seconds: float | None,
                  started: float | None) -> None:
    """:func:`record_timing`'s change to the task's timing record (in place)."""
    entry = {"kind": step.kind, "seconds": round(seconds, 1), "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
             "cpus": os.cpu_count(), "load_at_start": load, "platform": platform.platform()}
    earlier = record.get(UNFINISHED, {}).pop(step.label, {})
    earlier.pop(_piece_key(started), None)  # this run's own heartbeat piece: counted in ``seconds``
    if not record.get(UNFINISHED):
        record.pop(UNFINISHED, None)
    if step.resumes and earlier:
        entry["seconds"] = round(seconds + sum(p["seconds"] for p in earlier.values()), 1)
        cpu_seconds = (cpu_seconds or 0.0) + sum(p.get("cpu_seconds", 0.0) for p in earlier.values())
        entry["pieces"] = len(earlier) + 1
    if cpu_seconds:
        entry["cpu_seconds"] = round(cpu_seconds, 1)
    if step.label in record["steps"]:
        record.setdefault("repeats", {}).setdefault(step.label, []).append(entry)
    else:
        record["steps"][step.label] = entry


def _read_timing(step: Step) -> dict:
    """The step's task's timing file (an empty record before its first step)."""
    f = step.timing
    return json.loads(f.read_text()) if f.exists() else {"task": step.task, "steps": {}}


def _update_timing(step: Step, change: Callable[[dict], None]) -> None:
    """One read-modify-write of the task's timing file: under its lock (:func:`_timing_locked`), and
    replacing the file whole, so a reader sees the old record or the new one, never a half-written file."""
    with _timing_locked(step):
        record = _read_timing(step)
        change(record)
        atomic_write.write_text(step.timing, json.dumps(record, indent=2),
                                tmp_name=f"{step.timing.name}.tmp{os.getpid()}")


@contextmanager
def _timing_locked(step: Step):
    """Hold the task's timing file for one read-modify-write. Two grids may run on the same task (a
    second variant started beside a running grid); without the lock one's write would drop the
    other's record. The lock is ``flock`` on a sibling ``.lock`` file (not committed: see
    .gitignore), released when the process dies; where ``fcntl`` is missing (Windows) it is a no-op."""
    step.timing.parent.mkdir(parents=True, exist_ok=True)
    with open(step.timing.with_name(step.timing.name + ".lock"), "a") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            if fcntl is not None:
                fcntl.flock(lock, fcntl.LOCK_UN)


UNFINISHED = "unfinished"  # the timing file's pieces of steps that have not finished yet


def _piece_key(started: float | None) -> str:
    """A run's piece is keyed by when it started, in UTC to the microsecond."""
    return "" if started is None else datetime.fromtimestamp(started, timezone.utc).isoformat(timespec="microseconds")


def record_piece(step: Step, started: float, seconds: float, cpu_seconds: float | None) -> None:
    """A ``resumes`` step's run so far, kept under ``unfinished`` in its task's timing file (one piece
    per run, keyed by its start): written by the grid's heartbeat while it runs and when the grid is
    stopped (Ctrl-C, ``kill``, a session's end), so that its record, once it finishes in a later run,
    counts the time of every run (:func:`record_timing`). At most a heartbeat's time is missed when
    the grid dies without a word (``kill -9``, a machine gone)."""
    if step.timing is None or not step.resumes:
        return
    piece = {"seconds": round(seconds, 1), "kind": step.kind}
    if cpu_seconds:
        piece["cpu_seconds"] = round(cpu_seconds, 1)

    def add_piece(record: dict) -> None:
        record.setdefault(UNFINISHED, {}).setdefault(step.label, {})[_piece_key(started)] = piece

    _update_timing(step, add_piece)


def _process_cpu(proc) -> float | None:
    """CPU seconds (user + system, its waited-for children's included) of a running process, from
    ``/proc`` (Linux); None where it cannot be read (another platform, a process already gone)."""
    pid = getattr(proc, "pid", None)
    if pid is None:
        return None
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    # after the command name: state is field 3; utime, stime, cutime, cstime are fields 14-17
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def _load() -> float | None:
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:  # not on every platform
        return None


def timing_records(results: str | Path) -> dict[str, dict[str, dict]]:
    """Every task's recorded step timings under ``results`` (``<task>/pipeline_timing.json``, see
    :func:`record_timing`): {task: {label: record}}; unreadable files are skipped."""
    records = {}
    for f in sorted(Path(results).glob(f"*/{TIMING_FILE}")):
        try:
            record = json.loads(f.read_text())
            records[record["task"]] = record["steps"]
        except (json.JSONDecodeError, KeyError):
            continue
    return records


def prior_costs(results: str | Path) -> dict[str, dict[str, list[float]]]:
    """Seconds of steps finished before (:func:`timing_records`: other runs, sessions and
    machines): {"label": {...}, "kind": {...}}, for the ETA before this run has timed a step of its
    own."""
    prior: dict[str, dict[str, list[float]]] = {"label": {}, "kind": {}}
    for steps in timing_records(results).values():
        for label, st in steps.items():
            prior["label"].setdefault(label, []).append(st["seconds"])
            prior["kind"].setdefault(st["kind"], []).append(st["seconds"])
    return prior


def run_steps(steps: list[Step], log: Callable[[str], None] = print, runner=subprocess.run,
              prior: dict[str, dict[str, list[float]]] | None = None, jobs: int = 1, start=None,
              log_dir: str | Path | None = None, poll: float = 1.0, heartbeat: float = 600.0) -> dict:
    """Run the steps not yet done; returns {"ran": k, "skipped": s, "seconds": {...}}. Progress and
    an ETA (:func:`_eta`; ``prior``: :func:`prior_costs`) go to ``log``.

    ``jobs`` = 1 runs them one after the other in their listed order (``runner``, its output on this
    terminal). ``jobs`` > 1 keeps up to that many running at once (``start(argv, log_path)`` returns
    a process with ``poll()``; default ``subprocess.Popen``), each started once every step it
    ``needs`` is finished, from the task with the fewest running steps first, in listed order otherwise:
    a GPU holds a dozen trainings, a CPU two. Each
    step's output then goes to ``log_dir/<task>/<label>.log`` (None: this terminal, interleaved), and
    every ``heartbeat`` seconds a line says what is running, for how long and how far it has got.
    A failed step stops new starts; the running ones finish (and are kept) before the error."""
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    todo = [s for s in steps if not s.done()]
    skipped = len(steps) - len(todo)
    log(f"pipeline: {len(steps)} steps, {skipped} already done, {len(todo)} to run"
        + (f", up to {jobs} at once" if jobs > 1 else ""))
    if jobs > 1:
        return _run_parallel(todo, skipped, jobs, log, start or _popen, prior, log_dir, poll, heartbeat)
    by_kind: dict[str, list[float]] = {}  # seconds of finished steps, by kind and by label
    by_label: dict[str, list[float]] = {}
    t_start = time.time()
    ran = 0
    for k, step in enumerate(todo, 1):
        if step.done():  # finished meanwhile (another shard), or its condition no longer holds
            log(f"[{k}/{len(todo)}] {step.task}: {step.label}  (skipped: {step.status()})")
            skipped += 1
            continue
        ran += 1
        eta = _eta(todo[k - 1:], by_label, by_kind, prior)
        log(f"[{k}/{len(todo)}] {step.task}: {step.label}  (elapsed {hms(time.time() - t_start)}"
            f"{', ETA ' + hms(eta) if eta is not None else ''})")
        t0, load, cpu0 = time.time(), _load(), _children_cpu()
        try:
            proc = runner(step.argv)
        except KeyboardInterrupt:  # the grid stopped: the step's run so far is a piece of its cost
            record_piece(step, t0, time.time() - t0, _children_cpu() - cpu0)
            raise
        if proc.returncode != 0:
            record_piece(step, t0, time.time() - t0, _children_cpu() - cpu0)
            raise PipelineError(f"{step.task}: `{step.label}` failed (exit {proc.returncode}); fix it and "
                                f"re-run: finished steps are skipped")
        _finish(step, t0, load, by_kind, by_label, _children_cpu() - cpu0)
    return {"ran": ran, "skipped": skipped, "seconds": {k: sum(v) for k, v in by_kind.items()}}


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's children that have exited and been waited for:
    its difference across one child's reaping is that child's CPU time."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


# why a step that exited 0 may still not count as done, by kind (what ``Step.made`` checks)
MISSING = {
    "generate": "the split holds fewer kept episodes than asked",
    "verify": "the ground truth did not replay at 100 %",
    "train": "its finished marker was not written",
    "evaluate": "no record under results/ is the evaluation asked for: its method, N, start, images and "
                "refinement (update, rounds) on a test split whose replay is on record at 100 %; check "
                "result_record.is_eval against the record the log names",
    "media": "no rollout video was published",
}


def _finish(step: Step, t0: float, load: float | None, by_kind: dict, by_label: dict,
            cpu_seconds: float | None = None) -> None:
    """A step's command exited 0: publish its output (``after``), check it is there, record its time."""
    step.after()
    if not step.made():
        record_piece(step, t0, time.time() - t0, cpu_seconds)
        why = MISSING.get(step.kind, "its output check failed")
        raise PipelineError(f"{step.task}: `{step.label}` ran but its result is not there ({why})")
    seconds = time.time() - t0
    by_kind.setdefault(step.kind, []).append(seconds)
    by_label.setdefault(step.label, []).append(seconds)
    record_timing(step, seconds, load, cpu_seconds, started=t0)


def _popen(argv: list[str], log_path: Path | None):
    if log_path is None:
        return subprocess.Popen(argv)
    with open(log_path, "w") as out:  # the child keeps its own descriptor
        return subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT)


def step_log_path(log_dir: str | Path, step: Step) -> Path:
    """Where ``run_steps`` with jobs > 1 writes a step's output: LOG_DIR/<task>/<label as a file name>.log."""
    name = "".join(c if c.isalnum() or c in "-_." else "_" for c in step.label).strip("_")
    return Path(log_dir) / step.task / f"{name}.log"


def _tail(path: Path | None, lines: int = 15) -> str:
    if path is None or not path.exists():
        return ""
    text = path.read_text(errors="replace").splitlines()[-lines:]
    return "\n" + "\n".join("    " + ln for ln in text)


def _run_parallel(todo: list[Step], skipped: int, jobs: int, log, start, prior, log_dir, poll: float,
                  heartbeat: float = 600.0) -> dict:
    """``run_steps`` with up to ``jobs`` steps at once (see there)."""
    pending = list(todo)
    running: dict[int, tuple[Step, object, float, float | None, Path | None]] = {}  # id(step) -> ...
    try:
        return _schedule(todo, skipped, jobs, log, start, prior, log_dir, poll, pending, running, heartbeat)
    finally:  # an error or a kill of this process: stop the steps it started (each resumes when re-run)
        for step, proc, t0, *_ in running.values():
            if proc.poll() is None:
                record_piece(step, t0, time.time() - t0, _process_cpu(proc))
                proc.terminate()


def _schedule(todo, skipped, jobs, log, start, prior, log_dir, poll, pending, running, heartbeat=600.0) -> dict:
    by_kind: dict[str, list[float]] = {}
    by_label: dict[str, list[float]] = {}
    t_start, ran, failures, started = time.time(), 0, [], 0
    last_beat = time.time()

    def ready(step: Step) -> bool:
        waiting = {id(s) for s in pending} | set(running)
        return all(id(n) not in waiting and n.done() for n in step.needs)

    while pending or running:
        if not failures:
            while len(running) < jobs:
                candidates = [s for s in pending if ready(s)]
                if not candidates:
                    break
                # spread over the tasks (the task with the fewest steps running first), in listed order
                # otherwise: every task's READ trains before any task's baselines fill the slots
                busy = [s.task for s, *_ in running.values()]
                step = min(candidates, key=lambda s: busy.count(s.task))
                pending[:] = [s for s in pending if s is not step]  # by identity: Step's == compares fields
                started += 1
                if step.done():  # finished meanwhile (another shard), or its condition no longer holds
                    log(f"[{started}/{len(todo)}] {step.task}: {step.label}  (skipped: {step.status()})")
                    skipped += 1
                    continue
                path = None if log_dir is None else step_log_path(log_dir, step)
                if path is not None:
                    path.parent.mkdir(parents=True, exist_ok=True)
                eta = _eta(pending + [s for s, *_ in running.values()] + [step], by_label, by_kind, prior)
                log(f"[{started}/{len(todo)}] {step.task}: {step.label}  (started; {len(running) + 1} running, "
                    f"elapsed {hms(time.time() - t_start)}{', ETA ' + hms(eta / jobs) if eta is not None else ''}"
                    f"{', log ' + str(path) if path is not None else ''})")
                load = _load()
                running[id(step)] = (step, start(step.argv, path), time.time(), load, path)
                ran += 1
            if pending and not running:
                stuck = pending[0]
                raise PipelineError(f"{stuck.task}: `{stuck.label}` waits for steps that cannot finish: "
                                    + ", ".join(f"`{n.label}` ({n.status()})" for n in stuck.needs if not n.done()))
        elif not running:
            break
        finished, cpu, reaped_before = [], {}, _children_cpu()
        for k, v in running.items():
            if v[1].poll() is not None:  # reaped by this poll: the rusage difference is its CPU time
                finished.append((k, v))
                reaped = _children_cpu()
                cpu[k], reaped_before = reaped - reaped_before, reaped
        if not finished:
            if time.time() - last_beat >= heartbeat:
                last_beat = time.time()
                log(running_line(running.values(), pending, by_label, by_kind, prior, jobs, t_start))
                for step, proc, t0, *_ in running.values():  # kept should the grid die without a word
                    record_piece(step, t0, last_beat - t0, _process_cpu(proc))
            time.sleep(poll)
            continue
        for k, (step, proc, t0, load, path) in finished:
            del running[k]
            if proc.returncode != 0:
                record_piece(step, t0, time.time() - t0, cpu[k])
                failures.append(f"{step.task}: `{step.label}` failed (exit {proc.returncode}){_tail(path)}")
                log(f"failed  {step.task}: {step.label} (exit {proc.returncode}); waiting for the "
                    f"{len(running)} running step(s), starting no more")
                continue
            try:
                _finish(step, t0, load, by_kind, by_label, cpu[k])
            except PipelineError as e:
                failures.append(str(e))
                continue
            log(f"done    {step.task}: {step.label}  in {hms(time.time() - t0)}")
    if failures:
        raise PipelineError("; ".join(failures) + "\nfix it and re-run: finished steps are skipped")
    return {"ran": ran, "skipped": skipped, "seconds": {k: sum(v) for k, v in by_kind.items()}}


def running_line(running, pending, by_label, by_kind, prior, jobs: int, t_start: float) -> str:
    """The periodic line of a parallel grid: each running step, how long it has run and how far it has
    got (its ``progress``), and the ETA of the grid."""
    now = time.time()
    parts = []
    for step, _, t0, *_ in running:
        how_far = ""
        if step.progress is not None:
            try:
                how_far = f", {step.progress() or 'starting'}"
            except (OSError, ValueError, KeyError):  # a record half-written: the next line will have it
                pass
        parts.append(f"{step.task}: {step.label} ({hms(now - t0)}{how_far})")
    eta = _eta(list(pending) + [s for s, *_ in running], by_label, by_kind, prior)
    return (f"running  {'; '.join(parts)}  (elapsed {hms(now - t_start)}, {len(pending)} waiting"
            f"{', ETA ' + hms(eta / jobs) if eta is not None else ''})")


def _eta(remaining: list[Step], by_label: dict[str, list[float]], by_kind: dict[str, list[float]],
         prior: dict[str, dict[str, list[float]]] | None = None) -> float | None:
    """Seconds left: each remaining step at the mean time of the finished steps most like it, the
    first found of: this run's steps with its label (the same step on another task: "train read",
    "evaluate read --N 100"), earlier runs' with its label (``prior``), this run's of its kind,
    earlier runs' of its kind, and this run's of any kind. So a 35-minute READ training does not
    price a 7-minute regressor's, nor one training every verify. None before anything is known."""
    costs = [step_cost(s, by_label, by_kind, prior) for s in remaining]
    return None if any(c is None for c in costs) else sum(costs)


def step_cost(step: Step, by_label: dict[str, list[float]], by_kind: dict[str, list[float]],
              prior: dict[str, dict[str, list[float]]] | None = None) -> float | None:
    """One step's expected seconds, as :func:`_eta` prices it (its own ``seconds_left`` where it has
    one); None before anything is known."""
    if step.seconds_left is not None:
        try:
            own = step.seconds_left()
        except (OSError, ValueError, KeyError):  # a record half-written: price it as a step not begun
            own = None
        if own is not None:
            return own
    prior = prior or {"label": {}, "kind": {}}
    mean = lambda v: sum(v) / len(v)  # noqa: E731
    for table, key in ((by_label, step.label), (prior["label"], step.label), (by_kind, step.kind),
                       (prior["kind"], step.kind)):
        if table.get(key):
            return mean(table[key])
    known = [x for v in (*by_kind.values(), *prior["kind"].values()) for x in v]
    return mean(known) if known else None


def hms(seconds: float) -> str:
    """Seconds as H:MM:SS."""
    s = int(seconds)
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"
