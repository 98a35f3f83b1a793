"""The task registry: 16 RLBench tasks by long name, with the paper's codes as aliases.

``make(name_or_code)`` builds a task's environment (once per process). ``names()`` lists the
tasks whose module is implemented, in the paper's table order.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util

# long name -> (paper code, class name); the module is readjax.tasks.<long name>.
_TASKS = {
    "pick_up_cup": ("PC", "PickUpCup"),
    "reach_target": ("RT", "ReachTarget"),
    "push_button": ("PB", "PushButton"),
    "open_wine": ("OW", "OpenWine"),
    "close_box": ("CB", "CloseBox"),
    "put_rubbish": ("PR", "PutRubbish"),
    "stack_wine": ("SW", "StackWine"),
    "place_hanger": ("PH", "PlaceHanger"),
    "water_plants": ("WP", "WaterPlants"),
    "beat_the_buzz": ("BB", "BeatTheBuzz"),
    "put_knife": ("PK", "PutKnife"),
    "take_plate": ("TP", "TakePlate"),
    "straighten_rope": ("SR", "StraightenRope"),
    "put_umbrella": ("PU", "PutUmbrella"),
    "scoop_with_spatula": ("SS", "ScoopWithSpatula"),
    "stack_blocks": ("SB", "StackBlocks"),
}
# The suite version: what the 16 tasks are (placement, conditions, experts). Datasets record it, and
# a split of another version is refused; results carry the version of the test split they ran on.
SUITE_VERSION = 2
SUITES = {
    1: "hand-picked placement boxes with little or no turn (readjax until 2026-12-06)",
    2: "RLBench's placement: the task at a random workspace pose (yaw from its base_rotation_bounds, "
       "±pi by default), objects in spawn boundaries, per-seed rejection of unreachable placements; "
       "RLBench's success and failure conditions",
}


def suite_of(meta: dict) -> int:
    """The suite version a dataset's meta (or a result) records; 1 for those written before versions."""
    return int(meta.get("suite", 1))


AVG12 = ("PC", "RT", "PB", "OW", "CB", "PR", "SW", "PH", "WP", "BB", "PK", "TP")
AVG16 = AVG12 + ("SR", "PU", "SS", "SB")


class UnknownTaskError(KeyError):
    """An unknown task name or code (the message lists the registered ones)."""

    def __str__(self):
        return self.args[0]


def _implemented(name: str) -> bool:
    return importlib.util.find_spec(f"readjax.tasks.{name}") is not None


def names() -> tuple[str, ...]:
    """Implemented tasks' long names, in the paper's order (Avg12 first)."""
    return tuple(n for n in _TASKS if _implemented(n))


def codes() -> dict[str, str]:
    """Long name -> paper code, for the implemented tasks."""
    return {n: _TASKS[n][0] for n in names()}


def code_of(name: str) -> str:
    return _TASKS[canonical_name(name)][0]


def canonical_name(name_or_code: str) -> str:
    """Long name for a long name or paper code (case-insensitive); a clear error otherwise."""
    key = str(name_or_code).strip()
    name = key.lower() if key.lower() in _TASKS else None
    if name is None:
        name = next((n for n, (c, _) in _TASKS.items() if c == key.upper()), None)
    if name is None:
        known = ", ".join(f"{n} ({c})" for n, c in codes().items())
        raise UnknownTaskError(f"unknown task {name_or_code!r}; registered tasks: {known}")
    if not _implemented(name):
        raise UnknownTaskError(f"task {name!r} ({_TASKS[name][0]}) is not implemented yet")
    return name


def task_class(name_or_code: str):
    name = canonical_name(name_or_code)
    return getattr(importlib.import_module(f"readjax.tasks.{name}"), _TASKS[name][1])


def make(name_or_code: str):
    """The environment of a task, built once per process (names and codes share it)."""
    return _make(canonical_name(name_or_code))


@functools.cache
def _make(name: str):
    return task_class(name)()
