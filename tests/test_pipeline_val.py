"""The grid's validation path: the val split, its replay, each READ run's choice among the grid's
refinement settings before the test evaluations that take it (planned, then run in order with
stand-ins for the commands), and the options that set it."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from experiments import _cli
from experiments import choose as choose_cli
from readjax.lab import choice, pipeline, pipeline_config, report, verification
from readjax.lab.pipeline_config import ChoiceGrid
from readjax.lab.steps import PipelineError, run_in_order
from tests.pipeline_fakes import _fingerprint_from_summary  # noqa: F401 (an autouse fixture)


def _cfg(tmp_path, **kw):
    base = {"tasks": ("RT",), "methods": ("read", "deterministic"), "data": str(tmp_path / "data"),
            "runs": str(tmp_path / "runs"), "results": str(tmp_path / "results"), "train_episodes": 8,
            "test_episodes": 4, "val_episodes": 4, "media_episodes": 0, "diagnose_below": 0.0}
    return pipeline_config.PipelineConfig(**{**base, **kw}).validate()


def test_validation_and_the_choice_come_before_the_test_evaluations_that_take_it(tmp_path):
    steps = pipeline.plan_steps(_cfg(tmp_path, read_N=(0, 10, 100), media_episodes=8, diagnose_below=80.0))
    labels = [s.label for s in steps]
    val_gen, val_verify = labels.index("generate val 4"), labels.index("verify val (ground truth replay = 100 %)")
    val_evals = [s for s in steps if "--split" in s.argv and s.argv[s.argv.index("--split") + 1] == "val"
                 and s.kind == "evaluate"]
    chooser = next(s for s in steps if s.kind == "choose")
    assert len(val_evals) == 4 and chooser.label == "choose read's refinement on val (4 settings)"
    assert all(a[a.index("--N") + 1] == "100" for a in (s.argv for s in val_evals))  # at the largest N
    refining = [s for s in steps if s.kind in ("evaluate", "media") and "--run" in s.argv
                and Path(s.argv[s.argv.index("--run") + 1]).name == "read" and "val" not in s.argv
                and s.argv[s.argv.index("--N") + 1] != "0"]
    assert [s.label for s in refining] == ["evaluate read --N 10", "evaluate read --N 100",
                                           "render READ N=100 (4 episodes: overlay + video)",
                                           "evaluate read from the oracle's start --N 10 (READ below 80 %)",
                                           "evaluate read from the oracle's start --N 100 (READ below 80 %)"]
    at = {id(s): i for i, s in enumerate(steps)}
    first_test = min(at[id(s)] for s in refining)
    assert val_gen < val_verify < min(at[id(s)] for s in val_evals) < at[id(chooser)] < first_test

    def needs(s, other) -> bool:  # a step by identity: steps compare equal field by field
        return any(n is other for n in s.needs)

    assert all(needs(s, steps[val_verify]) for s in val_evals) and needs(steps[val_verify], steps[val_gen])
    assert all(any(n.label == "train read" for n in s.needs) for s in val_evals)
    assert all(needs(chooser, s) for s in val_evals)
    path = str(tmp_path / "results" / "reach_target" / "read" / "choice.json")
    for s in refining:
        assert needs(s, chooser) and s.argv[s.argv.index("--choice") + 1] == path
    untouched = [s for s in steps if s.kind == "evaluate" and not any(s is x for x in refining + val_evals)]
    assert [s.label for s in untouched] == ["evaluate read --N 0",
                                            "evaluate read from the oracle's start --N 0 (READ below 80 %)",
                                            "evaluate deterministic"]
    assert all("--choice" not in s.argv and not needs(s, chooser) for s in untouched)
    assert not any(s.kind in ("generate", "verify") and "val" in s.label for s in steps[val_verify + 1:])


@pytest.mark.parametrize("kw", [{"val_episodes": 0}, {"methods": ("deterministic",)}, {"read_N": (0,)}])
def test_no_validation_steps_where_nothing_chooses(tmp_path, kw):
    """--val-episodes 0, no READ run, or READ at N = 0 only: no val split, no choice, no --choice."""
    steps = pipeline.plan_steps(_cfg(tmp_path, **kw))
    assert steps and not any(s.kind == "choose" or "val" in s.label.split() or "--choice" in s.argv
                             or "--split" in s.argv and "val" in s.argv for s in steps)
    with pytest.raises(ValueError, match="--val-episodes"):
        _cfg(tmp_path, val_episodes=-1)


def test_a_fixed_refinement_run_chooses_nothing_beside_one_that_chooses(tmp_path):
    """The paper's recipe as its own row: a variant in --fixed-refinement refines with its own config's
    setting, evaluated on the test split with no choice, while READ's other runs still choose."""
    paper = ("read_paper", "read", ("sde.update=renoise", "sde.rounds=1"))
    steps = pipeline.plan_steps(_cfg(tmp_path, methods=("read", "read_paper"), variants=(paper,),
                                     fixed_refinement=("read_paper",)))
    choosers = [s.label for s in steps if s.kind == "choose"]
    assert choosers == ["choose read's refinement on val (4 settings)"]
    runs = {s.label: s.argv for s in steps if s.kind == "evaluate"}
    assert "--choice" in runs["evaluate read --N 100"] and "--choice" not in runs["evaluate read_paper --N 100"]
    assert not any("--split" in a and "read_paper" in " ".join(a) for a in runs.values())
    with pytest.raises(ValueError, match="--fixed-refinement deterministic: not a READ run"):
        _cfg(tmp_path, fixed_refinement=("deterministic",))
    with pytest.raises(ValueError, match="--fixed-refinement read_o: not a READ run"):
        _cfg(tmp_path, fixed_refinement=("read_o",))


