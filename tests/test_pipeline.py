"""A tiny end-to-end run: generate demos -> train READ (both stages) -> plan -> execute in MJX;
and the planner's input checks."""

from __future__ import annotations

import dataclasses
import json
import shutil

import jax
import numpy as np
import pytest

import readjax

from experiments import _cli
from experiments import evaluate as evaluate_cli
from experiments import train as train_cli
from readjax import provenance, retrieval
from readjax.lab import refine_report
from readjax.data import store
from readjax.data.generate import GenerateConfig, generate
from readjax.planner import Planner

pytestmark = pytest.mark.timeout(1500)

TINY = ["vae_steps=6", "steps=4", "vae_batch=4", "batch=4", "ckpt_every=2", "log_every=2",
        "denoiser.enc_depths=0,1,0,1", "denoiser.dec_depths=0,0,1", "denoiser.layers=1"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("e2e")
    data, runs = root / "data", root / "runs"
    for split, n in (("train", 8), ("test", 4)):
        generate(GenerateConfig(task="reach_target", split=split, episodes=n, out=str(data), batch_size=4,
                                image_size=64), progress=False)
    argv = ["--task", "RT", "--data", str(data), "--out", str(runs), "--quiet"] + sum((["--set", s] for s in TINY), [])
    assert _cli.run(train_cli.main, argv) == 0
    return data, runs / "reach_target" / "read"


@pytest.mark.parametrize("n, update", [(0, "renoise"), (2, "cold")])
def test_a_plan_does_not_depend_on_its_batch(run, n, update):
    """Planning 8 images at once equals planning each alone (retrieval and a deterministic refinement
    loop are per-image functions; the paper's re-noising draws its noise per batch, so it is not
    part of this invariance)."""
    data, run_dir = run
    planner = Planner.load(run_dir)
    planner.model.set_refine_update(update)
    test = store.load_dataset(data / "reach_target" / "test").resized(planner.image_size)
    images = np.concatenate([test.rgbd, test.rgbd])  # 8 images
    together = planner.plan(images, jax.random.key(0), N=n)
    for i in (0, 2, 5, 7):
        alone = planner.plan(images[i:i + 1], jax.random.key(0), N=n)
        assert alone.retrieved_index[0] == together.retrieved_index[i]
        np.testing.assert_allclose(alone.motion[0], together.motion[i], atol=1e-4)
        # Not asserted on the joints: IK (25 Newton steps per waypoint, warm-started) turns the batched
        # matmuls' rounding (< 1e-4 here) into up to 0.2 rad on this untrained model's barely
        # reachable poses; tests/sim/test_execute.py checks IK batched = alone on identical poses.


def test_candidates_keep_the_plan_with_the_smallest_fixed_point_residual(run):
    """candidates = 3: each image's plan is the refinement of one of SPE's 3 nearest retrievals, the
    one whose fixed-point residual is smallest; candidates = 1 is the plain top-1 plan; options that
    cannot apply are refused."""
    from readjax.planner import fixed_point_residual

    data, run_dir = run
    planner = Planner.load(run_dir)
    planner.model.set_refine_update("cold")
    test = store.load_dataset(data / "reach_target" / "test").resized(planner.image_size)
    key = jax.random.key(0)
    top1 = planner.plan(test.rgbd, key, N=2, rounds=1)  # one refinement per candidate (rounds: below)
    np.testing.assert_array_equal(planner.plan(test.rgbd, key, N=2, candidates=1, rounds=1).motion, top1.motion)
    best = planner.plan(test.rgbd, key, N=2, candidates=3, rounds=1)
    feats = planner.encode(test.rgbd)
    order = np.argsort(np.asarray(planner.model.spe_distances(feats, planner.db_uv, planner.db_tokens)), axis=1)[:, :3]
    assert order[:, 0].tolist() == top1.retrieved_index.tolist()
    residuals = []
    for c in range(3):
        m = planner.model.generate(feats, planner.db_motion[order[:, c]], key, 2)
        residuals.append(np.asarray(fixed_point_residual(planner.model, planner.camera, feats, m, key)))
        kept = best.retrieved_index == order[:, c]
        np.testing.assert_allclose(best.motion[kept], np.asarray(m)[kept], atol=1e-5)
    residuals = np.stack(residuals, axis=1)
    assert all(idx in order[i] for i, idx in enumerate(best.retrieved_index))
    chosen = [list(order[i]).index(idx) for i, idx in enumerate(best.retrieved_index)]
    np.testing.assert_array_equal(chosen, residuals.argmin(axis=1))
    for kwargs, match in [(dict(N=0, candidates=3), "N > 0"), (dict(N=2, candidates=0), "positive"),
                          (dict(N=2, candidates=3, retrieval_method="cheat", gt_motion=test.motion), "SPE"),
                          (dict(N=2, candidates=99), "exceeds")]:
        with pytest.raises(ValueError, match=match):
            planner.plan(test.rgbd, key, **kwargs)


def test_rounds_refine_again_from_the_previous_plan(run):
    """rounds = 2: the plan is a second refinement started from the first one's plan (noise from
    fold_in(key, 1)), still reported against the database motion SPE retrieved; rounds = 1 is the
    plain plan; rounds combine with candidates; rounds that cannot apply are refused."""
    data, run_dir = run
    planner = Planner.load(run_dir)
    planner.model.set_refine_update("renoise")  # a stochastic loop: the second round's key matters
    test = store.load_dataset(data / "reach_target" / "test").resized(planner.image_size)
    key = jax.random.key(0)
    once = planner.plan(test.rgbd, key, N=2, rounds=1)
    assert planner.default_rounds == 2  # the cpu preset's sde.rounds: what plan() runs when given none
    np.testing.assert_array_equal(planner.plan(test.rgbd, key, N=2).motion,
                                  planner.plan(test.rgbd, key, N=2, rounds=2).motion)
    twice = planner.plan(test.rgbd, key, N=2, rounds=2)
    feats = planner.encode(test.rgbd)
    by_hand = planner.model.generate(feats, jax.numpy.asarray(once.motion), jax.random.fold_in(key, 1), 2)
    np.testing.assert_allclose(twice.motion, np.asarray(by_hand), atol=1e-5)
    assert twice.retrieved_index.tolist() == once.retrieved_index.tolist()
    np.testing.assert_array_equal(twice.retrieved, once.retrieved)
    assert np.abs(twice.motion - once.motion).max() > 1e-4  # a second round is not the first again
    planner.model.set_refine_update("cold")  # deterministic and per image: the kept plans can be recomputed
    both = planner.plan(test.rgbd, key, N=2, candidates=2, rounds=2)
    m_r = planner.db_motion[jax.numpy.asarray(both.retrieved_index)]
    np.testing.assert_allclose(both.motion, np.asarray(planner.refine(feats, m_r, key, 2, rounds=2)), atol=1e-4)
    for kwargs, match in [(dict(N=0, rounds=2), "N > 0"), (dict(N=2, rounds=0), "positive")]:
        with pytest.raises(ValueError, match=match):
            planner.plan(test.rgbd, key, **kwargs)


def test_train_writes_checkpoints_metrics_and_plots(run):
    _, run_dir = run
    for stage in ("vae", "read"):
        assert (run_dir / stage / "loss.png").exists()
        assert (run_dir / stage / "metrics.jsonl").read_text().count("\n") >= 2
    assert (run_dir / "run.json").exists()


def test_a_variant_starts_from_a_finished_autoencoder_or_is_refused(run, tmp_path, capsys):
    """--vae-from copies another run's finished autoencoder stage instead of training one (READ's
    self-fed variant changes only the denoiser's objective); another autoencoder config, or a method
    without that stage, is refused with nothing written."""
    data, run_dir = run
    argv = ["--task", "RT", "--data", str(data), "--out", str(tmp_path), "--quiet"] + sum((["--set", s] for s in TINY), [])
    assert _cli.run(train_cli.main, argv + ["--name", "sf", "--set", "sde.self_feed=0.5", "--vae-from", str(run_dir)]) == 0
    variant = tmp_path / "reach_target" / "sf"
    assert (variant / "vae" / "metrics.jsonl").read_text() == (run_dir / "vae" / "metrics.jsonl").read_text()
    assert (variant / "read" / "loss.png").exists()
    assert json.loads((variant / "run.json").read_text())["configs"]["sde"]["self_feed"] == 0.5
    capsys.readouterr()
    assert _cli.run(train_cli.main, argv + ["--name", "kl", "--set", "vae.kl_weight=0.5", "--vae-from", str(run_dir)]) == 2
    assert "cannot be shared" in capsys.readouterr().err and not (tmp_path / "reach_target" / "kl").exists()
    assert _cli.run(train_cli.main, argv + ["--name", "un", "--vae-from", str(tmp_path / "reach_target" / "sf" / "read")]) == 2
    assert "no autoencoder stage" in capsys.readouterr().err and not (tmp_path / "reach_target" / "un").exists()
    assert _cli.run(train_cli.main, argv + ["--model", "deterministic", "--vae-from", str(run_dir)]) == 2
    assert "has none" in capsys.readouterr().err


def test_plan_and_execute(run, capsys, tmp_path):
    data, run_dir = run
    media = tmp_path / "media"  # --out: rendered apart from RUN/eval, which the tables read
    argv = ["--run", str(run_dir), "--episodes", "4", "--N", "2", "--batch-size", "4", "--videos", "1",
            "--out", str(media), "--quiet"]
    assert _cli.run(evaluate_cli.main, argv) == 0
    out = capsys.readouterr().out
    assert "RT" in out and "success" in out and str(media) in out
    # the cpu preset refines with the anchored cold update in two rounds: its results carry both in their name
    name = "spe_N2_cold_anchor_rounds2"
    assert (media / f"{name}.json").exists() and (media / f"{name}_overlay.png").exists()
    assert (media / f"{name}_rollouts.mp4").stat().st_size > 1000
    assert json.loads((media / f"{name}.json").read_text())["eval_config"]["rounds"] == 2
    assert not (run_dir / "eval" / f"{name}.json").exists()


def test_the_papers_loop_is_evaluated_under_its_own_name(run, capsys):
    data, run_dir = run
    argv = ["--run", str(run_dir), "--episodes", "4", "--N", "2", "--batch-size", "4", "--videos", "0",
            "--refine", "renoise", "--rounds", "1", "--quiet"]
    assert _cli.run(evaluate_cli.main, argv) == 0
    result = json.loads((run_dir / "eval" / "spe_N2.json").read_text())
    assert result["eval_config"]["refine_update"] == "renoise" and result["episodes"] == 4
    assert result["eval_config"]["rounds"] == 1
    # provenance: the data it ran on and the code that ran it
    test = store.load_dataset(data / "reach_target" / "test")
    assert result["test_fingerprint"] == test.fingerprint
    assert result["train_fingerprint"] == json.loads((run_dir / "run.json").read_text())["dataset_fingerprint"]
    assert result["commit"] == provenance.commit() != ""
    # how long each stage trained and why it stopped (the tiny run: at its step caps)
    assert {k: (v["steps"], v["stop"]["reason"]) for k, v in result["training"].items()} == {
        "vae": (6, "step cap"), "read": (4, "step cap")}
    # every failure has a mode, every success none; RT has nothing to grasp, so no missed grasps
    fails = result["failures"]
    assert [m is None for m in fails["mode"]] == [bool(s) for s in result["success"]]
    assert sum(fails["counts"].values()) == 4 - sum(result["success"]) and "missed grasp" not in fails["counts"]
    assert len(fails["keyframe_error_cm"]) == 4 and fails["gt_closings"] == [0] * 4
    assert len(fails["start_keyframe_error_cm"]) == 4 and fails["held"] is None  # READ refines a retrieval
    # RT has landmarks: every plan's end point is classified (target or distractor)
    assert len(result["end_points"]["nearest_landmark"]) == 4
    assert set(result["end_points"]["nearest_landmark"]) <= {"target", "distractor"}
    # and READ retrieves: success is split by where refinement started, every episode counted once
    starts = result["starts"]
    assert len(starts["start_nearest"]) == 4 and set(starts["start_nearest"]) <= {"target", "distractor"}
    by = starts["success_by_start"]
    assert sum(c["episodes"] for b in by.values() for c in b.values()) == 4
    assert sum(c["succeeded"] for b in by.values() for c in b.values()) == sum(result["success"])


def test_a_val_evaluation_goes_to_run_val_and_a_choice_to_the_test_record(run, tmp_path, capsys):
    """--split val evaluates the validation episodes (seeds from 2,000,000, generated first) into
    RUN/val/, never RUN/eval/ nor a report; --choice refines a test evaluation with the setting chosen
    on them, and the record names it."""
    from readjax.lab import report

    data, run_dir = run
    argv = ["--run", str(run_dir), "--split", "val", "--episodes", "2", "--N", "1", "--batch-size", "2",
            "--videos", "0", "--rounds", "1", "--refine", "renoise", "--quiet"]
    assert _cli.run(evaluate_cli.main, argv) == 0
    rec = json.loads((run_dir / "val" / "spe_N1.json").read_text())
    val = store.load_dataset(data / "reach_target" / "val", limit=2)
    assert rec["split"] == "val" and rec["test_fingerprint"] == val.fingerprint
    assert min(rec["seeds"]) >= 2_000_000 and rec["episodes"] == 2
    assert not (run_dir / "eval" / "spe_N1.json").exists()
    collected = report.collect(run_dir.parent.parent)
    assert not any(r.get("split") == "val" or "/val/" in r["_file"] for r in collected)
    choice_file = tmp_path / "choice.json"
    choice_file.write_text(json.dumps({
        "task": "reach_target", "run": run_dir.name, "N": 1, "episodes": 2, "val_fingerprint": rec["test_fingerprint"],
        "chosen": {"rounds": 1, "refine": "renoise", "candidates": 1}, "candidates": []}))
    shown = tmp_path / "shown"
    test_argv = ["--run", str(run_dir), "--episodes", "2", "--N", "1", "--batch-size", "2", "--videos", "0",
                 "--out", str(shown), "--quiet", "--choice", str(choice_file)]
    assert _cli.run(evaluate_cli.main, test_argv) == 0
    chosen = json.loads((shown / "spe_N1.json").read_text())
    assert chosen["split"] == "test" and chosen["chosen_on"] == "val"
    assert chosen["choice"]["file"] == str(choice_file) and chosen["choice"]["val_fingerprint"] == val.fingerprint
    assert (chosen["eval_config"]["rounds"], chosen["eval_config"]["refine_update"]) == (1, "renoise")
    assert max(chosen["seeds"]) < 2_000_000
    capsys.readouterr()
    assert _cli.run(evaluate_cli.main, test_argv + ["--rounds", "2"]) == 2
    assert "--choice sets" in capsys.readouterr().err
    assert _cli.run(evaluate_cli.main, argv + ["--out", str(run_dir / "eval")]) == 2
    assert "the tables read" in capsys.readouterr().err


def test_goal_shift_on_the_trained_run(run, tmp_path, capsys):
    """The goal-shift diagnostic renders the scenes the test images show (bit for bit up to float
    rounding), plans from the same oracle start on both images, and finds the goal's move in the
    image features near the goal and not far from it."""
    from experiments import goal_shift as goal_shift_cli
    from readjax.lab import goal_shift

    data, run_dir = run
    out = tmp_path / "shift.json"
    argv = ["--run", str(run_dir), "--data", str(data), "--images", "4", "--rank", "1", "3", "--N", "1",
            "--batch-size", "4", "--out", str(out), "--quiet"]
    assert _cli.run(goal_shift_cli.main, argv) == 0
    result = json.loads(out.read_text())
    assert result["replay_max_abs_diff"] < 1e-4 and result["goal_move_px_median"] > 0.5
    assert [r["rank"] for r in result["ranks"]] == [1, 3]
    assert all(len(r["sensitivity"]) == 4 and len(r["start_px"]) == 4 for r in result["ranks"])
    assert sum(b["n"] for b in result["by_start"]) == 8
    assert result["training_inputs"]["draws"] == 4000  # READ: its training inputs' reach beside the plans'
    reach = result["feature_reach"]
    assert reach[0]["lo"] == 0 and reach[0]["median"] > 10 * reach[-1]["median"]
    assert out.with_suffix(".png").exists() and "| i = 3 |" in capsys.readouterr().out
    # the same image twice: nothing changes anywhere
    planner = Planner.load(run_dir, data)
    test = store.load_dataset(data / "reach_target" / "test").resized(planner.image_size)
    uv = test.motion[:, -1, :2]
    feats = goal_shift.encode(planner, test.rgbd)
    assert all(b["median"] == 0 for b in goal_shift.feature_reach(planner, feats, feats, uv, uv))
    assert _cli.run(goal_shift_cli.main, argv + ["--shift-cm", "0"]) == 2


def test_training_inputs_decode_the_sde_marginal(run):
    """The goal-shift diagnostic's training support draws the denoiser's inputs from the SDE's
    marginal: at t = t_min it is Enc(M) itself, so the inputs end where the autoencoder's round trip
    of M ends, whatever M_R; with no noise to speak of (lam = 1e-6) at t = 1 it is its mean,
    zR + a(1) (z0 - zR)."""
    import jax.numpy as jnp

    from readjax.lab import goal_shift
    from readjax.diffusion import irsde
    from readjax.diffusion import latent as latent_lib

    data, run_dir = run
    planner = Planner.load(run_dir, data)
    model, motions = planner.model, np.asarray(planner.database.motion)
    n = len(motions)
    i, j = np.arange(n), (np.arange(n) + 3) % n
    sde = model.configs["sde"]
    near = goal_shift.training_input_ends(model, motions, i, j, np.full(n, sde.t_min, np.float32),
                                          jax.random.PRNGKey(0))
    enc, dec = latent_lib.codec(model.ae, model.ae_params, model.latent)
    z = enc(jnp.asarray(motions))
    np.testing.assert_allclose(near, np.asarray(dec(z))[:, -1, :2], atol=2e-3)
    model.configs["sde"] = dataclasses.replace(sde, lam=1e-6, theta0=sde.theta_start)
    try:
        far = goal_shift.training_input_ends(model, motions, i, j, np.ones(n, np.float32),
                                             jax.random.PRNGKey(1))
        a = irsde.mean_coef(1.0, model.configs["sde"])
    finally:
        model.configs["sde"] = sde
    np.testing.assert_allclose(far, np.asarray(dec(z[j] + a * (z[i] - z[j])))[:, -1, :2], atol=1e-4)
    px = goal_shift.training_input_px(planner, draws=64, seed=1)
    assert px.shape == (64,) and np.all(px >= 0)
    np.testing.assert_array_equal(px, goal_shift.training_input_px(planner, draws=64, seed=1))
    summary = goal_shift.support_summary(px)
    assert sum(b["share"] for b in summary["by_start"]) == pytest.approx(1.0)
    q = summary["px_percentiles"]
    assert q["50"] <= q["90"] <= q["99"] <= q["99.9"]


def test_refine_report_on_the_trained_run(run, tmp_path, capsys):
    from experiments import refine_report as refine_report_cli

    data, run_dir = run
    out = tmp_path / "refine.json"
    argv = ["--run", str(run_dir), "--data", str(data), "--images", "4", "--N", "0", "1", "3",
            "--batch-size", "4", "--out", str(out), "--quiet"]
    assert _cli.run(refine_report_cli.main, argv) == 0
    result = json.loads(out.read_text())
    assert [(r["split"], r["N"]) for r in result["rows"]] == [(s, n) for s in ("train", "test") for n in (0, 1, 3)]
    train0 = result["rows"][0]
    # a training image retrieves its own demonstration: N = 0 is the exact answer
    assert train0["err_cm_median"] == 0 and train0["within_3cm"] == 1.0
    # the run's two rounds of N = 3 steps: 6 predictions along the loop, 5 drifts between them
    assert result["rounds"] == 2
    assert len(result["loops"]["test"]["drift_mean_abs"]) == 5
    assert len(result["loops"]["test"]["end_depth_err_mm_mean"]) == 6
    assert [r["t"] for r in result["clean_input"]["train"]] == [None, 1.0, 0.5, 0.1, 0.01]
    assert "| train | 3 |" in capsys.readouterr().out
    assert _cli.run(refine_report_cli.main, argv + ["--rounds", "1"]) == 0
    once = json.loads(out.read_text())
    assert once["rounds"] == 1 and len(once["loops"]["test"]["end_depth_err_mm_mean"]) == 3
    assert once["rows"][0] == result["rows"][0]  # N = 0 (the retrieved motion) has no rounds
    assert _cli.run(refine_report_cli.main, argv + ["--N", "-1"]) == 2
    # from the oracle's start: the test plans at N = 0 are each episode's nearest training demo
    assert _cli.run(refine_report_cli.main, argv + ["--retrieval", "cheat", "--N", "0"]) == 0
    cheat = json.loads(out.read_text())
    assert cheat["retrieval"] == "cheat"
    planner = Planner.load(run_dir, data)
    test = store.load_dataset(data / "reach_target" / "test").resized(planner.image_size)
    nearest = retrieval.oracle_retrieve(planner.camera, test.motion[:4], planner.database.motion, 1)
    want = refine_report.summarise(refine_report.end_errors(planner.camera, planner.database.motion[nearest],
                                                            test.motion[:4], planner.image_size))
    assert cheat["rows"][1]["split"] == "test"
    assert cheat["rows"][1]["err_cm_median"] == pytest.approx(want["err_cm_median"], abs=1e-6)
    # from a poorer start (Table 8's protocol): the oracle's 3rd neighbour, each image's error recorded
    assert _cli.run(refine_report_cli.main, argv + ["--retrieval", "cheat", "--rank", "3", "--N", "0"]) == 0
    third = json.loads(out.read_text())
    nearest3 = retrieval.oracle_retrieve(planner.camera, test.motion[:4], planner.database.motion, 3)
    errs = refine_report.end_errors(planner.camera, planner.database.motion[nearest3], test.motion[:4],
                                    planner.image_size)["err_cm"]
    assert third["rank"] == 3 and third["rows"][1]["err_cm"] == pytest.approx(errs, abs=1e-3)
    assert "the oracle's neighbour 3" in capsys.readouterr().out
    assert _cli.run(refine_report_cli.main, argv + ["--rank", "3"]) == 2  # SPE's start has no rank
    # several starts: each one's report, then where refinement stops correcting, with a plot
    ranges = tmp_path / "range.json"
    several = argv[:-3] + ["--out", str(ranges), "--quiet", "--retrieval", "cheat", "--rank", "1", "3", "--N", "0", "1"]
    assert _cli.run(refine_report_cli.main, several) == 0
    combined = json.loads(ranges.read_text())
    assert [r["rank"] for r in combined["by_rank"]] == [1, 3] and combined["reports"][1]["rank"] == 3
    assert combined["reports"][0]["clean_input"] and not combined["reports"][1]["clean_input"]  # computed once
    assert sum(b["plans"] for b in combined["by_start"]) == 8 and combined["training_pairs"]["max_cm"] > 0
    assert ranges.with_suffix(".png").exists() and "training pairs" in capsys.readouterr().out
    assert _cli.run(refine_report_cli.main, several[:-3] + ["--N", "1", "3"]) == 2  # no N = 0 to compare with


def test_planner_api_and_bad_input(run):
    data, run_dir = run
    assert readjax.Planner is Planner  # the public name
    planner = readjax.Planner.load(run_dir)
    test = store.load_dataset(data / "reach_target" / "test")
    plan = planner.plan(test.rgbd[:2], jax.random.key(0), N=2)
    assert plan.motion.shape == (2, 101, 10) and plan.joints.shape == (2, 101, 7)
    assert plan.positions.shape == (2, 101, 3) and np.all(np.isfinite(plan.motion))
    again = planner.plan(test.rgbd[:2], jax.random.key(0), N=2)
    np.testing.assert_array_equal(plan.motion, again.motion)  # same key -> same plan
    retrieved = planner.plan(test.rgbd[:2], jax.random.key(0), N=0)
    np.testing.assert_array_equal(retrieved.motion, retrieved.retrieved)  # N = 0: the retrieved motion
    with pytest.raises(ValueError, match="batched"):
        planner.plan(test.rgbd[0], jax.random.key(0))
    with pytest.raises(ValueError, match=r"shape \(B, 64, 64, 4\)"):
        planner.plan(test.rgbd[:, :32, :32], jax.random.key(0))
    bad = test.rgbd[:1].copy()
    bad[0, 3, 3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        planner.plan(bad, jax.random.key(0))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        planner.plan(test.rgbd[:1] * 255, jax.random.key(0))
    with pytest.raises(ValueError, match="dtype"):
        planner.plan((test.rgbd[:1] * 255).astype(np.uint8), jax.random.key(0))
    with pytest.raises(ValueError, match="N must be"):
        planner.plan(test.rgbd[:1], jax.random.key(0), N=-1)


def test_missing_run_is_a_clear_error(tmp_path, capsys):
    assert _cli.run(evaluate_cli.main, ["--run", str(tmp_path / "nope")]) == 2
    assert "not a training run" in capsys.readouterr().err


def _train_here(argv):
    """An ``experiments.train`` step's command run in this process (the tests' stand-in for Ray)."""
    import subprocess

    assert argv[1:3] == ["-m", "experiments.train"]
    return subprocess.CompletedProcess(argv, _cli.run(train_cli.main, argv[3:]))


def _here(steps, log, on_finished, **ray_options):
    """A sweep's training steps run in order in this process, as ``ray_grid.run_on_ray`` is called."""
    from readjax.lab.steps import run_in_order

    return run_in_order(steps, log=log, runner=_train_here, on_finished=on_finished)


def test_sweep_resumes_and_reports(run, tmp_path, monkeypatch):
    from experiments import report as report_cli
    from experiments import sweep as sweep_cli
    from readjax.lab import ray_grid

    monkeypatch.setattr(ray_grid, "run_on_ray", _here)  # no Ray outside a private network namespace
    data, _ = run
    argv = ["--task", "RT", "--grid", "N=0,1", "L=0.3,0.5", "--episodes", "2", "--batch-size", "2",
            "--data", str(data), "--out", str(tmp_path), "--quiet",
            "--results", str(tmp_path / "committed")] + sum((["--set", s] for s in TINY), [])
    assert _cli.run(sweep_cli.main, argv) == 0
    sweep_dir = tmp_path / "reach_target" / "sweep"
    cells = json.loads((sweep_dir / "sweep.json").read_text())["cells"]
    assert [(c["N"], c["L"]) for c in cells] == [(0, 0.3), (1, 0.3), (0, 0.5), (1, 0.5)]
    # each cell records what it trained with: the cpu preset's K = 50, not the paper's A (K = 3)
    recorded = json.loads((sweep_dir / "sweep.json").read_text())
    assert recorded["reference"] == {"N": 100, "K": 50, "L": 0.5, "T": 2.0}
    assert {c["K"] for c in cells} == {50} and {c["T"] for c in cells} == {2.0}
    assert all(len(c["outcomes"]) == len(c["seeds"]) == 2 for c in cells)  # per episode, for paired tests
    committed = tmp_path / "committed" / "reach_target" / "sweep"
    assert json.loads((committed / "sweep.json").read_text())["cells"] == cells and (committed / "sweep.png").exists()
    assert (sweep_dir / "sweep.png").exists() and "| setting | N | K | L | T |" in (sweep_dir / "table.md").read_text()
    # the autoencoder is trained once and shared across L values
    assert (sweep_dir / "L0.5" / "vae" / "metrics.jsonl").read_text() == \
        (sweep_dir / "L0.3" / "vae" / "metrics.jsonl").read_text()
    stamps = {f: f.stat().st_mtime_ns for f in sweep_dir.rglob("*.json") if "eval" in f.parts}
    assert len(stamps) == 4
    assert _cli.run(sweep_cli.main, argv) == 0  # a finished sweep recomputes nothing
    assert {f: f.stat().st_mtime_ns for f in stamps} == stamps
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(tmp_path / "committed"), "--out", str(out)]) == 0
    assert "## Sweep: read on reach_target (2 episodes per cell)" in out.read_text()  # results/ alone suffices
    assert _cli.run(report_cli.main, ["--runs", str(tmp_path), "--out", str(out)]) == 0
    text = out.read_text()
    # a root holding only a sweep: its cells appear in the sweep's Table-7 layout, not as method rows
    assert "## Sweep: read on reach_target (2 episodes per cell)" in text and "| setting | N | K | L | T | RT |" in text
    assert "| method |" not in text and str(sweep_dir / "L0.3" / "eval" / "sweep_N0.json") in text
    # every cell records its test episodes and its autoencoder (one, shared: the same training trace)
    assert {c["test_fingerprint"] for c in cells} == {store.load_dataset(data / "reach_target" / "test",
                                                                          limit=2).fingerprint}
    assert len({c["vae_trace"] for c in cells}) == 1 and len(cells[0]["vae_trace"]) == 16
    # a fresh machine (the sweep's runs gone): the committed cells are kept, nothing trains or evaluates
    from readjax import methods
    from readjax.lab import sweep as sweep_lib
    from readjax.lab import sweep_grid
    shutil.rmtree(sweep_dir)
    monkeypatch.setattr(sweep_lib.evaluation, "evaluate", lambda *a, **k: pytest.fail("evaluated again"))
    monkeypatch.setattr(methods.module("read"), "train", lambda *a, **k: pytest.fail("trained again"))
    assert _cli.run(sweep_cli.main, argv) == 0
    assert json.loads((sweep_dir / "sweep.json").read_text())["cells"] == cells
    # ... but only cells measured on these episodes: one committed on other episodes trains again
    committed_json = committed / "sweep.json"
    moved = json.loads(committed_json.read_text())
    moved["cells"][0]["test_fingerprint"] = "0" * 16
    committed_json.write_text(json.dumps(moved))
    shutil.rmtree(sweep_dir)
    with pytest.raises(pytest.fail.Exception, match="trained again"):
        sweep_lib.run_sweep(sweep_grid.SweepConfig(task="RT", grid={"N": [0, 1], "L": [0.3, 0.5]}, data=str(data),
                                                  out=str(tmp_path), episodes=2, batch_size=2, sets=tuple(TINY),
                                                  results=str(tmp_path / "committed")), progress=False)
    # ... unless asked to keep cells on the same seeds from another version of the split (another CPU's
    # float rounding): then nothing trains, and the cell keeps its own fingerprint
    shutil.rmtree(sweep_dir, ignore_errors=True)
    assert _cli.run(sweep_cli.main, argv + ["--other-split-versions"]) == 0
    assert json.loads((sweep_dir / "sweep.json").read_text())["cells"] == moved["cells"]


