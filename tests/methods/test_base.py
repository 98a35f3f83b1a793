"""The batch functions every retrieval-conditioned stage trains on: pure in the step (exact resume),
and the precomputed codes belong to the demos and neighbours they sit beside."""

import numpy as np
import pytest

from readjax.config import TrainConfig
from readjax.methods import base
from readjax.training import StageSpec


class _Data:
    def __init__(self, n):
        rng = np.random.default_rng(0)
        self.rgbd = rng.uniform(size=(n, 8, 8, 4)).astype(np.float32)
        self.motion = rng.normal(size=(n, 101, 10)).astype(np.float32)

    def __len__(self):
        return len(self.motion)

    def subset(self, idx):
        out = _Data(1)
        out.rgbd, out.motion = self.rgbd[idx], self.motion[idx]
        return out


def test_paired_batch_is_pure_in_the_step_and_carries_each_demos_neighbour():
    ds = _Data(20)
    pairs = np.stack([(np.arange(20) + s) % 20 for s in (1, 2, 3)], axis=1)  # 3 neighbours each
    codes = np.arange(20, dtype=np.float32)[:, None] * np.ones((1, 4), np.float32)  # demo i -> i
    spec = StageSpec(steps=10, batch_size=6, seed=3)
    batch = base.paired_batch(ds, spec, pairs, 20, codes=codes, extra=np.ones(2))
    a, b, c = batch(5), batch(5), batch(6)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert not np.array_equal(a["motion"], c["motion"])
    idx = a["code"][:, 0].astype(int)
    j = a["code_r"][:, 0].astype(int)
    np.testing.assert_array_equal(a["motion"], ds.motion[idx])
    np.testing.assert_array_equal(a["image"], ds.rgbd[idx])
    assert "retrieved" not in a  # a latent-space loss reads the neighbour's code, not its motion
    assert all(jj in pairs[i] for i, jj in zip(idx, j))
    np.testing.assert_array_equal(a["extra"], np.ones(2))
    plain = base.paired_batch(ds, spec, pairs, 20)(5)  # without codes: the neighbours' motions
    assert "code" not in plain and "code_r" not in plain
    np.testing.assert_array_equal(plain["motion"], a["motion"])
    np.testing.assert_array_equal(plain["retrieved"], ds.motion[j])


def test_a_validation_slice_is_never_trained_on_and_batched_in_fixed_chunks():
    """With the last 5 of 20 demos held out, training batches draw from the first 15 only (the same
    draws a 15-demo set would give), and validation covers the 5 in fixed batches of the same size."""
    ds = _Data(20)
    pairs = np.stack([(np.arange(20) + s) % 15 for s in (1, 2, 3)], axis=1)  # neighbours among the first 15
    spec = StageSpec(steps=10, batch_size=4, seed=3)
    batches = base.paired_batch(ds, spec, pairs, 15)
    drawn = np.concatenate([np.nonzero((batches(s)["motion"][:, None] == ds.motion[None]).all((2, 3)))[1]
                            for s in range(50)])
    assert drawn.max() < 15
    whole = base.paired_batch(ds.subset(np.arange(15)), spec, pairs[:15], 15)
    np.testing.assert_array_equal(batches(7)["motion"], whole(7)["motion"])
    val = batches.validation()
    assert len(val) == 2 and all(len(b["motion"]) == 4 for b in val)  # ceil(5 / 4) full-size batches
    held = {tuple(m.ravel()) for b in val for m in b["motion"]}
    assert held == {tuple(m.ravel()) for m in ds.motion[15:]}
    assert base.paired_batch(ds, spec, pairs, 20).validation() is None
    with pytest.raises(ValueError, match="hold out fewer"):
        base.train_size(20, TrainConfig(val_episodes=19))


def test_autoencoder_stage_config_of_a_run_recorded_before_a_train_field_existed():
    """run.json of an older run lacks fields added since (e.g. train.schedule): its autoencoder
    stage ran with their defaults, and loading it must not fail on the missing key."""
    from readjax.methods import read

    old = {"vae": {"width": 32}, "train": {"episodes": 0, "vae_steps": 3000, "vae_batch": 32, "vae_lr": 1e-3,
                                           "seed": 0, "ckpt_every": 500, "log_every": 25, "steps": 3000}}
    stage = read.vae_stage_config(old)
    assert stage["train"]["schedule"] == "staircase" and stage["train"]["vae_steps"] == 3000
    assert "steps" not in stage["train"]  # the denoiser's settings do not touch the autoencoder stage