def test_a_protocol_run_is_evaluated_from_a_poor_start_as_read_is(tmp_path):
    """--protocol-runs read_paper: the paper's recipe evaluated under --protocols too (from the oracle's
    500th neighbour at N = 0 / 1 / 100), with its own refinement and no choice; READ with its choice."""
    paper = ("read_paper", "read", ("sde.update=renoise", "sde.rounds=1"))
    cfg = _cfg(tmp_path, methods=("read", "read_paper", "deterministic"), variants=(paper,), train_episodes=1000,
               fixed_refinement=("read_paper",), protocols=("poor",), protocol_runs=("read_paper",))
    runs = {s.label: s.argv for s in pipeline.plan_steps(cfg) if s.kind == "evaluate" and "500th" in s.label}
    assert sorted(runs) == sorted(f"evaluate {who} from the oracle's 500th neighbour --N {n}"
                                  for who in ("read", "read_paper") for n in (0, 1, 100))
    assert all(a[a.index("--rank") + 1] == "500" for a in runs.values())
    paper_runs = [a for label, a in runs.items() if "read_paper" in label]
    assert all(Path(a[a.index("--run") + 1]).name == "read_paper" and "--choice" not in a for a in paper_runs)
    assert "--choice" in runs["evaluate read from the oracle's 500th neighbour --N 100"]
    for bad, match in [(dict(protocol_runs=("deterministic",)), "--protocol-runs deterministic: not a READ variant"),
                       (dict(protocol_runs=("read",)), "--protocol-runs read: not a READ variant"),
                       (dict(protocol_runs=("read_paper",), protocols=()), "name the protocols too")]:
        with pytest.raises(ValueError, match=match):
            _cfg(tmp_path, **{**dict(methods=("read", "read_paper", "deterministic"), variants=(paper,),
                                     train_episodes=1000, protocols=("poor",)), **bad})