def test_a_table7_sweep_evaluates_the_reference_run_instead_of_training_it(run, tmp_path, monkeypatch):
    """--vary one --reference-run: setting A is the finished run (evaluated at each N, not trained
    again), each other value is trained alone from A, starting from A's autoencoder; the table is
    written after each setting, so a sweep cut short keeps its finished cells."""
    from readjax.lab import sweep as sweep_lib
    from readjax.lab import sweep_grid, sweep_table

    data, trained = run
    written, write = [], sweep_table.write_sweep
    monkeypatch.setattr(sweep_table, "write_sweep",
                        lambda sw, folder: (written.append(len(sw["cells"])), write(sw, folder)))
    cfg = sweep_grid.SweepConfig(task="RT", grid={"N": [0, 1], "T": [0.5, 2.0]}, data=str(data), out=str(tmp_path),
                                episodes=2, batch_size=2, sets=tuple(TINY), reference_run=str(trained), vary="one")
    out = sweep_lib.run_sweep(cfg, progress=False, execute=_here)
    cells = [(c["N"], c["T"], c["run"]) for c in out["cells"]]
    sweep_dir = tmp_path / "reach_target" / "sweep"
    assert cells == [(0, 2.0, str(trained)), (1, 2.0, str(trained)), (100, 2.0, str(trained)),
                     (100, 0.5, "reach_target/sweep/T0.5")]
    assert not (sweep_dir / "T2" / "vae").exists() and (sweep_dir / "T2" / "eval" / "sweep_N1.json").exists()
    assert not (trained / "eval" / "sweep_N1.json").exists()  # the reference run's folder is left as it was
    assert json.loads((sweep_dir / "T0.5" / "vae" / "stage.json").read_text())["dataset_fingerprint"] == \
        json.loads((trained / "vae" / "stage.json").read_text())["dataset_fingerprint"]
    assert "| A (default) | 100 | 50 | 0.5 | 2 |" in sweep_table.format_table7(out)
    assert written == [3, 4]  # after A's three cells, then after T = 0.5's
    # a run trained otherwise is refused before any work
    other = dataclasses.replace(cfg, sets=tuple(TINY) + ("sde.lam=0.3",), name="other")
    with pytest.raises(ValueError, match="sde.lam"):
        sweep_lib.run_sweep(other, progress=False, execute=_here)
    # A's cells take the reference run's own evaluations of the same episodes (the pipeline's) instead
    # of running them again: marked outcomes come back, and nothing is evaluated
    ref = tmp_path / "ref"
    shutil.copytree(trained, ref, ignore=shutil.ignore_patterns("eval"))
    (ref / "eval").mkdir()
    for n in (1, 100):
        cell = json.loads((sweep_dir / "T2" / "eval" / f"sweep_N{n}.json").read_text())
        (ref / "eval" / f"spe_N{n}.json").write_text(json.dumps({**cell, "name": f"spe_N{n}",
                                                                  "success": [not x for x in cell["success"]]}))
    monkeypatch.setattr(sweep_lib.evaluation, "evaluate", lambda *a, **k: pytest.fail("evaluated again"))
    again = sweep_lib.run_sweep(dataclasses.replace(cfg, grid={"N": [1]}, reference_run=str(ref), name="again"),
                                progress=False, execute=_here)
    for c in again["cells"]:
        cell = json.loads((sweep_dir / "T2" / "eval" / f"sweep_N{c['N']}.json").read_text())
        assert c["outcomes"] == [int(not x) for x in cell["success"]]
        reused = json.loads((tmp_path / "reach_target" / "again" / "default" / "eval" / f"sweep_N{c['N']}.json")
                            .read_text())  # a grid of N alone: A's folder is "default"
        assert reused["reused_from"] == str(ref / "eval" / f"spe_N{c['N']}.json")


