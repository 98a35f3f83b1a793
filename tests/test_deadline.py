"""A grid's deadline (readjax.lab.deadline): the forms --deadline reads, and which steps may still start.
The grid on Ray with a deadline: tests/test_ray_grid.py (two_nodes)."""

from __future__ import annotations

from datetime import datetime

import pytest

from readjax.lab import deadline
from readjax.lab.steps import Step

NOW = datetime(2026, 12, 7, 21, 30).timestamp()


def test_durations_clock_times_and_iso_times():
    assert deadline.parse("+90m", NOW) == NOW + 5400
    assert deadline.parse("+3h", NOW) == NOW + 3 * 3600
    assert deadline.parse("+45s", NOW) == NOW + 45
    assert deadline.parse("23:40", NOW) == datetime(2026, 12, 7, 23, 40).timestamp()
    assert deadline.parse("08:00", NOW) == datetime(2026, 12, 8, 8, 0).timestamp()  # the next 08:00: tomorrow
    assert deadline.parse("2026-12-09T10:15", NOW) == datetime(2026, 12, 9, 10, 15).timestamp()


@pytest.mark.parametrize("text", ["soon", "90m", "+3d", "25:00", "2026-13-01T00:00", "2026-12-07T20:00"])
def test_anything_else_or_a_past_time_is_refused_saying_the_forms(text):
    with pytest.raises(ValueError, match="deadline"):
        deadline.parse(text, NOW)


def _step(label: str, kind: str) -> Step:
    return Step(kind, "reach_target", label, ["true"], made=lambda: False)


def test_a_step_starts_only_while_its_expected_time_fits_before_the_deadline():
    prior = {"label": {"train read": [3000.0, 3400.0]}, "kind": {"evaluate": [100.0]}}
    train, evaluate = _step("train read", "train"), _step("evaluate read --N 100", "evaluate")
    latest, cost = deadline.start_by(train, NOW + 3600, prior)
    assert cost == 3200.0 and latest == NOW + 400
    deadline.check_start(train, latest, cost, now=NOW + 399)
    with pytest.raises(deadline.DeadlineError, match="`train read` not started: it takes about 0:53:20"):
        deadline.check_start(train, latest, cost, now=NOW + 401)
    assert deadline.start_by(evaluate, NOW + 3600, prior) == (NOW + 3500, 100.0)  # its kind's price
    assert deadline.start_by(train, None, prior) == (None, 3200.0)
    deadline.check_start(train, None, 3200.0, now=NOW + 10 ** 6)  # no deadline: always starts


def test_a_step_with_no_price_yet_starts_while_the_deadline_is_ahead():
    step = _step("generate test 100", "generate")
    latest, cost = deadline.start_by(step, NOW + 60, None)
    assert (latest, cost) == (NOW + 60, 0.0)
    deadline.check_start(step, latest, cost, now=NOW + 59)
    with pytest.raises(deadline.DeadlineError):
        deadline.check_start(step, latest, cost, now=NOW + 61)
