"""Training machinery: exact resume after a kill, checkpoint round trip, identity checks."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.training import (CheckpointError, Stage, StageSpec, TrainState, batch_indices, check_shareable_stage,
                              copy_finished_stage, learning_rate)

X = np.random.default_rng(0).normal(size=(64, 3)).astype(np.float32)
Y = X @ np.array([[1.0], [-2.0], [0.5]], np.float32)


def loss_fn(params, batch, rng):
    x, y = batch
    noise = 1e-3 * jax.random.normal(rng, y.shape)  # uses the per-step key: resume must reproduce it
    err = x @ params["w"] + params["b"] - y + noise
    return jnp.mean(err**2), {"mae": jnp.mean(jnp.abs(err))}


def sample(step):
    idx = batch_indices(len(X), 8, 0, step)
    return X[idx], Y[idx]


def params0():
    return {"w": jnp.zeros((3, 1)), "b": jnp.zeros((1,))}


SPEC = StageSpec(steps=40, batch_size=8, lr=0.05, ckpt_every=10, log_every=5)


def test_resume_continues_at_the_right_step(tmp_path):
    full = Stage(tmp_path / "a", "toy", SPEC, {"x": 1}, "fp").fit(params0(), loss_fn, sample, progress=False)
    stage = Stage(tmp_path / "b", "toy", SPEC, {"x": 1}, "fp")
    part = stage.fit(params0(), loss_fn, sample, progress=False, stop_at=20)
    assert int(part.step) == 20 and stage.latest_step() == 20
    # a kill after logging step 25 but before the step-30 checkpoint leaves extra log lines
    with open(stage.dir / "metrics.jsonl", "a") as f:
        f.write(json.dumps({"step": 25, "loss": 9.0}) + "\n")
    resumed = Stage(tmp_path / "b", "toy", SPEC, {"x": 1}, "fp").fit(params0(), loss_fn, sample, progress=False)
    assert int(resumed.step) == 40
    np.testing.assert_array_equal(np.asarray(resumed.params["w"]), np.asarray(full.params["w"]))
    steps = [r["step"] for r in stage.metrics()]
    assert steps == list(range(5, 45, 5))  # no step lost, none repeated
    assert stage.metrics()[-1]["loss"] < stage.metrics()[0]["loss"]
    assert (stage.dir / "loss.png").exists()


def test_relative_run_folder_checkpoints(tmp_path, monkeypatch):
    """The CLIs' default --out is relative (runs/); orbax only takes absolute paths."""
    monkeypatch.chdir(tmp_path)
    stage = Stage("runs/rel", "toy", SPEC, {}, "fp")
    stage.fit(params0(), loss_fn, sample, progress=False, stop_at=10)
    assert stage.latest_step() == 10 and (tmp_path / "runs" / "rel" / "toy" / "checkpoints" / "10").is_dir()


def test_checkpoint_round_trip_is_exact(tmp_path):
    stage = Stage(tmp_path, "toy", SPEC, {}, "fp")
    state = stage.fit(params0(), loss_fn, sample, progress=False, stop_at=10)
    template = TrainState(step=jnp.zeros((), jnp.int32), params=params0(), opt_state=state.opt_state)
    back = stage.restore(template)
    for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(back)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_refuses_other_dataset_or_config_and_corruption(tmp_path):
    Stage(tmp_path, "toy", SPEC, {"x": 1}, "fp").fit(params0(), loss_fn, sample, progress=False, stop_at=10)
    with pytest.raises(CheckpointError, match="dataset"):
        Stage(tmp_path, "toy", SPEC, {"x": 1}, "other")
    with pytest.raises(CheckpointError, match=r"differs in \['x'\]"):
        Stage(tmp_path, "toy", SPEC, {"x": 2}, "fp")
    stage = Stage(tmp_path, "toy", SPEC, {"x": 1}, "fp")
    for f in (stage.dir / "checkpoints" / "10").rglob("*"):
        if f.is_file() and f.stat().st_size > 0:
            f.write_bytes(b"\0garbage")
    with pytest.raises(CheckpointError, match="cannot be restored"):
        stage.fit(params0(), loss_fn, sample, progress=False)