def test_a_sweeps_trainings_are_steps_and_each_cell_is_published_once_trained(run, tmp_path, monkeypatch):
    """Each cell still to train is an `experiments.train` step with the cell's overrides, started from
    the shared autoencoder (the reference run's, or else the first cell's, trained alone first, which
    the others need); each cell is evaluated and published, in the sweep's order, once its training
    has finished. End to end with the trainings run here; then the steps of a sweep without a
    reference run."""
    from readjax.lab import sweep as sweep_lib
    from readjax.lab import sweep_grid, sweep_table

    data, trained = run
    handed, written = [], []
    write = sweep_table.write_sweep
    monkeypatch.setattr(sweep_table, "write_sweep", lambda sw, folder: (written.append(len(sw["cells"])), write(sw, folder)))

    def execute(steps, log, on_finished):
        handed.append([s.label for s in steps])
        return _here(steps, log, lambda step: (written.append(step.label), on_finished(step)))

    cfg = sweep_grid.SweepConfig(task="RT", grid={"T": [0.5]}, data=str(data), out=str(tmp_path), episodes=2,
                                batch_size=2, sets=tuple(TINY), reference_run=str(trained), vary="one")
    out = sweep_lib.run_sweep(cfg, progress=False, execute=execute)
    cell = tmp_path / "reach_target" / "sweep" / "T0.5"
    assert handed == [["train T0.5"]] and written == ["train T0.5", 1, 2]  # A's cell, then T0.5's, once trained
    assert [(c["T"], c["run"]) for c in out["cells"]] == [(2.0, str(trained)), (0.5, "reach_target/sweep/T0.5")]
    assert (cell / "read" / "stop.json").exists()
    assert json.loads((cell / "run.json").read_text())["configs"]["sde"]["theta1"] == 0.5
    assert out["cells"][0]["vae_trace"] == out["cells"][1]["vae_trace"]  # started from A's autoencoder
    assert sweep_lib.run_sweep(cfg, progress=False, execute=lambda *a, **k: pytest.fail("trained again")) == out

    fresh = dataclasses.replace(cfg, grid={"T": [0.5, 2.0]}, reference_run=None, name="fresh")
    plan = [({"T": t}, f"T{t:g}", tmp_path / "reach_target" / "fresh" / f"T{t:g}", None,
             tmp_path / "reach_target" / "fresh" / f"T{t:g}", [100], None) for t in (2.0, 0.5)]
    steps = sweep_lib.training_steps(fresh, "reach_target", plan, None)
    assert [s.label for s in steps] == ["train T2 (autoencoder only)", "train T2", "train T0.5"]
    first = str(tmp_path / "reach_target" / "fresh" / "T2")
    assert steps[0].argv[steps[0].argv.index("--stage") + 1] == "vae" and "--vae-from" not in steps[1].argv
    assert steps[2].argv[steps[2].argv.index("--vae-from") + 1] == first
    assert all(s.needs == [steps[0]] for s in steps[1:]) and all(s.kind == "train" and s.resumes for s in steps)
    args = train_cli.parser().parse_args(steps[2].argv[3:])  # what experiments.train will train with
    assert args.set == sweep_grid.cell_overrides(fresh, {"T": 0.5}) and args.name == "fresh/T0.5"


