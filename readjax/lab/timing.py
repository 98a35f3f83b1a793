"""What each step of a grid cost, kept beside the task's results, and the ETA priced from it.

A finished step's wall clock and CPU time go to ``<results>/<task>/pipeline_timing.json`` (committed,
read by the report's cost table, :mod:`readjax.lab.cost_table`); a step that ``resumes`` (a training)
is recorded with the time of every run it took, across stops, sessions and lost nodes. Every change
is one read-modify-write under a lock, replacing the file whole: several steps of one task finish at
once on a cluster, and a reader never sees half a file. The same records price the steps still to
run (:func:`step_cost`, :func:`eta`). The step is anything with ``task``, ``label``, ``kind``,
``timing`` (the file, None: not recorded), ``resumes`` and ``seconds_left`` (:class:`readjax.lab.steps.Step`).
"""

from __future__ import annotations

import json
import os
import platform
import socket
import time
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

from readjax import _runtime, atomic_write, tasks

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; one grid per task there
    fcntl = None

TIMING_FILE = "pipeline_timing.json"
UNFINISHED = "unfinished"  # the timing file's pieces of steps that have not finished yet


def record_timing(step, seconds: float, load: float | None, cpu_seconds: float | None = None,
                  started: float | None = None) -> float:
    """Add a finished step's wall clock to its task's ``pipeline_timing.json`` (committed beside the
    results, read by ``experiments.report``): seconds, when, and the core count and load average of
    the machine that ran it when it started (2-core timings beside another job are not idle-machine
    timings). A step that ran before under the same label (the same task regenerated on another
    machine, a replicate grid) keeps its first record, which the cost table reads: the cost of
    producing the task's results once; later runs are appended under ``repeats``, never overwriting it.
    ``cpu_seconds``: the CPU time (user + system) of the step's process, which neither another job
    beside it nor a pause (a stopped process) inflates as they do the wall clock.
    A step that ``resumes`` adds the earlier runs' pieces (:func:`record_piece`) to its seconds and CPU
    seconds and counts its runs in ``pieces``; ``started`` (its run's start, ``time.time()``) tells this
    run's own heartbeat piece from them. Returns the step's :func:`price` as recorded: its whole cost,
    every run of a resumed one (what prices the same step elsewhere), ``seconds`` where nothing is recorded."""
    if step.timing is None:
        return seconds
    return _update_timing(step, lambda record: _add_finished(record, step, seconds, load, cpu_seconds, started))


def _add_finished(record: dict, step, seconds: float, load: float | None, cpu_seconds: float | None,
                  started: float | None) -> float:
    """:func:`record_timing`'s change to the task's timing record (in place); the entry's :func:`price`."""
    entry = {"kind": step.kind, "seconds": round(seconds, 1), "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
             "cpus": os.cpu_count(), "load_at_start": load, "platform": platform.platform(), "malloc": malloc_setting(),
             **_whose(step)}
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
    return price(entry)


def price(entry: dict) -> float:
    """What a recorded step costs a CPU slot: its CPU seconds where recorded, else its wall clock. The
    wall clock of a step beside other work, or paused, or resumed across sessions, counts time it did
    not use (a training recorded at 75 min of wall clock used 44 min of CPU); a step's process uses
    about one core when the grid keeps every core busy, so its CPU time is its time in a slot."""
    return entry.get("cpu_seconds") or entry["seconds"]


def record_piece(step, started: float, seconds: float, cpu_seconds: float | None) -> None:
    """A ``resumes`` step's run so far, kept under ``unfinished`` in its task's timing file (one piece
    per run, keyed by its start): written every heartbeat while it runs and when it is stopped
    (Ctrl-C, ``kill``, a cancelled task, a failure), so that its record, once it finishes in a later
    run, counts the time of every run (:func:`record_timing`). At most a heartbeat's time is missed
    when the step dies without a word (``kill -9``, a node gone)."""
    if step.timing is None or not step.resumes:
        return
    piece = {"seconds": round(seconds, 1), "kind": step.kind, **_whose(step)}
    if cpu_seconds:
        piece["cpu_seconds"] = round(cpu_seconds, 1)

    def add_piece(record: dict) -> None:
        record.setdefault(UNFINISHED, {}).setdefault(step.label, {})[_piece_key(started)] = piece

    _update_timing(step, add_piece)


def malloc_setting(env=None) -> str:
    """How the steps this process launches allocate: "tuned" (``readjax._runtime.MALLOC_TUNABLES``, what
    :func:`readjax.lab.steps.launch` gives them) or "system" (``READJAX_MALLOC=system``). A record without
    the field predates the tuning: "system" (READ's training steps ran 1.5-1.9x slower, BENCHMARKS 30)."""
    return "system" if _runtime.malloc_opted_out(os.environ if env is None else env) else "tuned"


def _whose(step) -> dict:
    """What a timing entry says the step worked for: its run (None: a data step) and the suite version of
    the tasks, so a grid's cost sums its own runs' steps (:func:`readjax.lab.cost_table.grid_cost_lines`)."""
    run_name = getattr(step, "run_name", None)
    return {"run": run_name() if callable(run_name) else None, "suite": tasks.SUITE_VERSION}


def _piece_key(started: float | None) -> str:
    """A run's piece is keyed by when it started, in UTC to the microsecond."""
    return "" if started is None else datetime.fromtimestamp(started, timezone.utc).isoformat(timespec="microseconds")


