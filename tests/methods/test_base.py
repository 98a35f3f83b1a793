"""The batch functions every retrieval-conditioned stage trains on: pure in the step (exact resume),
and the precomputed codes belong to the demos and neighbours they sit beside."""

import numpy as np

from readjax.methods import base
from readjax.training import StageSpec


class _Data:
    def __init__(self, n):
        rng = np.random.default_rng(0)
        self.rgbd = rng.uniform(size=(n, 8, 8, 4)).astype(np.float32)
        self.motion = rng.normal(size=(n, 101, 10)).astype(np.float32)

    def __len__(self):
        return len(self.motion)


def test_paired_batch_is_pure_in_the_step_and_carries_each_demos_neighbour():
    ds = _Data(20)
    pairs = np.stack([(np.arange(20) + s) % 20 for s in (1, 2, 3)], axis=1)  # 3 neighbours each
    codes = np.arange(20, dtype=np.float32)[:, None] * np.ones((1, 4), np.float32)  # demo i -> i
    spec = StageSpec(steps=10, batch_size=6, seed=3)
    batch = base.paired_batch(ds, spec, pairs, codes=codes, extra=np.ones(2))
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
    plain = base.paired_batch(ds, spec, pairs)(5)  # without codes: the neighbours' motions
    assert "code" not in plain and "code_r" not in plain
    np.testing.assert_array_equal(plain["motion"], a["motion"])
    np.testing.assert_array_equal(plain["retrieved"], ds.motion[j])


def test_autoencoder_stage_config_of_a_run_recorded_before_a_train_field_existed():
    """run.json of an older run lacks fields added since (e.g. train.schedule): its autoencoder
    stage ran with their defaults, and loading it must not fail on the missing key."""
    from readjax.methods import read

    old = {"vae": {"width": 32}, "train": {"episodes": 0, "vae_steps": 3000, "vae_batch": 32, "vae_lr": 1e-3,
                                           "seed": 0, "ckpt_every": 500, "log_every": 25, "steps": 3000}}
    stage = read.vae_stage_config(old)
    assert stage["train"]["schedule"] == "staircase" and stage["train"]["vae_steps"] == 3000
    assert "steps" not in stage["train"]  # the denoiser's settings do not touch the autoencoder stage
