"""Reading an evaluation result: which evaluation a pipeline step asks for, and pairing by seed."""

from __future__ import annotations

from readjax.config import DEFAULT_N
from readjax.config import configs_to_dict, override, presets
from readjax.lab.result_record import by_seed, is_default_eval, is_spe_eval, protocol, recipe_differences, training_stops


def _read(N, update="cold_anchor", rounds=2, run_sde=("cold_anchor", 2), **cfg):
    return {"method": "read", "name": "x",
            "eval_config": {"episodes": 100, "N": N, "retrieval": "spe", "rank": 1, "candidates": 1,
                            "image_noise": 0.0, "brightness": 1.0, "rounds": rounds, "refine_update": update, **cfg},
            "configs": {"sde": {"update": run_sde[0], "rounds": run_sde[1]}}}


def test_the_default_evaluation_of_a_read_run():
    assert is_default_eval(_read(100), "read", 100)
    assert is_default_eval(_read(0, rounds=2), "read", 0)  # at N = 0 no refinement ran, whatever the rounds
    assert not is_default_eval(_read(100), "read", 0)
    assert not is_default_eval(_read(100), "deterministic", 100)
    # another refinement than the run's own is not what `evaluate --N 100` writes
    assert not is_default_eval(_read(100, rounds=1), "read", 100)
    assert not is_default_eval(_read(100, update="renoise"), "read", 100)
    assert is_default_eval(_read(100, update="renoise", rounds=1, run_sde=("renoise", 1)), "read", 100)
    # other protocols and settings
    assert not is_default_eval(_read(100, retrieval="cheat"), "read", 100)
    assert not is_default_eval(_read(100, candidates=5), "read", 100)
    assert not is_default_eval(_read(100, brightness=1.2), "read", 100)
    # from the oracle's start (--retrieval cheat --rank 1)
    oracle = _read(100, retrieval="cheat")
    assert is_default_eval(oracle, "read", 100, oracle_rank=1) and not is_default_eval(oracle, "read", 100)
    assert not is_default_eval(_read(100, retrieval="cheat", rank=3), "read", 100, oracle_rank=1)
    assert not is_default_eval(_read(100), "read", 100, oracle_rank=1)
    # the main table asks for a named refinement instead of the run's own
    assert is_spe_eval(_read(100, rounds=1, update="cold"), 100, ("cold", 1))
    assert not is_spe_eval(_read(100), 100, ("cold", 1))


def test_the_default_evaluation_of_other_methods():
    direct = {"method": "deterministic", "name": "direct",
              "eval_config": {"episodes": 100, "N": None, "retrieval": "spe", "rank": 1, "candidates": 1,
                              "rounds": 1, "refine_update": None}, "configs": {"train": {}}}
    assert is_default_eval(direct, "deterministic", None)
    # READ-O has READ's SDE but not its update: its default evaluation runs its run's sde.rounds
    read_o = {"method": "read_o", "name": "x",
              "eval_config": {"episodes": 100, "N": 100, "retrieval": "spe", "rank": 1, "candidates": 1,
                              "rounds": 2, "refine_update": None},
              "configs": {"sde": {"update": "cold_anchor", "rounds": 2}}}
    assert is_default_eval(read_o, "read_o", 100)
    assert not is_default_eval({**read_o, "eval_config": {**read_o["eval_config"], "rounds": 1}}, "read_o", 100)
    assert not is_default_eval({**direct, "eval_config": {**direct["eval_config"], "rounds": 2}}, "deterministic", None)
    assert not is_default_eval(direct, "deterministic", 100)
    # an iterative method run with no --N records the planner's default N
    vpsde = {"method": "vpsde", "eval_config": {**direct["eval_config"], "N": DEFAULT_N},
             "configs": {"sde": {"update": "renoise", "rounds": 1}}}
    assert is_default_eval(vpsde, "vpsde", None)
    assert not is_default_eval({**vpsde, "eval_config": {**vpsde["eval_config"], "N": 7}}, "vpsde", None)
    # an evaluation that predates a field ran with the field's default then
    old = {"method": "deterministic", "eval_config": {"episodes": 100, "N": None, "retrieval": "spe"}}
    assert protocol(old) == "main" and is_default_eval(old, "deterministic", None)


def test_outcomes_pair_by_seed():
    assert by_seed({"seeds": [5, 3], "success": [1, 0]}) == {5: 1, 3: 0}
    assert by_seed({}) == {}


def test_recipe_differences_name_the_trained_fields_only():
    """A recorded recipe equals the wanted one up to what is not the recipe: inference-only fields
    (refinement's update and rounds), data-derived ones (motion statistics) and fields the run
    predates, counted at their defaults. A trained field that differs is named."""
    configs = override(presets("cpu"), ["sde.self_feed=0"])  # the cpu preset before it self-fed
    wanted = configs_to_dict(configs, ["denoiser", "sde"])
    recorded = {"denoiser": {**wanted["denoiser"], "motion_mean": [1.0], "motion_std": [2.0]},
                "sde": {k: v for k, v in wanted["sde"].items() if k != "self_feed"}}  # predates self_feed
    recorded["sde"]["rounds"] = 7
    assert recipe_differences(recorded, wanted) == []
    # the current cpu preset self-feeds: a run that predates the field trained otherwise
    assert recipe_differences(recorded, configs_to_dict(presets("cpu"), ["denoiser", "sde"])) == ["sde.self_feed"]
    other = configs_to_dict(override(configs, ["sde.lam=0.1", "denoiser.layers=3"]), ["denoiser", "sde"])
    assert recipe_differences(other, wanted) == ["denoiser.layers", "sde.lam"]


def test_training_stops_reads_each_stage_with_why_it_stopped():
    """One (stage, last step, reason) per trained stage; a stage without a stop record is unfinished;
    an evaluation older than the training records has none."""
    r = {"training": {"vae": {"steps": 3000, "stop": {"reason": "step cap"}},
                      "read": {"steps": 9500, "stop": {"reason": "converged"}}, "extra": {}}}
    assert training_stops(r) == [("vae", 3000, "step cap"), ("read", 9500, "converged"),
                                               ("extra", "?", "unfinished")]
    assert training_stops({}) == [] == training_stops({"training": None})