def _update_timing(step, change: Callable[[dict], object]):
    """One read-modify-write of the task's timing file: under its lock (:func:`_timing_locked`), and
    replacing the file whole, so a reader sees the old record or the new one, never a half-written file.
    The temporary file is named by process and host: two nodes of a cluster may share a process id.
    Returns what ``change`` returns."""
    with _timing_locked(step.timing):
        f = step.timing
        record = json.loads(f.read_text()) if f.exists() else {"task": step.task, "steps": {}}
        result = change(record)
        atomic_write.write_text(f, json.dumps(record, indent=2),
                                tmp_name=f"{f.name}.tmp{os.getpid()}.{socket.gethostname()}")
    return result


@contextmanager
def _timing_locked(timing: Path):
    """Hold a task's timing file for one read-modify-write: the steps of one task finish side by side
    (on a cluster, on several nodes; or two grids run on one task), and without the lock one's write
    would drop the other's record. The lock is ``flock`` on a sibling ``.lock`` file (not committed:
    see .gitignore), released when the process dies; NFS (v4, or v3 with lockd) carries it between
    nodes. Where ``fcntl`` is missing (Windows) it is a no-op."""
    timing.parent.mkdir(parents=True, exist_ok=True)
    with open(timing.with_name(timing.name + ".lock"), "a") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            if fcntl is not None:
                fcntl.flock(lock, fcntl.LOCK_UN)


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


def timing_entries(results: str | Path) -> dict[str, list[tuple[str, dict]]]:
    """Every finished run of every step under ``results``, the first (``steps``) and the later ones
    (``repeats``: the same step of a later grid, e.g. on another suite or another run of that label):
    {task: [(label, entry), ...]}; unreadable files are skipped."""
    out = {}
    for f in sorted(Path(results).glob(f"*/{TIMING_FILE}")):
        try:
            record = json.loads(f.read_text())
            out[record["task"]] = ([(label, e) for label, e in record["steps"].items()]
                                   + [(label, e) for label, es in record.get("repeats", {}).items() for e in es])
        except (json.JSONDecodeError, KeyError):
            continue
    return out


def prior_costs(results: str | Path, malloc: str | None = None) -> dict[str, dict[str, list[float]]]:
    """Seconds (:func:`price`) of steps finished before (:func:`timing_entries`: other runs, sessions and
    machines, every run of a step): {"label": {...}, "kind": {...}, "run": {"<run>: <label>": ...}}, for the ETA before
    this run has timed a step of its own; "run" holds the steps of a named run (the same recipe's
    training on other tasks prices it better than every recipe's). Under each key, the records made with
    this process's malloc setting (``malloc``, default :func:`malloc_setting`) where there are any, else all."""
    malloc = malloc or malloc_setting()
    same: dict[str, dict[str, list[float]]] = {"label": {}, "kind": {}, "run": {}}
    every: dict[str, dict[str, list[float]]] = {"label": {}, "kind": {}, "run": {}}
    for entries in timing_entries(results).values():
        for label, st in entries:
            keys = [("label", label), ("kind", st["kind"])] + ([("run", f"{st['run']}: {label}")] if st.get("run") else [])
            for table, key in keys:
                every[table].setdefault(key, []).append(price(st))
                if st.get("malloc", "system") == malloc:
                    same[table].setdefault(key, []).append(price(st))
    return {table: {key: same[table].get(key) or values for key, values in every[table].items()} for table in every}


def eta(remaining: list, by_label: dict[str, list[float]], by_kind: dict[str, list[float]],
        prior: dict[str, dict[str, list[float]]] | None = None) -> float | None:
    """Seconds of work left: each remaining step at :func:`step_cost`. So a 35-minute READ training
    does not price a 7-minute regressor's, nor one training every verify. None before anything is known."""
    costs = [step_cost(s, by_label, by_kind, prior) for s in remaining]
    return None if any(c is None for c in costs) else sum(costs)


def step_cost(step, by_label: dict[str, list[float]], by_kind: dict[str, list[float]],
              prior: dict[str, dict[str, list[float]]] | None = None) -> float | None:
    """One step's expected seconds: its own ``seconds_left`` where it has one (a training under way:
    its pace times the steps to its cap), else the mean time of the finished steps most like it, the
    first found of: this run's steps with its label (the same step on another task: "train read",
    "evaluate read --N 100"), earlier runs' of the same run name with its label (``prior["run"]``: the
    same recipe on other tasks), earlier runs' with its label (``prior``), this run's of its kind,
    earlier runs' of its kind, and this run's or earlier runs' of any kind. None before anything is known."""
    if step.seconds_left is not None:
        try:
            own = step.seconds_left()
        except (OSError, ValueError, KeyError):  # a record half-written: price it as a step not begun
            own = None
        if own is not None:
            return own
    prior = prior or {"label": {}, "kind": {}}
    mean = lambda v: sum(v) / len(v)  # noqa: E731
    run = step.run_name() if hasattr(step, "run_name") else None
    for table, key in ((by_label, step.label), (prior.get("run", {}), f"{run}: {step.label}"),
                       (prior["label"], step.label), (by_kind, step.kind), (prior["kind"], step.kind)):
        if table.get(key):
            return mean(table[key])
    known = [x for v in (*by_kind.values(), *prior["kind"].values()) for x in v]
    return mean(known) if known else None


def load_average() -> float | None:
    """This machine's 1-minute load average (None where the platform has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


def hms(seconds: float) -> str:
    """Seconds as H:MM:SS."""
    s = int(seconds)
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"
