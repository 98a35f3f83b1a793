"""Keys whose draws are a pure function of their own seed, under any batching.

readjax makes ``rbg`` JAX's default PRNG (cheap compiles on the CPU, see :mod:`readjax._runtime`),
but under ``vmap`` an rbg key batch draws its random bits from the batch's *first* key: element i
of a vmapped draw depends on (first key, i), not on key i (../shared/STACK.md, measured). Anything
a user or a later run must reproduce from a seed alone -- an episode's scene above all -- draws
from :func:`seed_pure` keys instead: threefry keys, which vmap draws per key.

The conversion keeps seeds meaningful across implementations: an rbg key is two threefry keys
side by side (``key(s)``, ``split`` and ``fold_in`` act on each half as threefry does), so its
first half *is* the threefry key of the same seed and history. ``seed_pure(key(5))`` under rbg
and ``key(5, impl="threefry2x32")`` are the same key.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

THREEFRY = "threefry2x32"


def seed_pure(key_or_seed) -> jax.Array:
    """A threefry key (vmap-invariant draws) for a typed JAX key of any implementation (batched or
    not) or for integer seeds (a Python int or an integer array: one key per seed)."""
    x = key_or_seed
    if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jax.dtypes.prng_key):
        if str(jax.random.key_impl(x)) == THREEFRY:
            return x
        return jax.random.wrap_key_data(jax.random.key_data(x)[..., :2], impl=THREEFRY)
    seeds = jnp.asarray(x)
    if not jnp.issubdtype(seeds.dtype, jnp.integer):
        raise TypeError(f"expected a jax.random.key or integer seeds, got dtype {seeds.dtype}")
    make = lambda s: jax.random.key(s, impl=THREEFRY)  # noqa: E731
    return jax.vmap(make)(seeds.reshape(-1)).reshape(seeds.shape) if seeds.ndim else make(seeds)


def seed_pure_fn(fn):
    """Decorate ``fn(self, key, ...)`` so that it always draws from :func:`seed_pure` keys."""

    @functools.wraps(fn)
    def wrapper(self, key, *args, **kwargs):
        return fn(self, seed_pure(key), *args, **kwargs)

    wrapper.seed_pure = True
    return wrapper
