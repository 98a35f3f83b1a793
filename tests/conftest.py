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
