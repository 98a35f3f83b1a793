"""Retrieval: training pairs exclude self, oracle ranks, SPE finds an image's own demo."""

from __future__ import annotations

import numpy as np
import pytest

from readjax import retrieval, tasks
from readjax.data import motion as mo
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


def test_oracle_ranks(cam):
    db = _motions(cam, 20)
    q = db[[4, 7]] + 1e-4
    assert list(retrieval.oracle_retrieve(cam, q, db, rank=1)) == [4, 7]
    second = retrieval.oracle_retrieve(cam, q, db, rank=2)
    assert not np.any(second == [4, 7])
    far = retrieval.oracle_retrieve(cam, q, db, rank=500)  # clipped to the farthest available
    order = retrieval.oracle_ranking(cam, q, db)
    assert list(far) == list(order[:, -1])
