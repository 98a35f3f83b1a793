"""Retrieval: training pairs exclude self, oracle ranks, SPE finds an image's own demo."""

from __future__ import annotations

import numpy as np
import pytest

from readjax import retrieval, tasks
from readjax import motion as mo
from readjax.sim.camera import camera_from_model


@pytest.fixture(scope="module")
def cam():
    return camera_from_model(tasks.make("reach_target").mj_model, "front", 64, 64)


def _motions(cam, n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, 101)[None, :, None]
    start = rng.uniform([0.3, -0.3, 0.1], [0.7, 0.3, 0.5], size=(n, 1, 3))
    end = rng.uniform([0.3, -0.3, 0.1], [0.7, 0.3, 0.5], size=(n, 1, 3))
    pos = (start + t * (end - start)).astype(np.float32)
    rot = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (n, 101, 3, 3)).astype(np.float32)
    return np.array(mo.encode(cam, pos, rot, np.ones((n, 101), np.float32)))


def test_training_pairs_exclude_self_and_are_nearest(cam):
    m = _motions(cam, 30)
    pairs = retrieval.training_pairs(cam, m, 3)
    assert pairs.shape == (30, 3)
    assert not np.any(pairs == np.arange(30)[:, None])
    # duplicate demo 0 as demo 29: they must be each other's nearest neighbour
    m[29] = m[0]
    pairs = retrieval.training_pairs(cam, m, 3)
    assert pairs[0, 0] == 29 and pairs[29, 0] == 0
    with pytest.raises(ValueError, match="K must be"):
        retrieval.training_pairs(cam, m, 30)
    with pytest.warns(UserWarning, match="using all"):  # a preset's K on a small dataset
        everyone = retrieval.training_pairs(cam, m, 30, clamp=True)
    assert everyone.shape == (len(m), len(m) - 1)
    assert all(set(row) == set(range(len(m))) - {i} for i, row in enumerate(everyone))


def test_training_pairs_of_a_split_come_from_the_training_demos_only(cam):
    """With the last 10 of 30 demos held out (pool = 20), every demo's neighbours are among the first
    20; a held-out demo's nearest is the training demo nearest to it, and the training demos' pairs
    are those of the 20 alone."""
    m = _motions(cam, 30)
    m[25] = m[3]  # a held-out duplicate of training demo 3
    pairs = retrieval.training_pairs(cam, m, 3, pool=20)
    assert pairs.shape == (30, 3) and pairs.max() < 20
    assert not np.any(pairs[:20] == np.arange(20)[:, None])
    assert pairs[25, 0] == 3 and 25 not in pairs[3]
    np.testing.assert_array_equal(pairs[:20], retrieval.training_pairs(cam, m[:20], 3))
    with pytest.raises(ValueError, match="pool"):
        retrieval.training_pairs(cam, m, 3, pool=1)


def test_oracle_ranks(cam):
    db = _motions(cam, 20)
    q = db[[4, 7]] + 1e-4
    assert list(retrieval.oracle_retrieve(cam, q, db, rank=1)) == [4, 7]
    second = retrieval.oracle_retrieve(cam, q, db, rank=2)
    assert not np.any(second == [4, 7])
    far = retrieval.oracle_retrieve(cam, q, db, rank=500)  # clipped to the farthest available
    order = retrieval.oracle_ranking(cam, q, db)
    assert list(far) == list(order[:, -1])


@pytest.mark.parametrize("input_skip", [False, True])
def test_spe_distances_match_the_per_candidate_definition_and_find_the_own_demo(input_skip):
    """SPE: the one-jit form (the test image's full map, sampled along every candidate's track)
    equals the definition mean((retrieval_tokens(F_test, uv_i) - f_i)^2) per candidate, and a
    database image used as the query retrieves its own demo (distance 0); with input_skip the
    compared tokens are the transformer's own (features + embedded input pixels)."""
    import dataclasses

    import jax
    import jax.numpy as jnp

    from readjax.methods.common import database_features
    from readjax.models import Denoiser
    from tests.models.helpers import TINY_DENOISER, chain_and_camera

    _, cam32 = chain_and_camera(32)
    cfg = dataclasses.replace(TINY_DENOISER, input_skip=input_skip)
    if input_skip:  # standardised depth too: the normalisation must commute with the sampling
        cfg = dataclasses.replace(cfg, motion_mean=(0.0, 0.0, 1.2) + (0.0,) * 7,
                                  motion_std=(0.5, 0.5, 0.1) + (1.0,) * 7)
    den = Denoiser(cfg)
    n = 6
    motions = jnp.asarray(_motions(cam32, n, seed=3))
    images = jax.random.uniform(jax.random.key(0), (n, 32, 32, 4))
    params = den.init({"params": jax.random.key(1), "dropout": jax.random.key(2)}, images[:1], motions[:1],
                      jnp.zeros((1,)))
    db_uv = mo.uv(motions)
    db_tok = database_features(den, params, np.asarray(images), np.asarray(motions), chunk=4)
    feats = den.apply(params, images, method="encode_image")
    d = np.asarray(retrieval.spe_distances(den, params, feats, db_uv, db_tok))
    assert d.shape == (n, n)
    for q in range(n):
        fq = jnp.broadcast_to(feats[q], (n,) + feats.shape[1:])
        g = den.apply(params, fq, db_uv, method="retrieval_tokens")
        if input_skip:
            np.testing.assert_allclose(g, den.apply(params, fq, db_uv, method="track_tokens"), atol=0)
        else:
            np.testing.assert_allclose(g, den.apply(params, fq, db_uv, method="image_tokens"), atol=0)
        np.testing.assert_allclose(d[q], np.mean((np.asarray(g) - db_tok) ** 2, axis=(1, 2)), rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(np.diag(d), 0.0, atol=1e-8)
    assert list(np.argmin(d, axis=1)) == list(range(n))
