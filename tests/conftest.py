"""Test session set-up: 2 forced host devices (exercises the sharded path), a persistent JAX
compilation cache of this session alone, single-threaded torch, and shared fixtures for the task
tests."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

# The session's own compilation cache (unless READJAX_JAX_CACHE is set): the user-wide one is
# shared with every other readjax process on the machine, and a test run beside trainings that
# were writing to it died in a segfault inside the cache read (jax's _cache_read ->
# deserialize_executable; BENCHMARKS.md 8h). A fresh directory is what a fresh CI machine starts
# with anyway, and repeated compilations within the session still hit it.
if "READJAX_JAX_CACHE" not in os.environ:
    _cache = tempfile.mkdtemp(prefix="readjax-test-jax-cache-")
    os.environ["READJAX_JAX_CACHE"] = _cache
    atexit.register(shutil.rmtree, _cache, ignore_errors=True)

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


def pytest_collection_modifyitems(config, items):
    """Leave ``slow`` tests out unless asked for with ``-m slow``."""
    if "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
