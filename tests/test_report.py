"""experiments.report on hand-written evaluation files: protocol grouping, labels, exclusion."""

import json

from experiments import _cli
from experiments import report as report_cli
from readjax import tasks
from readjax.lab import cost_table, report
from readjax.lab.paired import paired_outcomes
from readjax.lab.report import collect, write_report


def _write(root, task, run, name, rate, suite=tasks.SUITE_VERSION, **cfg):
    d = root / task / run / "eval"
    d.mkdir(parents=True, exist_ok=True)
    eval_config = {"N": 10, "retrieval": "spe", "rank": 1, "image_noise": 0.0, "brightness": 1.0, **cfg}
    record = {"task": task, "name": name, "success_rate": rate, "seeds": [1, 2], "eval_config": eval_config,
              "versions": {"jax": "x"}}
    if suite is not None:  # None: a result written before suite versions (suite 1)
        record["suite"] = suite
    (d / f"{name}.json").write_text(json.dumps(record))


def test_report_groups_protocols_and_excludes(tmp_path, capsys):
    runs = tmp_path / "runs"
    _write(runs, "reach_target", "read", "spe_N10", 0.5)
    _write(runs, "reach_target", "read", "spe_N0", 0.25, N=0)
    _write(runs, "push_button", "read", "spe_N10", 0.75)
    _write(runs, "reach_target", "deterministic", "direct", 0.125, N=None)
    _write(runs, "reach_target", "read", "cheat500_N100", 0.375, retrieval="cheat", rank=500, N=100)
    _write(runs, "reach_target", "read", "spe_N10_noise0.1", 0.0625, image_noise=0.1)
    _write(runs, "reach_target", "read_try", "spe_N10", 0.99)
    _write(runs / "older", "reach_target", "read", "spe_N10", 0.875)  # same run name, another place
    _write(runs / "older", "reach_target", "read_x", "spe_N10", 0.97)
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--exclude", "*_try", "older/read_x"]) == 0
    text = out.read_text()
    main, oracle = text.split("## Oracle")[0], text.split("## Oracle")[1].split("## Perturbed")[0]
    perturbed = text.split("## Perturbed")[1].split("## Provenance")[0]
    assert "| read: spe_N10 | 50.0 | 75.0 | 62.5 |" in main
    assert "| read: retrieval only (N=0) | 25.0 | – | 25.0 |" in main
    assert "| deterministic | 12.5 | – | 12.5 |" in main
    assert "cheat500" not in main and "| read: cheat500_N100 | 37.5 | 37.5 |" in oracle
    assert "| read: spe_N10_noise0.1 | 6.2 | 6.2 |" in perturbed
    assert "| older/read: spe_N10 | 87.5 | – | 87.5 |" in main
    assert "99.0" not in text and "read_try" not in text and "97.0" not in text
    assert out.with_suffix(".png").exists() and "![success by task](results.png)" in main


def test_include_keeps_only_the_named_runs_and_sweeps(tmp_path):
    """--include: a focused report of one grid's runs (and sweeps) out of a results folder holding
    many; --exclude still applies within it."""
    from readjax.lab import sweep_grid, sweep_table

    runs = tmp_path / "runs"
    _write(runs, "reach_target", "read_rep", "spe_N10", 0.5)
    _write(runs, "reach_target", "det_conv", "direct", 0.25, N=None)
    _write(runs, "reach_target", "vpsde_conv", "N100", 0.125)
    _write(runs, "reach_target", "read_old", "spe_N10", 0.99)
    cell = {**sweep_grid.DEFAULTS, "success": 0.5, "seeds": [1, 2], "outcomes": [1, 0]}
    for name in ("table7", "old_sweep"):
        sweep_table.write_sweep({"task": "reach_target", "code": "RT", "model": "read", "grid": {"N": [100]}, "episodes": 2,
                           "cells": [cell]}, runs / "reach_target" / name)
    out = tmp_path / "focused.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--include", "read_rep", "*_conv",
                                      "table7", "--exclude", "vpsde*"]) == 0
    text = out.read_text()
    assert "| read_rep: spe_N10 | 50.0 |" in text and "| det_conv | 25.0 |" in text
    assert "read_old" not in text and "vpsde_conv" not in text and "99.0" not in text
    assert text.count("## Sweep: read on reach_target") == 1
    assert len(report.sweeps(runs)) == 2 and len(report.sweeps(runs, include=("table7",))) == 1
    # the cost table keeps the tasks the focused report shows
    for task in ("reach_target", "push_button"):
        (runs / task).mkdir(exist_ok=True)
        (runs / task / "pipeline_timing.json").write_text(json.dumps({"task": task, "steps": {
            "train x": {"kind": "train", "seconds": 60.0}}}))
    assert [ln.split(" |")[0] for ln in cost_table.cost_lines(runs) if ln.startswith("| ") and "task" not in ln] == \
        ["| RT", "| PB", "| all 2"]
    assert [ln.split(" |")[0] for ln in cost_table.cost_lines(runs, {"reach_target"})
            if ln.startswith("| ") and "task" not in ln] == ["| RT", "| all 1"]


