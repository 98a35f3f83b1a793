"""A grid's deadline: a job with a wall-clock limit (a SLURM ``--time``, a lent machine, a session) starts
only the steps expected to finish before it, so that its cores go to work that will land, and a re-run
goes on from there (``experiments.pipeline --deadline``, :func:`readjax.lab.ray_grid.run_on_ray`).

A step's expected time is :func:`readjax.lab.timing.step_cost`: a training under way by its own pace,
else the same step's recorded times on other tasks or runs, else its kind's. A step with no price yet
is started while the deadline is ahead. What a step makes lands only once the steps that need it have
run (a training is committed as its evaluations), and a machine given back at the deadline loses the
rest (its data, its checkpoints): so a step starts only where it and every step that needs it, directly
or not, fit before the deadline, the latter shared among the grid's ``slots`` (the steps run at once).
"""

from __future__ import annotations

import re
import time
from datetime import datetime, timedelta

from readjax.lab.steps import PipelineError
from readjax.lab.timing import hms, step_cost

_DURATION = re.compile(r"^\+(\d+(?:\.\d+)?)([smh])$")
_UNIT = {"s": 1, "m": 60, "h": 3600}


class DeadlineError(PipelineError):
    """A step not started because it would end after the grid's deadline."""


def parse(text: str, now: float | None = None) -> float:
    """A deadline as seconds since the epoch, from ``+90m`` / ``+3h`` / ``+45s`` (from now), ``HH:MM``
    (local time: its next occurrence) or an ISO date and time (``2026-12-07T23:40``, local unless it
    names a zone). ValueError, saying the forms, for anything else or a time already past."""
    now = time.time() if now is None else now
    m = _DURATION.match(text.strip())
    if m:
        return now + float(m.group(1)) * _UNIT[m.group(2)]
    try:
        if re.fullmatch(r"\d{1,2}:\d{2}", text.strip()):
            hour, minute = map(int, text.split(":"))
            day = datetime.fromtimestamp(now).replace(hour=hour, minute=minute, second=0, microsecond=0)
            at = day if day.timestamp() > now else day + timedelta(days=1)
        else:
            at = datetime.fromisoformat(text.strip())
    except ValueError:
        raise ValueError(f"--deadline {text!r}: expected +DURATION (+90m, +3h, +45s), HH:MM or an ISO date and "
                         f"time (2026-12-07T23:40)") from None
    if at.timestamp() <= now:
        raise ValueError(f"--deadline {text!r} is already past")
    return at.timestamp()


def latest_starts(todo: list, needs: dict[int, list[int]], deadline: float | None, prior: dict | None,
                  slots: int = 1) -> list[tuple[float | None, float, float]]:
    """Per step of ``todo`` (``needs``: the indices each one waits for): (the latest time it may start,
    its expected seconds, the seconds of the steps that need it, directly or not, over ``slots``); the
    latest start is the deadline less both (None without a deadline)."""
    cost = [step_cost(s, {}, {}, prior) or 0.0 for s in todo]
    users: dict[int, set[int]] = {i: set() for i in range(len(todo))}
    for i, ns in needs.items():
        for n in ns:
            users[n].add(i)
    out = []
    for i in range(len(todo)):
        after, stack = set(), list(users[i])
        while stack:
            j = stack.pop()
            if j not in after:
                after.add(j)
                stack += users[j]
        rest = sum(cost[j] for j in after) / max(1, slots)
        out.append(((None if deadline is None else deadline - cost[i] - rest), cost[i], rest))
    return out


def check_start(step, latest: float | None, cost: float, rest: float = 0.0, now: float | None = None) -> None:
    """Raise :class:`DeadlineError` where ``step`` would start after ``latest`` (:func:`latest_starts`)."""
    if latest is not None and (time.time() if now is None else now) > latest:
        then = f" and the steps that need it about {hms(rest)} more" if rest else ""
        raise DeadlineError(f"{step.task}: `{step.label}` not started: it takes about {hms(cost)}{then}, which "
                            f"would end after the deadline ({stamp(latest + cost + rest)})")


def stamp(t: float) -> str:
    """A deadline as the log and the errors print it (local time)."""
    return time.strftime("%Y-%m-%d %H:%M", time.localtime(t))
