"""Randomisation helpers shared by the tasks (pure jnp; every draw takes an explicit key)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

# Named colours for distractors (RLBench draws from a similar list); red is never a distractor.
PALETTE = {
    "green": (0.1, 0.65, 0.15),
    "blue": (0.1, 0.25, 0.9),
    "yellow": (0.95, 0.85, 0.1),
    "cyan": (0.1, 0.8, 0.85),
    "magenta": (0.85, 0.15, 0.75),
    "orange": (1.0, 0.5, 0.05),
    "purple": (0.45, 0.15, 0.7),
    "white": (0.95, 0.95, 0.95),
    "black": (0.08, 0.08, 0.08),
    "gray": (0.5, 0.5, 0.5),
    "olive": (0.5, 0.5, 0.05),
    "navy": (0.05, 0.05, 0.45),
}
RED = (0.9, 0.08, 0.08)
_PALETTE = jnp.array(list(PALETTE.values()), jnp.float32)


def distractor_colours(key: jax.Array, n: int) -> jax.Array:
    """n distinct non-red colours as RGBA (n, 4)."""
    idx = jax.random.choice(key, _PALETTE.shape[0], (n,), replace=False)
    return jnp.concatenate([_PALETTE[idx], jnp.ones((n, 1))], axis=1)


def separated_points(key: jax.Array, n: int, low, high, min_dist: float, tries: int = 128) -> jax.Array:
    """n points uniform in the box [low, high] with pairwise distance >= min_dist.

    Rejection sampling without a data-dependent loop: ``tries`` candidate sets are drawn and
    the first valid one is kept (the best-separated one if none is valid, which the tasks'
    region sizes make vanishingly rare; tests check the distance on many seeds).
    """
    low, high = jnp.asarray(low, jnp.float32), jnp.asarray(high, jnp.float32)
    pts = jax.random.uniform(key, (tries, n, low.shape[0]), minval=low, maxval=high)
    if n == 1:
        return pts[0]
    diff = pts[:, :, None, :] - pts[:, None, :, :]
    dist = jnp.linalg.norm(diff, axis=-1) + jnp.eye(n) * 1e3
    closest = dist.min(axis=(1, 2))
    ok = closest >= min_dist
    pick = jnp.where(jnp.any(ok), jnp.argmax(ok), jnp.argmax(closest))
    return pts[pick]


def uniform(key: jax.Array, low, high, shape=()) -> jax.Array:
    return jax.random.uniform(key, shape, minval=low, maxval=high)