def test_only_a_finished_stage_of_the_same_config_and_dataset_is_shared(tmp_path):
    """copy_finished_stage (READ variants share the autoencoder): an unfinished source, another config
    or another dataset is refused with nothing written; a finished one is copied once, byte for byte."""
    src, dst = tmp_path / "src", tmp_path / "dst"
    Stage(src, "toy", SPEC, {"x": 1}, "fp").fit(params0(), loss_fn, sample, progress=False, stop_at=10)
    with pytest.raises(CheckpointError, match="not a finished"):
        copy_finished_stage(src, dst, "toy", {"x": 1}, "fp")
    Stage(src, "toy", SPEC, {"x": 1}, "fp").fit(params0(), loss_fn, sample, progress=False)
    for config, fingerprint, why in (({"x": 2}, "fp", "another config"), ({"x": 1}, "other", "dataset")):
        with pytest.raises(CheckpointError, match=why):
            check_shareable_stage(src, "toy", config, fingerprint)
        with pytest.raises(CheckpointError, match=why):
            copy_finished_stage(src, dst, "toy", config, fingerprint)
    assert not dst.exists()
    assert copy_finished_stage(src, dst, "toy", {"x": 1}, "fp")
    assert (dst / "toy" / "metrics.jsonl").read_bytes() == (src / "toy" / "metrics.jsonl").read_bytes()
    assert not copy_finished_stage(src, dst, "toy", {"x": 1}, "fp")  # already there: left alone
    assert int(Stage(dst, "toy", SPEC, {"x": 1}, "fp").latest_step()) == SPEC.steps


def test_stage_from_an_older_readjax_accepts_new_fields_at_their_defaults(tmp_path):
    """A field added to a config section since a stage was recorded counts as unchanged at its
    default (new fields default to the old behaviour), and as a change otherwise."""
    old = {"denoiser": {"d_model": 64}, "train": {"steps": 5}}
    Stage(tmp_path, "toy", SPEC, old, "fp").fit(params0(), loss_fn, sample, progress=False, stop_at=5)
    new = {"denoiser": {"d_model": 64, "input_skip": False, "motion_std": []}, "train": {"steps": 5, "K": 3}}
    Stage(tmp_path, "toy", SPEC, new, "fp")  # defaults: accepted
    with pytest.raises(CheckpointError, match=r"differs in \['denoiser'\]"):
        Stage(tmp_path, "toy", SPEC, {**new, "denoiser": {**new["denoiser"], "input_skip": True}}, "fp")


def test_stage_resumes_when_only_an_inference_setting_changed(tmp_path):
    """sde.update (the refinement step) is used at inference only: a stage trained under "cold"
    resumes under "cold_anchor"; a change of a field training reads (sde.lam) is still refused."""
    cfg = {"sde": {"lam": 0.5, "update": "cold"}}
    Stage(tmp_path, "toy", SPEC, cfg, "fp").fit(params0(), loss_fn, sample, progress=False, stop_at=5)
    state = Stage(tmp_path, "toy", SPEC, {"sde": {"lam": 0.5, "update": "cold_anchor"}}, "fp").fit(
        params0(), loss_fn, sample, progress=False, stop_at=10)
    assert int(state.step) == 10
    with pytest.raises(CheckpointError, match=r"differs in \['sde'\]"):
        Stage(tmp_path, "toy", SPEC, {"sde": {"lam": 1.0, "update": "cold"}}, "fp")


def test_learning_rate_schedules(tmp_path):
    """staircase: lr x lr_decay every lr_decay_every steps (constant at lr_decay 1); cosine: lr at
    step 0, half at mid-stage, 0 at the last step, whatever lr_decay says; a cosine stage resumes
    exactly like a staircase one (the rate is a function of the step)."""
    import dataclasses

    from readjax.config import TrainConfig

    stair = StageSpec(steps=100, batch_size=8, lr=0.1, lr_decay=0.5, lr_decay_every=30)
    assert [float(learning_rate(stair)(s)) for s in (0, 29, 30, 61)] == pytest.approx([0.1, 0.1, 0.05, 0.025])
    assert learning_rate(dataclasses.replace(stair, lr_decay=1.0)) == 0.1
    cos = dataclasses.replace(stair, schedule="cosine")
    assert [float(learning_rate(cos)(s)) for s in (0, 50, 100)] == pytest.approx([0.1, 0.05, 0.0], abs=1e-7)
    with pytest.raises(ValueError, match="schedule"):
        learning_rate(dataclasses.replace(stair, schedule="linear"))
    with pytest.raises(ValueError, match="schedule"):
        TrainConfig(schedule="linear")
    spec = dataclasses.replace(SPEC, schedule="cosine")
    full = Stage(tmp_path / "a", "toy", spec, {}, "fp").fit(params0(), loss_fn, sample, progress=False)
    Stage(tmp_path / "b", "toy", spec, {}, "fp").fit(params0(), loss_fn, sample, progress=False, stop_at=20)
    resumed = Stage(tmp_path / "b", "toy", spec, {}, "fp").fit(params0(), loss_fn, sample, progress=False)
    np.testing.assert_array_equal(np.asarray(resumed.params["w"]), np.asarray(full.params["w"]))
    staircase = Stage(tmp_path / "c", "toy", SPEC, {}, "fp").fit(params0(), loss_fn, sample, progress=False)
    assert not np.allclose(np.asarray(staircase.params["w"]), np.asarray(full.params["w"]))