class FakeRunner:
    """Stands in for the commands (the choice: the real experiments.choose, in this process); READ's
    val success per (rounds, refine) is ``val_rates``, its test success 1."""

    def __init__(self, val_rates, verify_rates=None):
        self.calls, self.val_rates, self.verify_rates = [], val_rates, verify_rates or {}

    def __call__(self, argv):
        mod = argv[2].split(".")[1]
        self.calls.append((mod, argv))

        def arg(k, default=None):
            return argv[argv.index(k) + 1] if k in argv else default

        if mod == "choose":
            return subprocess.CompletedProcess(argv, _cli.run(choose_cli.main, argv[3:]))
        split = arg("--split", "train" if mod == "generate" else "test")

        def summary(task):
            return json.loads((Path(arg("--data")) / task / split / "summary.json").read_text())

        if mod == "generate":
            d = Path(arg("--out")) / arg("--task") / split
            d.mkdir(parents=True, exist_ok=True)
            (d / "summary.json").write_text(json.dumps({"episodes_kept": int(arg("--episodes")),
                                                        "fingerprint": f"a-{split}"}))
        elif mod == "verify":
            verification.write(arg("--results"), {
                "task": arg("--task"), "split": split, "dataset_fingerprint": summary(arg("--task"))["fingerprint"],
                "episodes": int(arg("--episodes")), "success_rate": self.verify_rates.get(split, 1.0)})
        elif mod == "train":
            (Path(arg("--out")) / arg("--task") / arg("--name")).mkdir(parents=True, exist_ok=True)
        elif mod == "evaluate":
            run, k = Path(arg("--run")), int(arg("--episodes"))
            method = "read" if run.name == "read" else "deterministic"
            n = int(arg("--N")) if "--N" in argv else None
            rounds, refine, cands = int(arg("--rounds", 2)), arg("--refine", "cold_anchor"), int(arg("--candidates", 1))
            extra = {}
            if "--choice" in argv:
                c = choice.load(arg("--choice"))
                s = choice.chosen_setting(c)
                rounds, refine, cands, extra = s.rounds, s.refine, s.candidates, choice.record_of(arg("--choice"), c)
            wins = round(self.val_rates[(rounds, refine)] * k) if split == "val" else k
            name = "direct" if n is None else f"spe_N{n}_{refine}_rounds{rounds}"
            folder = run / ("val" if split == "val" else "eval")
            folder.mkdir(parents=True, exist_ok=True)
            (folder / f"{name}.json").write_text(json.dumps({
                "task": run.parent.name, "method": method, "name": name, "split": split, "episodes": k,
                "test_fingerprint": summary(run.parent.name)["fingerprint"], "success_rate": wins / k,
                "success": [1] * wins + [0] * (k - wins), "eval_config": {
                    "episodes": k, "N": n, "retrieval": "spe", "rank": 1, "candidates": cands, "rounds": rounds,
                    "image_noise": 0.0, "brightness": 1.0, "refine_update": refine if method == "read" else None},
                **extra}))
        return subprocess.CompletedProcess(argv, 0)


RATES = {(1, "renoise"): 0.5, (1, "cold_anchor"): 0.75, (2, "renoise"): 0.25, (2, "cold_anchor"): 1.0}