def test_ae_report_on_the_trained_run(run, tmp_path, capsys):
    from experiments import ae_report as ae_report_cli

    data, run_dir = run
    out = tmp_path / "ae.json"
    argv = ["--runs", str(run_dir), "--data", str(data), "--split", "test", "--episodes", "2", "--out", str(out)]
    assert _cli.run(ae_report_cli.main, argv) == 0
    rows = json.loads(out.read_text())["rows"]
    assert [r["episodes"] for r in rows] == [2, 2]
    rec = rows[1]["reconstruction"]
    assert np.isfinite(rec["end_pos_err_mm_median"]) and rec["end_pos_err_mm_p95"] >= rec["end_pos_err_mm_median"]
    assert "end pos err mm" in out.with_suffix(".md").read_text()
    assert _cli.run(ae_report_cli.main, ["--runs", str(tmp_path / "nope"), "--data", str(data)]) == 2

    # --execute: the reference row is the ground-truth replay through the evaluation path (100 %), and
    # every autoencoder row gains its round trip's task success, episode by episode
    assert _cli.run(ae_report_cli.main, argv + ["--execute"]) == 0
    record = json.loads(out.read_text())
    reference, trained = record["rows"]
    assert reference["task_success"] == {"rate": 1.0, "successes": 2, "success": [1, 1]}
    ts = trained["task_success"]
    assert len(ts["success"]) == 2 and set(ts["success"]) <= {0, 1} and ts["successes"] == sum(ts["success"])
    assert len(record["seeds"]) == 2 and record["dataset_fingerprint"]
    assert "| task success |" in out.with_suffix(".md").read_text() and "2 / 2 |" in out.with_suffix(".md").read_text()


