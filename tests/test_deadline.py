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


def _step(label: str, kind: str, task: str = "reach_target") -> Step:
    return Step(kind, task, label, ["true"], made=lambda: False)


# a task's steps as the pipeline chains them: data -> training -> evaluations; and another task's evaluation
GRID = [_step("generate test 100", "generate"), _step("train read", "train"), _step("evaluate read --N 0", "evaluate"),
        _step("evaluate read --N 100", "evaluate"), _step("evaluate read --N 0", "evaluate", "push_button")]
NEEDS = {0: [], 1: [0], 2: [1, 0], 3: [1, 0], 4: []}
PRIOR = {"label": {"generate test 100": [200.0], "train read": [3000.0, 3400.0], "evaluate read --N 100": [300.0]},
         "kind": {"evaluate": [100.0]}}


def test_a_step_starts_only_where_it_and_the_steps_that_need_it_fit_before_the_deadline():
    starts = deadline.latest_starts(GRID, NEEDS, NOW + 7200, PRIOR, slots=2)
    # (latest start, own price, the steps that need it over 2 slots): a training's evaluations count with it,
    # the data its training and evaluations; an evaluation of another task only itself
    assert starts == [(NOW + 7200 - 200 - (3200 + 100 + 300) / 2, 200.0, 1800.0),
                      (NOW + 7200 - 3200 - 200, 3200.0, 200.0),
                      (NOW + 7200 - 100, 100.0, 0.0), (NOW + 7200 - 300, 300.0, 0.0), (NOW + 7200 - 100, 100.0, 0.0)]
    assert deadline.latest_starts(GRID, NEEDS, NOW + 7200, PRIOR, slots=1)[0][2] == 3600.0
    latest, cost, rest = starts[1]
    deadline.check_start(GRID[1], latest, cost, rest, now=latest - 1)
    with pytest.raises(deadline.DeadlineError, match="`train read` not started: it takes about 0:53:20 and the "
                                                      "steps that need it about 0:03:20 more"):
        deadline.check_start(GRID[1], latest, cost, rest, now=latest + 1)
    assert [x[0] for x in deadline.latest_starts(GRID, NEEDS, None, PRIOR)] == [None] * 5  # no deadline
    deadline.check_start(GRID[1], None, cost, rest, now=NOW + 10 ** 6)  # ... always starts


def test_a_step_with_no_price_yet_starts_while_the_deadline_is_ahead():
    step = _step("generate test 100", "generate")
    [(latest, cost, rest)] = deadline.latest_starts([step], {0: []}, NOW + 60, None)
    assert (latest, cost, rest) == (NOW + 60, 0.0, 0.0)
    deadline.check_start(step, latest, cost, rest, now=NOW + 59)
    with pytest.raises(deadline.DeadlineError):
        deadline.check_start(step, latest, cost, rest, now=NOW + 61)


def test_a_step_is_priced_by_its_own_runs_records_on_other_tasks_before_every_runs():
    """timing.step_cost: the same run name's steps with its label (the same recipe on other tasks) come before
    every run's with that label, which mixes recipes of other sizes."""
    from readjax.lab.timing import step_cost

    train = Step("train", "put_rubbish", "train read", ["python", "-m", "experiments.train", "--name", "read_s2"],
                 made=lambda: False)
    prior = {"label": {"train read": [2000.0, 4000.0]}, "kind": {}, "run": {"read_s2: train read": [4300.0, 4500.0]}}
    assert step_cost(train, {}, {}, prior) == 4400.0
    other = Step("train", "put_rubbish", "train read", ["python", "-m", "experiments.train", "--name", "read_v2"],
                 made=lambda: False)
    assert step_cost(other, {}, {}, prior) == 3000.0
    assert step_cost(train, {"train read": [100.0]}, {}, prior) == 100.0  # this grid's own come first