def test_report_without_results_is_a_clear_error(tmp_path, capsys):
    assert _cli.run(report_cli.main, ["--runs", str(tmp_path), "--out", str(tmp_path / "r.md")]) == 2
    assert "no evaluation results" in capsys.readouterr().err


def test_provenance_separates_machines_and_differing_versions(tmp_path):
    runs = tmp_path / "runs"
    _write(runs, "reach_target", "read", "spe_N10", 0.5)
    _write(runs, "push_button", "vpsde", "N100", 0.25)
    f = runs / "push_button" / "vpsde" / "eval" / "N100.json"
    r = json.loads(f.read_text())
    r["versions"] = {"jax": "y"}
    r["machine"] = {"backend": "gpu", "devices": "1 x NVIDIA H200"}
    f.write_text(json.dumps(r))
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out)]) == 0
    prov = out.read_text().split("## Provenance")[1]
    assert "| machine | jax | results |" in prov
    assert "| gpu: 1 x NVIDIA H200 | y | vpsde: N100 (PB) |" in prov
    assert "| not recorded | x | read: spe_N10 (RT) |" in prov


def test_mcnemar_exact_values():
    from readjax.lab.paired import mcnemar_p

    assert mcnemar_p([True] * 6 + [False] * 4, [False] * 6 + [False] * 4) == 2 / 64  # 6 discordant, one way
    assert mcnemar_p([True, False], [True, False]) == 1.0  # no discordant episodes
    assert mcnemar_p([True, False], [False, True]) == 1.0  # one each way
    import pytest

    with pytest.raises(ValueError, match="same episodes"):
        mcnemar_p([True], [True, False])


def test_pooling_sums_the_discordant_episodes_of_the_pairs_on_the_same_episodes():
    from readjax.lab.paired import pool, sign_test_p

    def rec(succ, seeds, suite=2):
        return {"success": succ, "seeds": seeds, "suite": suite}

    a, b = rec([1, 1, 0, 0], [0, 1, 2, 3]), rec([0, 1, 1, 0], [0, 1, 2, 3])  # +1 / -1
    c, d = rec([1, 1, 1], [5, 6, 7]), rec([0, 0, 1], [5, 6, 7])  # +2 / -0
    other_seeds, old_suite = rec([1, 1, 1], [5, 6, 8]), rec([0, 0, 1], [5, 6, 7], suite=1)
    wins, losses, left_out = pool([(a, b), (c, d), (c, other_seeds), (c, old_suite)])
    assert (wins, losses, left_out) == (3, 1, [2, 3])
    assert sign_test_p(wins, losses) == 0.625  # 2 * P(X >= 3), X ~ Bin(4, 1/2)
    assert pool([]) == (0, 0, [])


def test_compare_pairs_rows_on_common_episodes(tmp_path, capsys):
    runs = tmp_path / "runs"
    seeds = list(range(10))
    for run, name, succ in [("read", "spe_N100", [True] * 8 + [False] * 2),
                            ("deterministic", "direct", [False] * 2 + [True] * 6 + [False] * 2)]:
        _write(runs, "reach_target", run, name, sum(succ) / 10)
        f = runs / "reach_target" / run / "eval" / f"{name}.json"
        r = json.loads(f.read_text())
        r.update(seeds=seeds, success=succ)
        f.write_text(json.dumps(r))
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--compare", "read: spe_N100"]) == 0
    section = out.read_text().split("## Paired comparison with `read: spe_N100`")[1].split("## Provenance")[0]
    assert "| deterministic | -20 (p=0.5) |" in section  # 2 discordant episodes, both for READ
    argv = ["--runs", str(runs), "--out", str(out), "--compare", "read: spe_N100", "deterministic"]
    assert _cli.run(report_cli.main, argv) == 0  # one paired table per reference row
    other = out.read_text().split("## Paired comparison with `deterministic`")[1].split("## Provenance")[0]
    assert "| read: spe_N100 | +20 (p=0.5) |" in other
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--compare", "nope"]) == 2
    assert "no row 'nope'" in capsys.readouterr().err


