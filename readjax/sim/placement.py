"""RLBench's placement rules in jnp: the task at a random workspace pose, objects in spawn boundaries,
and a per-seed rejection loop.

RLBench (``rlbench/backend/scene.py:115-150, 529-537``; ``backend/spawn_boundary.py``) places a task
in three nested steps, and readjax follows them:

1. **Objects in their boundaries** (``SpawnBoundary.sample``): an object's bounding box, turned by a
   yaw drawn from its rotation bounds (±3.14 by default), must fit inside the boundary, and its
   origin is drawn uniformly where the turned box stays inside (:func:`spawn_in_boundary`). Objects
   closer than ``min_distance`` to one placed before, or colliding with it, are drawn again.
2. **The whole task in the workspace** (``Scene._place_task``): unless the task is a static
   workspace, its model (every object, fixture, boundary and sensor) is turned by a yaw drawn from
   ``base_rotation_bounds()`` (±3.14 by default) and put where its turned bounding box fits inside
   the scene's ``workspace`` plane (:func:`place_task`).
3. **Validation** (``Scene.init_episode``, ``Task.validate``): a placement where the arm collides or
   a waypoint of the demonstration cannot be reached is rejected and everything is drawn again.

Here all three become one rejection loop per seed (:func:`first_accepted`): candidate ``i`` is drawn
from ``fold_in(key, i)`` and the first accepted candidate is the scene, so a scene is a function of
its seed alone under any batching (``lax.while_loop`` under ``vmap`` keeps each lane's own stream and
stops advancing a lane once it is accepted). A seed with no accepted candidate in ``max_tries`` is
marked infeasible, and generation drops it as it drops a seed whose expert fails.

The workspace plane. RLBench keeps its size in ``task_design.ttt`` (a binary scene we cannot read).
Ours is the part of the table in front of the robot that the Panda can reach and the front camera
sees: x in [0.25, 0.80] m, y in [-0.45, 0.45] m from the robot base (its far corners are beyond
the arm's reach; the validation step rejects what the arm cannot reach, as RLBench's does).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

WORKSPACE_LOW = np.array([0.25, -0.45], np.float32)
WORKSPACE_HIGH = np.array([0.80, 0.45], np.float32)
FULL_TURN = (-np.pi, np.pi)  # RLBench's default rotation bounds (it writes ±3.14)


def rot2(yaw: jax.Array) -> jax.Array:
    """2-D rotation matrix (..., 2, 2)."""
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    return jnp.stack([jnp.stack([c, -s], -1), jnp.stack([s, c], -1)], -2)


def turn(xy: jax.Array, yaw: jax.Array) -> jax.Array:
    """Points (..., 2) turned by ``yaw`` about the origin, the same float for float alone and under any
    batching, as a scene must be: a matmul rounds differently batched and alone (XLA picks another
    kernel), and so do plain multiply-adds (XLA fuses them into FMAs in some layouts and not in
    others), so the products pass an optimisation barrier before they are summed."""
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    x, y = xy[..., 0], xy[..., 1]
    cx, sy, sx, cy = lax.optimization_barrier((c * x, s * y, s * x, c * y))
    return jnp.stack([cx - sy, sx + cy], -1)


def turned_extent(box_min, box_max, yaw: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Axis-aligned (min, max) corners (2,) of a 2-D box [box_min, box_max] (in its own frame, around
    its origin) turned by ``yaw`` about that origin: RLBench's ``BoundingBox.rotate``."""
    lo, hi = jnp.asarray(box_min, jnp.float32), jnp.asarray(box_max, jnp.float32)
    corners = jnp.stack([lo, jnp.stack([hi[0], lo[1]]), jnp.stack([lo[0], hi[1]]), hi])
    turned = turn(corners, yaw)
    return turned.min(0), turned.max(0)


def spawn_in_boundary(key: jax.Array, boundary_low, boundary_high, box_min, box_max,
                      yaw_bounds=FULL_TURN) -> tuple[jax.Array, jax.Array, jax.Array]:
    """RLBench's ``BoundaryObject.add``: a yaw from ``yaw_bounds`` and an origin (2,) uniform where the
    object's turned bounding box [box_min, box_max] (its own frame) lies inside the boundary
    rectangle [boundary_low, boundary_high]. Returns (xy, yaw, fits); ``fits`` is False when the turned
    box is larger than the boundary (RLBench's -1: draw again)."""
    k_yaw, k_xy = jax.random.split(key)
    yaw = jax.random.uniform(k_yaw, (), minval=yaw_bounds[0], maxval=yaw_bounds[1])
    lo, hi = turned_extent(box_min, box_max, yaw)
    b_lo, b_hi = jnp.asarray(boundary_low, jnp.float32), jnp.asarray(boundary_high, jnp.float32)
    x_lo, x_hi = b_lo - lo, b_hi - hi  # origin range keeping the whole turned box inside
    fits = jnp.all(x_lo <= x_hi)
    u = jax.random.uniform(k_xy, (2,))
    xy = x_lo + lax.optimization_barrier(u * jnp.maximum(x_hi - x_lo, 0.0))  # no FMA: see turn
    return xy, yaw, fits


def place_task(key: jax.Array, footprint_min, footprint_max, yaw_bounds=FULL_TURN):
    """RLBench's ``Scene._place_task``: the task frame (origin xy (2,), yaw) such that the task's turned
    footprint [footprint_min, footprint_max] (its bounding box in the task frame) fits the workspace.
    Returns (xy, yaw, fits)."""
    return spawn_in_boundary(key, WORKSPACE_LOW, WORKSPACE_HIGH, footprint_min, footprint_max, yaw_bounds)


def to_world(origin_xy: jax.Array, yaw: jax.Array, local) -> jax.Array:
    """Points (..., 2) or (..., 3) given in a task frame (origin on the table, turned by ``yaw``) -> world."""
    local = jnp.asarray(local, jnp.float32)
    xy = origin_xy + turn(local[..., :2], yaw)
    return jnp.concatenate([xy, local[..., 2:]], -1) if local.shape[-1] == 3 else xy


def min_pairwise_distance(points: jax.Array) -> jax.Array:
    """Smallest distance between any two of (n, d) points (inf for n < 2)."""
    n = points.shape[0]
    if n < 2:
        return jnp.asarray(jnp.inf)
    d = jnp.linalg.norm(points[:, None] - points[None], axis=-1) + jnp.eye(n) * 1e6
    return d.min()


def first_accepted(key: jax.Array, draw: Callable, accept: Callable, max_tries: int):
    """The first candidate ``draw(fold_in(key, i))``, i = 0, 1, ..., that ``accept`` takes, within
    ``max_tries``: returns (candidate, accepted, tries). Each lane of a batch follows its own key
    stream and stops at its own first accepted candidate, so the result is a function of ``key``
    alone, whatever the batch (the rejection sampling of :mod:`readjax.sim.placement`)."""
    first = draw(jax.random.fold_in(key, 0))
    ok0 = accept(first)

    def cond(carry):
        i, ok, _ = carry
        return (~ok) & (i < max_tries)

    def body(carry):
        i, _, _ = carry
        cand = draw(jax.random.fold_in(key, i))
        return i + 1, accept(cand), cand

    tries, ok, cand = lax.while_loop(cond, body, (jnp.ones((), jnp.int32), ok0, first))
    return cand, ok, tries