def test_ae_report_execute_refuses_a_split_whose_ground_truth_fails(run, tmp_path, capsys):
    """Executed round trips mean something only where the recorded demos themselves succeed."""
    import h5py

    from experiments import ae_report as ae_report_cli

    data, run_dir = run
    split = data / "reach_target" / "test"
    broken = tmp_path / "reach_target" / "test"
    broken.mkdir(parents=True)
    for f in split.iterdir():
        if f.name != "verify.json":
            (broken / f.name).write_bytes(f.read_bytes())
    with h5py.File(broken / "shard_00000.h5", "r+") as f:
        f["motion"][...] = np.asarray(f["motion"])[::-1]  # each episode gets another episode's motion
    out = tmp_path / "ae.json"
    argv = ["--runs", str(run_dir), "--data", str(tmp_path), "--execute", "--out", str(out)]
    assert _cli.run(ae_report_cli.main, argv) == 2
    assert "the ground truth replays at" in capsys.readouterr().err and not out.exists()


def test_the_autoencoder_row_executes_the_round_trip_not_the_demos(run):
    from readjax.lab import ae_eval
    from readjax.data import store

    data, run_dir = run
    motions = store.load_dataset(store.split_dir(data, "reach_target", "test")).motion[:3]
    handed = []
    res = ae_eval.evaluate_autoencoder(run_dir, motions, execute=lambda m: handed.append(m) or np.array([1, 0, 1]))
    recon, _ = ae_eval.round_trip(run_dir, motions)
    np.testing.assert_array_equal(handed[0], recon)
    assert not np.allclose(recon, motions, atol=1e-4)  # the tiny autoencoder is not the identity
    assert res["task_success"] == {"rate": 2 / 3, "successes": 2, "success": [1, 0, 1]}
