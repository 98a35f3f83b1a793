"""One tiny end-to-end run per method of METHOD.md section 10 (and READ with the kinematics-aware
autoencoder): train a few steps through ``experiments.train --model NAME``, then plan 2 episodes
through ``Planner.load`` (shapes, finiteness, same key -> same plan)."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

from experiments import _cli
from experiments import train as train_cli
from readjax.data.generate import GenerateConfig, generate
from readjax.evaluation import refine_update
from readjax.methods import base
from readjax.planner import Planner

pytestmark = pytest.mark.timeout(1200)

TINY = ["steps=4", "batch=4", "vae_steps=4", "vae_batch=4", "ckpt_every=4", "log_every=2",
        "denoiser.conv_dims=8,8,8,8", "denoiser.enc_depths=0,0,0,0", "denoiser.dec_depths=0,0,0",
        "denoiser.feature_channels=16", "denoiser.d_model=16", "denoiser.ffn=32", "denoiser.layers=1",
        "denoiser.heads=2", "vae.width=16", "vae.layers=1", "vae.heads=2", "vae.ffn=32", "vae.latent_dim=16",
        "resnet.stage_widths=8,8,16,16", "resnet.stage_blocks=1,1,1,1", "resnet.norm_groups=4",
        "resnet.proj_dim=8", "resnet.head_hidden=32"]

CASES = {  # run name -> (method, extra overrides, stages)
    "deterministic": ("deterministic", [], ("deterministic",)),
    "vpsde": ("vpsde", ["vpsde.sampler=sde"], ("vpsde",)),
    "vpsde_cg": ("vpsde_cg", ["vpsde.guidance=1.5"], ("vpsde_cg",)),
    "read_o": ("read_o", [], ("read_o",)),  # CD: READ's update (sde.update) in task space
    "read_o_em": ("read_o", ["read_o.sampler=em"], ("read_o",)),  # the reverse SDE: no update to choose
    "read_l": ("read_l", ["sde.latent_norm=true"], ("vae", "read_l")),
    "read_kinematic": ("read", ["vae.kinematic=true", "sde.latent_norm=true"], ("vae", "read")),
    # the convergence rule: 2 of the 8 demos held out, validated every 2 steps; no 90 % gain within 2
    # steps ends both stages at step 4 of their 6-step cap
    "read_converged": ("read", ["steps=6", "vae_steps=6", "val_episodes=2", "val_every=2", "stop_patience=2",
                                "stop_min_delta=0.9", "sde.latent_norm=true"], ("vae", "read")),
}


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("methods_e2e")
    generate(GenerateConfig(task="reach_target", episodes=8, out=str(root / "data"), batch_size=4, image_size=64),
             progress=False)
    return root


@pytest.mark.parametrize("name", list(CASES))
def test_train_and_plan(data, name):
    method, extra, stages = CASES[name]
    runs = data / "runs"
    argv = ["--task", "RT", "--model", method, "--name", name, "--data", str(data / "data"), "--out", str(runs),
            "--quiet"] + sum((["--set", s] for s in TINY + extra), [])
    assert _cli.run(train_cli.main, argv) == 0
    run_dir = runs / "reach_target" / name
    spec = base.read_run(run_dir)
    assert spec["method"] == method
    for stage in stages:
        rows = [json.loads(ln) for ln in (run_dir / stage / "metrics.jsonl").read_text().splitlines()]
        assert rows[-1]["step"] == 4 and np.isfinite(rows[-1]["loss"])
        if name == "read_converged":
            stop = json.loads((run_dir / stage / "stop.json").read_text())
            assert stop["reason"] == "converged" and stop["stopped_at"] == 4
            assert [r["step"] for r in rows if "val_loss" in r] == [2, 4]
    if method in ("read", "read_l"):  # their SDE runs on the standardised latent (sde.latent_norm)
        assert spec["configs"]["sde"]["latent_norm"]
        stats = json.loads((run_dir / "latent_stats.json").read_text())
        assert len(stats["mean"]) == len(stats["std"]) == 16 and min(stats["std"]) >= stats["std_floor"]

    planner = Planner.load(run_dir)
    rgbd = planner.database.rgbd[:2]
    plan = planner.plan(rgbd, jax.random.key(0), N=2)
    assert plan.motion.shape == (2, 101, 10) and plan.joints.shape == (2, 101, 7)
    assert np.all(np.isfinite(plan.motion)) and np.all(np.isfinite(plan.positions))
    again = planner.plan(rgbd, jax.random.key(0), N=2)
    np.testing.assert_array_equal(plan.motion, again.motion)  # same key -> same plan
    # the plan is the planner's refinement (the run's rounds) of what it retrieved
    other = planner.refine(planner.encode(rgbd), plan.retrieved, jax.random.key(1), 2, planner.default_rounds)
    cold = refine_update(planner.model) in ("cold", "cold_anchor")
    if method == "deterministic" or cold:
        np.testing.assert_array_equal(other, plan.motion)  # no sampling: the key is ignored
    else:
        assert not np.allclose(other, plan.motion)  # another key -> another sample
    assert (refine_update(planner.model) is not None) == (method in ("read", "read_l") or name == "read_o")
    if refine_update(planner.model) is None:
        with pytest.raises(ValueError, match="no refinement update"):
            planner.model.set_refine_update("cold")
    if cold:  # the paper's loop re-noises: the key matters
        planner.model.set_refine_update("renoise")
        paper = planner.model.generate(planner.encode(rgbd), plan.retrieved, jax.random.key(0), 2)
        assert not np.allclose(planner.model.generate(planner.encode(rgbd), plan.retrieved, jax.random.key(1), 2),
                               paper)
    if planner.model.uses_retrieval:
        retrieved = planner.plan(rgbd, jax.random.key(0), N=0)
        np.testing.assert_array_equal(retrieved.motion, retrieved.retrieved)


def test_prepare_records_the_adjusted_configs(data):
    """common.prepare: the run folder every method's train starts from. ``adjust`` sees the
    training set before run.json is written, run.json records only the method's sections, and
    ``result()`` is run.json as read back."""
    from readjax import config
    from readjax.methods import common

    seen = []

    def adjust(configs, ds):
        seen.append(len(ds))
        return config.override(configs, ["K=3"])

    configs = config.presets("cpu")
    run = common.prepare("deterministic", "RT", data / "data", data / "prep", configs, "cpu",
                         ("resnet",), 64, adjust=adjust)
    assert seen == [8] and run.task == "reach_target" and len(run.ds) == 8 and run.image_size == 64
    assert run.train_cfg.K == 3 and run.configs["train"].K == 3
    spec = run.result()
    assert spec == base.read_run(data / "prep")
    assert set(spec["configs"]) == {"resnet", "train"} and spec["configs"]["train"]["K"] == 3
    assert spec["episodes"] == 8 and spec["dataset_fingerprint"] == run.ds.fingerprint


def test_plan_refuses_bad_input_with_a_clear_message(data):
    """What a new user tries first: an empty batch, no key, a batch of keys (each a one-line ValueError
    before any JAX work); a legacy ``PRNGKey`` works like a typed key."""
    run = data / "runs" / "reach_target" / "read_converged"
    if not run.exists():
        pytest.skip("needs test_train_and_plan[read_converged]'s run")
    planner = Planner.load(run)
    rgbd = planner.database.rgbd[:2]
    with pytest.raises(ValueError, match="holds no images"):
        planner.plan(rgbd[:0], jax.random.key(0), N=2)
    for bad in (None, 0, np.zeros(3, np.float32)):
        with pytest.raises(ValueError, match="key must be a JAX PRNG key"):
            planner.plan(rgbd, bad, N=2)
    with pytest.raises(ValueError, match="one PRNG key for the whole batch"):
        planner.plan(rgbd, jax.random.split(jax.random.key(0), 2), N=2)
    legacy = planner.plan(rgbd, jax.random.PRNGKey(0), N=2)
    assert legacy.motion.shape == (2, 101, 10) and np.all(np.isfinite(legacy.motion))