def test_across_trainings_groups_replicates_of_one_recipe(tmp_path):
    """Runs whose configs differ only in train.seed (fields a run predates count at their default)
    form one group with each training's rate, the mean and the range; another recipe, or one
    training alone, forms none."""
    runs = tmp_path / "runs"

    def write(run, rate, seed, **train):
        _write(runs, "reach_target", run, "spe_N10", rate)
        f = runs / "reach_target" / run / "eval" / "spe_N10.json"
        r = json.loads(f.read_text())
        r["method"] = "read"
        r["configs"] = {"train": {"steps": 3000, "seed": seed, **train}, "vae": {"width": 32}}
        f.write_text(json.dumps(r))

    write("read_a", 0.79, 0)
    write("read_b", 0.51, 1, schedule="staircase")  # recorded by a newer readjax: the default, explicit
    write("read_c", 0.60, 2)
    write("read_cos", 0.90, 0, schedule="cosine")  # another recipe, one training: no group
    write("read_other_data", 0.70, 3)  # the recipe on another training set: no group either
    f = runs / "reach_target" / "read_other_data" / "eval" / "spe_N10.json"
    f.write_text(json.dumps(dict(json.loads(f.read_text()), train_fingerprint="another")))
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out)]) == 0
    section = out.read_text().split("## Across trainings")[1].split("## Provenance")[0]
    assert "| RT | read_a: spe_N10 (0)<br>read_b: spe_N10 (1)<br>read_c: spe_N10 (2) | 79 / 51 / 60 | 63.3 | 51-79 |" in section
    assert "read_cos" not in section and "read_other_data" not in section


def test_where_refinement_started_table(tmp_path):
    """Rows that record where refinement started get one table per task: succeeded / episodes per
    start group and distance, target groups first and nearest first; rows without it are absent."""
    runs = tmp_path / "runs"
    _write(runs, "reach_target", "read_a", "spe_N10", 0.5)
    _write(runs, "reach_target", "read_b", "spe_N10", 0.25)
    _write(runs, "reach_target", "det", "direct", 0.7)
    by = {"read_a": {"distractor": {"0-3 cm": {"episodes": 1, "succeeded": 0}},
                     "target": {"6-10 cm": {"episodes": 1, "succeeded": 1}, "0-3 cm": {"episodes": 2, "succeeded": 1}}},
          "read_b": {"target": {"0-3 cm": {"episodes": 4, "succeeded": 1}}}}
    for run, table in by.items():
        f = runs / "reach_target" / run / "eval" / "spe_N10.json"
        r = json.loads(f.read_text())
        r["starts"] = {"success_by_start": table}
        f.write_text(json.dumps(r))
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out)]) == 0
    section = out.read_text().split("## Where refinement started")[1].split("## Provenance")[0]
    assert "| RT | target 0-3 cm | target 6-10 cm | distractor 0-3 cm |" in section
    assert "| read_a: spe_N10 | 1 / 2 | 1 / 1 | 0 / 1 |" in section
    assert "| read_b: spe_N10 | 1 / 4 | – | – |" in section
    assert "det" not in section


def test_results_of_an_older_suite_are_marked_and_never_paired_with_the_current(tmp_path):
    """Suite 1 (written before versions) and the current suite ran the same seeds on other scenes: their
    rows are labelled apart and a comparison between them pairs no episode."""
    runs = tmp_path / "runs"
    _write(runs, "reach_target", "read", "spe_N10", 0.5, suite=None)
    _write(runs, "reach_target", "read2", "spe_N10", 1.0)
    text = write_report(runs, tmp_path / "r.md", compare=("read2: spe_N10",))
    assert "| read [suite 1]: spe_N10 |" in text and "| read2: spe_N10 |" in text
    old = [r for r in collect(runs) if r["_run_name"] == "read"][0]
    new = [r for r in collect(runs) if r["_run_name"] == "read2"][0]
    old["success"], new["success"] = [1, 0], [1, 1]
    assert paired_outcomes(old, new) is None and paired_outcomes(new, new) is not None
