"""Test session set-up: 2 forced host devices (exercises the sharded path), the persistent JAX
compilation cache, single-threaded torch, shared fixtures for the task tests, and the worker groups
of `make test`'s two pytest-xdist workers (``xdist_group_of``)."""

from __future__ import annotations

import os

os.environ["XLA_FLAGS"] = (
    os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2"
).strip()

import readjax  # noqa: E402,F401  (adds the CPU fusion flag, cache, Cholesky before jax is used)

import pytest  # noqa: E402

try:
    import torch

    torch.set_num_threads(1)
except ImportError:  # the dev extra is not installed
    pass


def xdist_group_of(nodeid: str, task_names) -> str:
    """The worker group of a test under `make test`'s two pytest-xdist workers: a task's tests share
    one group (its expert rollout, compiled and run once per process by
    ``tests.tasks.helpers.expert_run``, serves its own file, the smoke test over every task and the
    scene-purity case), every other test is grouped by its file, so a module-scoped fixture (a
    trained tiny run) is built once, as in a single process."""
    path = nodeid.split("::", 1)[0]
    if path.startswith("tests/tasks/"):
        param = nodeid.rsplit("[", 1)[-1].rstrip("]") if nodeid.endswith("]") else None
        if param in task_names:
            return f"task:{param}"
        stem = path.rsplit("/", 1)[-1].removesuffix(".py").removeprefix("test_")
        if stem in task_names:
            return f"task:{stem}"
    return path


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist: unknown without it
def pytest_xdist_make_scheduler(config, log):
    """Hand pytest-xdist whole groups (``xdist_group_of``) instead of single tests. (Its own
    ``--dist loadgroup`` reads ``xdist_group`` marks by rewriting ``item._nodeid``, which pytest 9
    no longer reads: the marks would be ignored.)"""
    from xdist.scheduler import LoadScopeScheduling

    from readjax import tasks

    names = set(tasks.names())

    class TaskGroupScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return xdist_group_of(nodeid, names)

    return TaskGroupScheduling(config, log)


def pytest_collection_modifyitems(config, items):
    """Leave ``slow`` tests out unless asked for with ``-m slow``."""
    if "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(autouse=True)
def _release_compiled_code():
    """Hundreds of compiled programs in one pytest process reach Linux's cap on memory mappings
    (vm.max_map_count) and the next compile segfaults (BENCHMARKS 8i): after each test, drop JAX's
    in-memory executables once the process holds half the cap (later tests recompile, mostly from
    the persistent cache)."""
    yield
    from readjax import _runtime

    _runtime.release_compiled_if_crowded(0.5)