def test_the_grid_chooses_on_val_and_its_test_evaluations_take_the_choice(tmp_path):
    cfg = _cfg(tmp_path, methods=("read",))
    runner = FakeRunner(RATES)
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=runner)
    res = tmp_path / "results" / "reach_target"
    made = json.loads((res / "read" / "choice.json").read_text())
    assert made["chosen"] == {"rounds": 2, "refine": "cold_anchor", "candidates": 1}  # the best on val
    assert made["flags"] == ["--rounds", "2", "--refine", "cold_anchor", "--candidates", "1"]
    assert {(c["setting"]["rounds"], c["setting"]["refine"]): (c["success_rate"], c["episodes"])
            for c in made["candidates"]} == {k: (v, 4) for k, v in RATES.items()}
    assert made["val_fingerprint"] == "a-val" and made["rule"] == choice.RULE and made["commit"]
    assert (res / "verify" / "val_a-val.json").exists()
    # the test evaluation that refines names the choice; the one at N = 0 has nothing to choose
    top = json.loads((res / "read" / "eval" / "spe_N100_cold_anchor_rounds2.json").read_text())
    assert top["chosen_on"] == "val" and top["choice"]["file"] == str(res / "read" / "choice.json")
    assert top["split"] == "test" and top["choice"]["val_fingerprint"] == "a-val"
    assert "chosen_on" not in json.loads(next((res / "read" / "eval").glob("spe_N0_*.json")).read_text())
    # the val evaluations stay out of every eval/ folder, and out of the report
    assert sorted(f.name for f in (res / "read" / "val").glob("*.json")) == sorted(
        f"spe_N100_{u}_rounds{r}.json" for r, u in RATES)
    assert not any(json.loads(f.read_text())["split"] == "val" for f in tmp_path.rglob("eval/*.json"))
    assert {r["split"] for r in report.collect(tmp_path / "results")} == {"test"}
    assert {r["split"] for r in report.collect(tmp_path / "runs")} == {"test"}
    # resumable: nothing runs again, and the choice is not made again
    stamp = (res / "read" / "choice.json").stat().st_mtime_ns
    again = FakeRunner(RATES)
    assert run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=again)["ran"] == 0
    assert again.calls == [] and (res / "read" / "choice.json").stat().st_mtime_ns == stamp
    # a choice gone: made again from the val records on file (no val evaluation runs), and the test
    # evaluation that takes it checked again once it is made: the same setting, nothing to evaluate
    (res / "read" / "choice.json").unlink()
    steps = pipeline.plan_steps(cfg)
    assert [s.label for s in steps if not s.done()] == ["choose read's refinement on val (4 settings)",
                                                        "evaluate read --N 100"]
    run_in_order(steps, log=lambda m: None, runner=again)
    assert [m for m, _ in again.calls] == ["choose"]
    assert json.loads((res / "read" / "choice.json").read_text())["chosen"] == made["chosen"]
    # the paper's recipe as good on val: the tie goes to it, and the test evaluation runs again with it
    paper = res / "read" / "val" / "spe_N100_renoise_rounds1.json"
    paper.write_text(json.dumps({**json.loads(paper.read_text()), "success_rate": 1.0, "success": [1] * 4}))
    (res / "read" / "choice.json").unlink()
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=again)
    assert [m for m, _ in again.calls] == ["choose", "choose", "evaluate"]
    assert json.loads((res / "read" / "choice.json").read_text())["chosen"] == {
        "rounds": 1, "refine": "renoise", "candidates": 1}
    assert json.loads((res / "read" / "eval" / "spe_N100_renoise_rounds1.json").read_text())["chosen_on"] == "val"
    # another grid of settings: the choice over the old one does not count, nor the test evaluations on it
    wider = _cfg(tmp_path, methods=("read",), choice_grid=ChoiceGrid(candidates=(1, 2)))
    assert not all(s.done() for s in pipeline.plan_steps(wider) if s.kind == "choose")


def test_a_val_split_that_does_not_replay_stops_the_choice(tmp_path):
    runner = FakeRunner(RATES, verify_rates={"val": 0.99})
    with pytest.raises(PipelineError, match="verify val"):
        run_in_order(pipeline.plan_steps(_cfg(tmp_path, methods=("read",))), log=lambda m: None, runner=runner)
    assert not any(m in ("choose", "evaluate") for m, _ in runner.calls)
    assert not (tmp_path / "results" / "reach_target" / "read" / "choice.json").exists()


def test_the_pipeline_cli_sets_the_validation_and_its_grid(tmp_path, capsys):
    from experiments import pipeline as pipeline_cli

    argv = ["--tasks", "RT", "--methods", "read", "--data", str(tmp_path / "d"), "--runs", str(tmp_path / "r"),
            "--results", str(tmp_path / "res"), "--dry-run"]
    assert _cli.run(pipeline_cli.main, argv) == 0
    out = capsys.readouterr().out
    assert "generate val 100" in out and "choose read's refinement on val (4 settings)" in out
    grid = ["--val-episodes", "20", "--choice-rounds", "1", "3", "--choice-refine", "cold", "--choice-candidates", "1", "2"]
    assert _cli.run(pipeline_cli.main, argv + grid) == 0
    out = capsys.readouterr().out
    assert "generate val 20" in out and "choose read's refinement on val (4 settings)" in out
    assert "evaluate read on val --N 100 (rounds=3,refine=cold,candidates=2)" in out
    assert _cli.run(pipeline_cli.main, argv + ["--val-episodes", "0"]) == 0
    out = capsys.readouterr().out
    assert "choose" not in out and " val " not in out
    for bad, match in ((["--choice-rounds", "x"], "--choice-rounds"), (["--val-episodes", "-1"], "--val-episodes"),
                       (["--choice-rounds", "0"], "--choice-rounds")):
        assert _cli.run(pipeline_cli.main, argv + bad) == 2
        assert match in capsys.readouterr().err
    text = pipeline_cli.parser().format_help()
    assert "--val-episodes" in text and "--choice-refine" in text and "choice.json" in text