def test_stop_decision_waits_for_patience_and_counts_only_real_improvements():
    import dataclasses

    from readjax.training import stop_decision

    spec = dataclasses.replace(SPEC, stop_patience=100, stop_min_delta=0.1)
    assert stop_decision([(50, 1.0), (100, 0.5)], spec) is None
    assert stop_decision([(50, 1.0), (100, 0.5), (150, 0.49)], spec) is None  # 2 % better: not real; 50 steps
    assert stop_decision([(50, 1.0), (100, 0.5), (150, 0.44), (200, 0.43)], spec) is None  # 12 % at 150
    stop = stop_decision([(50, 1.0), (100, 0.5), (150, 0.49), (200, 0.48)], spec)
    assert stop["stopped_at"] == 200 and stop["best_step"] == 100 and stop["reason"] == "converged"
    assert "10%" in stop["rule"] and "100 steps" in stop["rule"]
    assert stop_decision([(50, 1.0), (100, 0.5), (250, 0.47)], dataclasses.replace(spec, stop_patience=0)) is None


def test_a_stage_stops_on_its_validation_loss_records_why_and_resumes_to_the_same_end(tmp_path):
    """The toy regression converges within ~20 steps: validation every 5 steps, patience 10 ends it
    well before the 200-step cap; stop.json says when and why, the curve logs val_loss, fitting
    again returns the same state at once, and a run killed before the stop ends at the same step
    with the same parameters."""
    import dataclasses

    spec = dataclasses.replace(SPEC, steps=200, val_every=5, stop_patience=10, stop_min_delta=0.05)
    val = [(X[i:i + 8], Y[i:i + 8]) for i in (48, 56)]
    full = Stage(tmp_path / "a", "toy", spec, {}, "fp")
    state = full.fit(params0(), loss_fn, sample, progress=False, val_batches=val)
    stop = full.stop_record()
    assert stop["reason"] == "converged" and int(state.step) == stop["stopped_at"] < 200
    assert full.latest_step() == stop["stopped_at"]
    logged = [r for r in full.metrics() if "val_loss" in r]
    assert [r["step"] for r in logged] == list(range(5, stop["stopped_at"] + 1, 5))
    assert (tmp_path / "a" / "toy" / "loss.png").exists()
    again = full.fit(params0(), loss_fn, sample, progress=False, val_batches=val)
    assert int(again.step) == stop["stopped_at"]
    killed = Stage(tmp_path / "b", "toy", spec, {}, "fp")
    killed.fit(params0(), loss_fn, sample, progress=False, val_batches=val, stop_at=10)
    assert killed.stop_record() is None
    resumed = Stage(tmp_path / "b", "toy", spec, {}, "fp").fit(params0(), loss_fn, sample, progress=False,
                                                                val_batches=val)
    assert int(resumed.step) == stop["stopped_at"]
    np.testing.assert_array_equal(np.asarray(resumed.params["w"]), np.asarray(state.params["w"]))
    capped = Stage(tmp_path / "c", "toy", dataclasses.replace(spec, steps=20), {}, "fp")
    capped.fit(params0(), loss_fn, sample, progress=False, val_batches=val)
    assert capped.stop_record()["reason"] == "step cap" and capped.stop_record()["stopped_at"] == 20


def test_convergence_settings_are_validated():
    from readjax.config import TrainConfig

    with pytest.raises(ValueError, match="validation split"):
        TrainConfig(stop_patience=1000)
    with pytest.raises(ValueError, match="at least one validation"):
        TrainConfig(val_episodes=50, stop_patience=100, val_every=250)
    with pytest.raises(ValueError, match="stop_min_delta"):
        TrainConfig(val_episodes=50, stop_min_delta=1.5)
    with pytest.raises(ValueError, match="non-negative"):
        TrainConfig(val_episodes=-1)
    assert TrainConfig(val_episodes=50, stop_patience=500).stop_patience == 500
