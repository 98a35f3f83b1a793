"""The benchmarks: the planner cost model for skipping cells, the regression check, the training profile."""

from pathlib import Path

import pytest

from readjax.lab.bench_planner import _estimate_call_s


def test_estimate_separates_fixed_cost_from_per_step_cost():
    # 4 s fixed (encoding 64 images) + 0.6 s per refinement step
    timed = [(1, 4.6), (10, 10.0)]
    assert _estimate_call_s(timed, 100) == pytest.approx(64.0)
    assert _estimate_call_s([], 100) == 0.0  # nothing timed yet: run the cell
    assert _estimate_call_s([(1, 4.6)], 100) == pytest.approx(4.6)  # a lower bound, never an overestimate
    assert _estimate_call_s([(1, 5.0), (10, 4.0)], 100) == pytest.approx(4.0)  # noise never gives negative steps


def test_regression_check_flags_only_what_got_twice_as_slow():
    from readjax.lab.bench_compare import slower_than

    old = {"cells": [{"preset": "cpu", "batch": 1, "N": 1, "ms_per_call": 100.0, "ms_per_plan": 100.0},
                     {"preset": "cpu", "batch": 1, "N": 100, "ms_per_call": 1000.0},
                     {"preset": "paper", "batch": 1, "N": 100, "skipped": True}],
           "parts": [{"preset": "cpu", "batch": 1, "encode_ms": 10.0, "retrieve_ms": 5.0}]}
    new = {"cells": [{"preset": "cpu", "batch": 1, "N": 1, "ms_per_call": 199.0, "ms_per_plan": 199.0},
                     {"preset": "cpu", "batch": 1, "N": 100, "ms_per_call": 2000.0},
                     {"preset": "paper", "batch": 1, "N": 100, "ms_per_call": 9e9},  # no old timing
                     {"preset": "cpu", "batch": 64, "N": 1, "ms_per_call": 9e9}],  # a new cell
           "parts": [{"preset": "cpu", "batch": 1, "encode_ms": 25.0, "retrieve_ms": 1.0}]}
    flagged = slower_than(old, new)
    assert len(flagged) == 2
    assert flagged[0].startswith("preset=cpu batch=1 N=100 ms_per_call: 1000.0 -> 2000.0")
    assert flagged[1].startswith("preset=cpu batch=1 encode_ms: 10.0 -> 25.0 (2.5x)")
    assert slower_than(old, new, factor=3.0) == []
    # the other way round only the part that was 5x faster before is flagged: faster is never flagged
    assert slower_than(new, old) == ["preset=cpu batch=1 retrieve_ms: 1.0 -> 5.0 (5.0x)"]


def test_original_ratios_pair_cells_by_batch_n_and_threads():
    from readjax.lab.bench_compare import original_ratios

    cells = [{"preset": "paper", "batch": 1, "N": 1, "ms_per_call": 500.0},
             {"preset": "paper", "batch": 1, "N": 100, "ms_per_call": 2000.0},
             {"preset": "cpu", "batch": 1, "N": 1, "ms_per_call": 50.0},  # not the original's size
             {"preset": "paper", "batch": 64, "N": 100, "skipped": True}]
    plans = [{"variant": "as_is", "threads": 2, "batch": 1, "N": 1, "measured": True, "median_ms": 650.0},
             {"variant": "cached", "threads": 2, "batch": 1, "N": 100, "measured": True, "median_ms": 2400.0},
             {"variant": "as_is", "threads": 1, "batch": 1, "N": 100, "measured": True, "median_ms": 1.0},
             {"variant": "as_is", "threads": 2, "batch": 1, "N": 100, "measured": False}]
    rows = original_ratios(cells, plans, threads=2)
    assert [(r["N"], r["variant"], r["speedup"]) for r in rows] == [(1, "as_is", 1.3), (100, "cached", 1.2)]


def test_the_originals_harness_is_asked_for_this_benchmarks_cells_and_variants(tmp_path):
    """--vs-original times the original at the benchmark's own batches, N, database and cap, and only
    at the variants asked for (as released, at batch 64 and N = 100, runs about an hour on 2 cores)."""
    from experiments.bench import parser
    from readjax.lab.bench_compare import original_command

    argv = ["planner", "--presets", "paper", "--batch-sizes", "64", "--N", "100", "1", "--database", "32",
            "--max-seconds", "900", "--vs-original", str(tmp_path)]
    cmd = original_command(parser().parse_args(argv + ["--original-variants", "cached"]), tmp_path / "o.json")
    text = " ".join(cmd)
    assert "--batches 64 --steps 1 100 --variants cached --repeats" in text
    assert "--db-size 32 --max-cell-s 900.0" in text and cmd[2] == str(tmp_path)
    both = original_command(parser().parse_args(argv), tmp_path / "o.json")
    assert "--variants as_is cached" in " ".join(both)
    harness = Path(parser().parse_args(argv).original_harness)  # the shared harness, by default
    if harness.exists():  # the flag names the harness's own option and choices
        assert 'add_argument("--variants"' in harness.read_text() and '"as_is", "cached"' in harness.read_text()


