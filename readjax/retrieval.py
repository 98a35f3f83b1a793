"""Retrieval of a motion from the training database (METHOD.md sections 6 and 7).

* Training pairs: for each demo, its top-K neighbours among the OTHER demos by ground-truth
  motion (flattened [position; 0.1 * rot6d], L2) — READ draws M_R uniformly from these.
* SPE retrieval (test time): the test image's feature map is sampled along each candidate's uv and
  compared with the candidate's own image features sampled along its own motion (precomputed once
  per checkpoint); the smallest mean squared difference wins.
* Oracle ("cheat") retrieval: the i-th nearest neighbour of the ground-truth test motion (mean
  position error + 0.01 * mean rot6d error), used for the paper's oracle tables.
Positions are 3D (world frame, recovered from uv and z with the dataset's camera).
"""

from __future__ import annotations

import warnings
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from readjax import motion as motion_lib
from readjax.models.denoiser import sample_features
from readjax.sim.camera import CameraParams


def positions(cam: CameraParams, motions: jax.Array) -> jax.Array:
    """3D end-effector positions (..., 101, 3) of motions."""
    pos, _, _ = motion_lib.decode(cam, jnp.asarray(motions))
    return pos


def _pair_features(cam: CameraParams, motions) -> np.ndarray:
    m = jnp.asarray(motions)
    feat = jnp.concatenate([positions(cam, m), 0.1 * motion_lib.rot6d(m)], axis=-1)
    return np.asarray(feat.reshape(m.shape[0], -1), np.float64)


def training_pairs(cam: CameraParams, motions, k: int, clamp: bool = False, pool: int | None = None) -> np.ndarray:
    """(N, k) indices of each demo's k nearest OTHER demos (self excluded), nearest first, chosen
    among the first ``pool`` demos (default all): with a held-out validation slice at the end, every
    demo, held out or not, is paired with training demos only, as a test image is at inference.

    ``clamp``: a pool larger than the other demos (a preset's K on a small dataset) becomes all
    of them, with a warning, instead of an error."""
    n = len(motions)
    pool = n if pool is None else pool
    if not 2 <= pool <= n and not (pool == n == 1):
        raise ValueError(f"the neighbour pool must hold 2..{n} demos, got {pool}")
    if clamp and pool >= 2 and k > pool - 1:
        warnings.warn(f"K = {k} neighbours asked for, but the training set has {pool} demos: using all "
                      f"{pool - 1} others", stacklevel=2)
        k = pool - 1
    if not 1 <= k < pool:
        raise ValueError(f"K must be in [1, N-1] = [1, {pool - 1}], got {k}")
    f = _pair_features(cam, motions)
    sq = (f**2).sum(1)
    d = sq[:, None] + sq[None, :pool] - 2 * f @ f[:pool].T
    d[np.arange(pool), np.arange(pool)] = np.inf
    return np.argsort(d, axis=1, kind="stable")[:, :k].astype(np.int32)


def oracle_ranking(cam: CameraParams, query_motions, db_motions) -> np.ndarray:
    """(B, N) database indices sorted by the cheat distance to each query's ground truth."""
    q, db = jnp.asarray(query_motions), jnp.asarray(db_motions)
    pq, pdb = positions(cam, q), positions(cam, db)
    pos_err = jnp.linalg.norm(pq[:, None] - pdb[None], axis=-1).mean(-1)
    rot_err = jnp.linalg.norm(motion_lib.rot6d(q)[:, None] - motion_lib.rot6d(db)[None], axis=-1).mean(-1)
    return np.argsort(np.asarray(pos_err + 0.01 * rot_err), axis=1, kind="stable")


def oracle_retrieve(cam: CameraParams, query_motions, db_motions, rank: int = 1) -> np.ndarray:
    """Indices of the ``rank``-th nearest database motion (1 = nearest; clipped to the farthest)."""
    if rank < 1:
        raise ValueError(f"oracle rank must be >= 1, got {rank}")
    order = oracle_ranking(cam, query_motions, db_motions)
    return order[:, min(rank, order.shape[1]) - 1]


@partial(jax.jit, static_argnums=(0,))
def _spe(den, den_params, feats, db_uv, db_tokens):
    """(B, N) distances. Per test image (``lax.map``, so memory does not grow with B): its
    full-resolution retrieval map once (:meth:`Denoiser.retrieval_map`), then plain bilinear samples
    along all N candidates' tracks (embedded by ``retrieval_embed``) -- the same values as
    ``retrieval_tokens`` per candidate, without N copies of the image's features."""
    n, t = db_uv.shape[:2]

    def one(fmap):
        full = den.apply(den_params, fmap[None], method="retrieval_map")
        g = sample_features(full, db_uv.reshape(1, n * t, 2)).reshape(n, t, -1)
        g = den.apply(den_params, g, method="retrieval_embed")
        return jnp.mean((g - db_tokens) ** 2, axis=(1, 2))

    return jax.lax.map(one, feats)


def spe_distances(den, den_params, test_features: jax.Array, db_uv, db_tokens) -> jax.Array:
    """(B, N) SPE distances mean((g_i - f_i)^2): g_i = the test image's features sampled along
    candidate i's uv, f_i = candidate i's own image features along its own motion (precomputed,
    ``db_tokens`` (N, 101, C)). ``den`` is the denoiser whose ``retrieval_tokens`` are compared;
    ``test_features`` (B, ...) come from its ``encode_image``. One jitted call; pass ``db_uv`` and
    ``db_tokens`` as device arrays (the planner keeps them on device) to avoid a copy per call."""
    return _spe(den, den_params, jnp.asarray(test_features), jnp.asarray(db_uv), jnp.asarray(db_tokens))
