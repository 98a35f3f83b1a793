"""Settings chosen on a validation split, never on the test episodes: the choosing rule, the choice grid,
and a validation evaluation kept out of every test table and every "done" check."""

from __future__ import annotations

import json

import pytest

from experiments import evaluate as evaluate_cli
from readjax import config
from readjax.lab import choice, report, verification
from readjax.lab.pipeline_config import ChoiceGrid, EvalRequest
from readjax.lab.refine_setting import RefineSetting
from readjax.lab.pipeline_results import finished_evaluation

S = RefineSetting


def test_the_best_val_setting_is_chosen_and_ties_go_to_the_papers_recipe():
    assert choice.choose([(S(1, "renoise"), 0.70), (S(2, "cold_anchor"), 0.80)]) == S(2, "cold_anchor")
    assert choice.choose([(S(2, "cold_anchor"), 0.80), (S(1, "renoise"), 0.81)]) == S(1, "renoise")
    tied = [(S(2, "cold_anchor"), 0.8), (S(2, "renoise"), 0.8), (S(1, "cold_anchor"), 0.8), (S(1, "renoise"), 0.5)]
    # one field off the paper's recipe beats two; with one off each, fewer extra rounds win
    assert choice.choose(tied) == choice.choose(tied[::-1]) == S(1, "cold_anchor")
    assert choice.choose(tied + [(S(1, "renoise"), 0.8)]) == S(1, "renoise")  # the paper's own recipe
    assert choice.choose([(S(1, "renoise", 3), 0.6), (S(1, "cold"), 0.6)]) == S(1, "cold")
    assert choice.choose([(S(3, "renoise"), 0.6), (S(2, "renoise"), 0.6)]) == S(2, "renoise")
    with pytest.raises(ValueError, match="nothing to choose"):
        choice.choose([])


def test_the_choice_grid_and_its_settings():
    cpu, paper = config.presets("cpu")["sde"], config.presets("paper")["sde"]
    assert (cpu.rounds, cpu.update) == (2, "cold_anchor")
    assert ChoiceGrid().settings(cpu) == (S(1, "renoise"), S(1, "cold_anchor"), S(2, "renoise"), S(2, "cold_anchor"))
    assert ChoiceGrid().settings(paper) == (S(1, "renoise"),)  # the run's own values are the paper's: one left
    assert ChoiceGrid(rounds=(1,), refine=("cold",), candidates=(1, 3)).settings(cpu) == (S(1, "cold"), S(1, "cold", 3))
    s = S(2, "cold_anchor", 3)
    assert S.parse(s.text()) == s and S.parse("rounds=1,refine=renoise") == S(1, "renoise")
    assert s.argv() == ["--rounds", "2", "--refine", "cold_anchor", "--candidates", "3"]
    for bad in ("rounds=1", "rounds=x,refine=renoise", "rounds=1,refine=hot", "rounds=1,refine=renoise,k=2",
                "rounds=0,refine=renoise"):
        with pytest.raises(ValueError):
            S.parse(bad)
    for grid in (ChoiceGrid(rounds=()), ChoiceGrid(rounds=(0,)), ChoiceGrid(refine=("hot",)),
                 ChoiceGrid(candidates=(0,))):
        with pytest.raises(ValueError):
            grid.validate()


def _record(split: str, **kw) -> dict:
    return {"task": "reach_target", "method": "read", "name": "spe_N100", "split": split, "episodes": 2,
            "test_fingerprint": f"fp-{split}", "success_rate": 1.0, "success": [1, 1], "seeds": [1, 2],
            "eval_config": {"N": 100, "retrieval": "spe", "rank": 1, "candidates": 1, "rounds": 1,
                            "image_noise": 0.0, "brightness": 1.0, "refine_update": "renoise"},
            "configs": {"sde": {"update": "renoise", "rounds": 1}}, **kw}


def test_a_val_evaluation_never_lands_in_eval_nor_counts_as_a_test_one(tmp_path):
    run = tmp_path / "runs" / "reach_target" / "read"
    assert evaluate_cli.output_folder(run, "val", None) == run / "val"
    assert evaluate_cli.output_folder(run, "test", None) == run / "eval"
    assert evaluate_cli.output_folder(run, "val", str(tmp_path / "shown")) == tmp_path / "shown"
    with pytest.raises(ValueError, match="the tables read"):
        evaluate_cli.output_folder(run, "val", str(run / "eval"))
    args = evaluate_cli.parser().parse_args(["--run", str(run)])
    assert args.split == "test" and evaluate_cli.parser().parse_args(["--run", "r", "--split", "val"]).split == "val"
    # even a val record copied into an eval/ folder by hand is neither a table's number nor a finished step
    results = tmp_path / "results"
    for split in ("test", "val"):
        verification.write(results, {"task": "reach_target", "split": split, "dataset_fingerprint": f"fp-{split}",
                                     "episodes": 2, "success_rate": 1.0})
    folder = results / "reach_target" / "read" / "eval"
    folder.mkdir(parents=True)
    (folder / "spe_N100.json").write_text(json.dumps(_record("val")))
    assert report.collect(results) == []
    assert finished_evaluation(results, "reach_target", "read", "read", EvalRequest(100), 2) is None
    (folder / "spe_N100.json").write_text(json.dumps(_record("test")))
    assert [r["split"] for r in report.collect(results)] == ["test"]
    assert finished_evaluation(results, "reach_target", "read", "read", EvalRequest(100), 2) is not None
    # a val record is verified against the val split's replay, a test record against the test split's
    assert verification.evaluation_verified(results, _record("val"))
    assert not verification.evaluation_verified(results, _record("val", test_fingerprint="fp-test"))


def test_a_test_evaluation_takes_a_choice_only_as_recorded(tmp_path):
    """A test record counts for a run that chooses only if it ran with the chosen setting and says so;
    without a choice file nothing counts yet."""
    path = tmp_path / "choice.json"
    request = EvalRequest(100, choice=str(path))
    assert request.argv() == ["--N", "100", "--choice", str(path)]
    chosen = _record("test", chosen_on="val")
    assert not request.matches(chosen, "read")  # no choice file yet
    path.write_text(json.dumps({"chosen": {"rounds": 1, "refine": "renoise", "candidates": 1}, "candidates": []}))
    assert request.matches(chosen, "read")
    assert not request.matches(_record("test"), "read")  # the same setting, not chosen on val
    path.write_text(json.dumps({"chosen": {"rounds": 2, "refine": "renoise", "candidates": 1}, "candidates": []}))
    assert not request.matches(chosen, "read")  # another setting than the one chosen
