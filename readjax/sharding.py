"""Data parallelism over ``jax.devices()``: one mesh axis, "batch".

The same code runs on one CPU device, on 2 forced host devices (the tests) and on several GPUs:
arrays whose leading axis is the batch are placed with :func:`batch_sharding`, jit propagates it.
"""

from __future__ import annotations

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P


def mesh() -> Mesh:
    return Mesh(np.asarray(jax.devices()), ("batch",))


def batch_sharding(ndim_extra: int = 0) -> NamedSharding:
    """Shard axis 0 over all devices, replicate the rest."""
    return NamedSharding(mesh(), P("batch", *([None] * ndim_extra)))


def replicated() -> NamedSharding:
    return NamedSharding(mesh(), P())


def device_count() -> int:
    return jax.device_count()


def check_batch(batch: int) -> None:
    n = jax.device_count()
    if batch % n:
        raise ValueError(f"batch size {batch} must be a multiple of the device count {n}")


def fit_batch(batch: int, n: int) -> int:
    """The batch to run ``n`` items in at most ``batch`` at a time: no larger than needed, and a
    multiple of the device count (a short last batch is padded by the caller)."""
    d = jax.device_count()
    b = max(1, min(batch, n))
    return -(-b // d) * d


def shard_batch(tree):
    """Place every leaf's leading (batch) axis across the devices."""
    return jax.tree.map(lambda x: jax.device_put(x, batch_sharding(np.ndim(x) - 1)), tree)