def test_bad_compare_or_original_paths_fail_before_any_timing(tmp_path):
    """A missing or broken --compare JSON and a missing --vs-original copy are one-line errors
    (exit 2) raised before the benchmark runs, and nothing is written."""
    from experiments import _cli
    from experiments.bench import main

    out = tmp_path / "planner.json"
    base = ["planner", "--presets", "cpu", "--out", str(out)]
    assert _cli.run(main, base + ["--compare", str(tmp_path / "missing.json")]) == 2
    (tmp_path / "broken.json").write_text("{not json")
    assert _cli.run(main, base + ["--compare", str(tmp_path / "broken.json")]) == 2
    (tmp_path / "other.json").write_text('{"tasks": {}}')  # a sim benchmark, not a planner one
    assert _cli.run(main, base + ["--compare", str(tmp_path / "other.json")]) == 2
    assert _cli.run(main, base + ["--vs-original", str(tmp_path / "no_READ")]) == 2
    assert not out.exists()


def test_train_profile_attributes_a_steps_ops_to_the_models_parts():
    """The training profile (experiments.bench train --profile) traces real steps and finds the
    denoiser's parts, forward and backward, in the compiled program's metadata."""
    import jax.numpy as jnp

    from experiments import bench_train
    from readjax.models import Denoiser
    from readjax.training import StageSpec
    from tests.models.helpers import TINY_DENOISER, jit_init, key, synthetic_batch

    den = Denoiser(TINY_DENOISER)
    b = synthetic_batch(2)
    image = jnp.zeros((2, 32, 32, 4))
    params = jit_init(den, key(0), image, b["motion"], jnp.zeros((2,)))

    def loss(p, batch, rng):
        pred = den.apply(p, batch["image"], batch["motion"], jnp.full((2,), 0.5))
        return jnp.mean((pred - batch["motion"]) ** 2), {}

    stepper = bench_train._Stepper(loss, params, StageSpec(steps=1, batch_size=2), {"image": image,
                                                                                     "motion": b["motion"]}, 0)
    rows = {r["part"]: r for r in bench_train.profile_step(stepper, calls=2)}
    assert {"transformer layers", "UNet image encoder", "feature sampling"} <= set(rows)
    assert rows["transformer layers"]["fwd_ms"] > 0 and rows["transformer layers"]["bwd_ms"] > 0
    assert bench_train._part_of("jvp(Denoiser)/Denoiser.denoise/Denoiser.track_tokens/unet.head_at/mul") \
        == "feature sampling"
    assert stepper.cost()["gflop"] > 0


def test_planner_benchmark_runs_end_to_end_and_compares_with_itself(tmp_path):
    """``experiments.bench planner`` at the cpu preset, one image, a 2-demo database: every cell and
    part is timed and written, and ``--compare`` against its own JSON flags nothing (exit 0)."""
    import json

    from experiments import _cli
    from experiments.bench import main

    out = tmp_path / "planner.json"
    argv = ["planner", "--presets", "cpu", "--batch-sizes", "1", "--N", "1", "--database", "2", "--repeats", "1"]
    assert _cli.run(main, argv + ["--out", str(out)]) == 0
    rec = json.loads(out.read_text())
    assert [(c["preset"], c["batch"], c["N"]) for c in rec["cells"]] == [("cpu", 1, 1)]
    assert rec["cells"][0]["ms_per_plan"] > 0 and rec["cells"][0]["setup_s"] >= 0
    assert {"encode_ms", "retrieve_ms", "refine_N1_ms", "decode_ik_ms"} <= set(rec["parts"][0])
    assert _cli.run(main, argv + ["--out", str(tmp_path / "again.json"), "--compare", str(out),
                                  "--slower", "1000"]) == 0


def test_the_malloc_benchmark_runs_each_setting_in_turn_and_compares_parameters(monkeypatch):
    """Each setting runs ``rounds`` times, alternating; the row is each setting's median and the ratio;
    parameters count as the same only if every process's hash agrees."""
    import argparse

    from experiments import bench_malloc

    order, ms = [], {"system": [120.0, 140.0], "tuned": [60.0, 80.0]}

    def run_setting(setting, steps, batch):
        order.append(setting)
        k = sum(s == setting for s in order) - 1
        sha = "b" if setting == "tuned" and k == 1 else "a"
        return {st: {"ms": ms[setting][k], "faults": 10.0, "sys_s": 0.01, "params_sha256": sha if st == "read" else "a"}
                for st in ("vae", "read")}

    monkeypatch.setattr(bench_malloc, "run_setting", run_setting)
    out = bench_malloc.bench_malloc(argparse.Namespace(rounds=2, steps=3, batch=4))
    assert order == ["system", "tuned", "system", "tuned"]
    vae, read = out["stages"]
    assert vae["system"]["ms"] == 130.0 and vae["tuned"]["ms"] == 70.0 and vae["speedup"] == pytest.approx(1.86)
    assert vae["same_parameters"] and not read["same_parameters"]
