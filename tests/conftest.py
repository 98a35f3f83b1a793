"""Test session set-up: 2 forced host devices (exercises the sharded path), the persistent JAX
compilation cache, single-threaded torch, and shared fixtures for the task tests."""

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
