"""Data parallelism over ``jax.devices()``: one mesh axis, "batch".

The same code runs on one CPU device, on 2 forced host devices (the tests), on several GPUs and
across processes (:mod:`readjax.distributed`: ``jax.devices()`` is then every process's devices):
arrays whose leading axis is the batch are placed with :func:`batch_sharding`, jit propagates it.
In a multi-process run each process holds the rows of a batch its devices hold (:func:`process_rows`).
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


def process_rows(batch: int) -> slice:
    """The rows of a global batch of ``batch`` rows that this process's devices hold (all of them in a
    one-process run): one contiguous block, the mesh listing each process's devices together."""
    blocks = sorted({(s.start or 0, batch if s.stop is None else s.stop)
                     for (s,) in batch_sharding().addressable_devices_indices_map((batch,)).values()})
    for (_, stop), (start, _) in zip(blocks, blocks[1:]):
        if stop != start:
            raise RuntimeError(f"this process's rows of the batch are not contiguous: {blocks}")
    return slice(blocks[0][0], blocks[-1][1])


def shard_batch(tree):
    """Place every leaf's leading (batch) axis across the devices; ``tree`` holds the whole batch
    (in a multi-process run every process passes the same batch and contributes its rows)."""
    if jax.process_count() == 1:
        return jax.tree.map(lambda x: jax.device_put(x, batch_sharding(np.ndim(x) - 1)), tree)
    batch = len(jax.tree.leaves(tree)[0])
    rows = process_rows(batch)
    return shard_rows(jax.tree.map(lambda x: np.asarray(x)[rows], tree), batch)


def shard_rows(tree, batch: int):
    """The global batch of ``batch`` rows from this process's rows of it (:func:`process_rows`): each
    leaf holds those rows only; assembled with ``jax.make_array_from_process_local_data``."""
    def put(x):
        x = np.asarray(x)
        return jax.make_array_from_process_local_data(batch_sharding(x.ndim - 1), x, (batch,) + x.shape[1:])

    return jax.tree.map(put, tree)


def replicate(tree):
    """Every leaf, whole, on every device of the mesh (a train state). In a multi-process run every
    process passes the same values (the same initialisation, or the same restored checkpoint)."""
    s = replicated()
    if jax.process_count() == 1:
        return jax.device_put(tree, s)
    return jax.tree.map(lambda x: jax.make_array_from_callback(np.shape(x), s, lambda i, x=np.asarray(x): x[i]),
                        tree)
