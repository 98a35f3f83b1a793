"""Evaluation result names say only what applies to the method (no 'spe' for a method that does
not retrieve, no N for a one-pass one), so the report's rows are not misleading."""

from experiments import evaluate as evaluate_cli


def _name(argv, **kw):
    return evaluate_cli.default_name(evaluate_cli.parser().parse_args(["--run", "r"] + argv), **kw)


def test_read_like_methods_name_retrieval_and_N():
    assert _name([], default_n=100) == "spe_N100"
    assert _name(["--N", "10"], default_n=100) == "spe_N10"
    assert _name(["--no-refine"], default_n=100) == "spe_N0"
    assert _name(["--retrieval", "cheat", "--rank", "500", "--N", "1"]) == "cheat500_N1"
    assert _name(["--noise", "0.1", "--brightness", "0.5", "--N", "10"]) == "spe_N10_noise0.1_bright0.5"


def test_cold_refinement_is_named_where_it_applies():
    assert _name(["--N", "10"], default_n=100, refine_update="cold") == "spe_N10_cold"
    assert _name([], default_n=100, refine_update="cold") == "spe_N100_cold"
    assert _name(["--no-refine"], default_n=100, refine_update="cold") == "spe_N0"  # nothing refined
    assert _name(["--N", "10"], default_n=100, refine_update="renoise") == "spe_N10"  # the paper's loop
    assert _name(["--N", "10", "--candidates", "3"], default_n=100, refine_update="cold") == "spe_N10_cold_top3"
    assert _name(["--N", "10", "--candidates", "1"], default_n=100, refine_update="cold") == "spe_N10_cold"
    assert _name(["--N", "10", "--rounds", "2"], default_n=100, refine_update="cold_anchor") == "spe_N10_cold_anchor_rounds2"
    assert _name(["--N", "10", "--rounds", "1"], default_n=100, refine_update="cold_anchor") == "spe_N10_cold_anchor"
    # the run's default rounds (the cpu preset: 2) name the result unless --rounds overrides them
    assert _name(["--N", "10"], default_n=100, refine_update="cold_anchor", default_rounds=2) == "spe_N10_cold_anchor_rounds2"
    assert _name(["--N", "10", "--rounds", "1"], default_n=100, refine_update="cold_anchor", default_rounds=2) == "spe_N10_cold_anchor"
    assert _name(["--no-refine"], default_n=100, refine_update="cold_anchor", default_rounds=2) == "spe_N0"


def test_vpsde_has_no_retrieval_part():
    assert _name(["--N", "20"], uses_retrieval=False) == "N20"
    assert _name([], uses_retrieval=False, default_n=100) == "N100"


def test_one_pass_method_is_direct():
    assert _name([], uses_retrieval=False, iterative=False) == "direct"
    assert _name(["--N", "5"], uses_retrieval=False, iterative=False) == "direct"
    assert _name(["--brightness", "0.5"], uses_retrieval=False, iterative=False) == "direct_bright0.5"
