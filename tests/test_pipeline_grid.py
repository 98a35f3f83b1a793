"""The grid's plan, run in order with stand-ins for the commands: step order, skipping what is done,
stopping on a failed replay, ETA; what the steps need, as Ray is handed them."""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path

import pytest

from experiments import _cli
from experiments import pipeline as pipeline_cli
from readjax import config, methods
from readjax.lab import cost_table, pipeline, pipeline_config, ray_grid, ray_resources, timing, verification
from readjax.lab.steps import PipelineError, Step, run_in_order
from tests.pipeline_fakes import _fingerprint_from_summary  # noqa: F401 (an autouse fixture)


def _cfg(tmp_path, **kw):
    """A grid without the validation split (its steps: tests/test_pipeline_val.py)."""
    base = dict(tasks=("RT", "PB"), data=str(tmp_path / "data"), runs=str(tmp_path / "runs"),
                results=str(tmp_path / "results"), train_episodes=8, test_episodes=4, val_episodes=0)
    return pipeline_config.PipelineConfig(**{**base, **kw}).validate()


REFINING = ("read", "read_o", "read_l")  # methods that run READ's refinement update (sde.update)


class FakeRunner:
    """Stands in for the commands: writes what each would write, records the calls. ``machine``
    enters every dataset's content hash, as float rounding does on a real machine."""

    def __init__(self, verify_rate=1.0, media_outcome=1, machine="a", read_top=1):
        self.calls, self.verify_rate, self.media_outcome, self.machine = [], verify_rate, media_outcome, machine
        self.read_top = read_top  # READ's outcome in every episode at N = 100 from SPE's start
        self.methods, self.sets, self.recipes = {}, {}, {}

    def __call__(self, argv):
        mod = argv[2].split(".")[1]
        self.calls.append((mod, argv))
        arg = lambda k: argv[argv.index(k) + 1]  # noqa: E731
        if mod == "generate":
            d = Path(arg("--out")) / arg("--task") / arg("--split")
            d.mkdir(parents=True, exist_ok=True)
            (d / "summary.json").write_text(json.dumps({"episodes_kept": int(arg("--episodes")),
                                                        "fingerprint": f"{self.machine}-{arg('--split')}"}))
        elif mod == "verify":
            task = arg("--task")
            fp = json.loads((Path(arg("--data")) / task / "test" / "summary.json").read_text())["fingerprint"]
            verification.write(arg("--results"), {"task": task, "split": "test", "dataset_fingerprint": fp,
                                                  "episodes": int(arg("--episodes")), "success_rate": self.verify_rate})
        elif mod == "train":
            run = Path(arg("--out")) / arg("--task") / arg("--name")
            run.mkdir(parents=True, exist_ok=True)
            self.methods[str(run)] = arg("--model")
            sets = [argv[i + 1] for i, a in enumerate(argv) if a == "--set"]
            configs = config.override(config.presets(arg("--preset")), sets)
            self.recipes[str(run)] = json.loads(json.dumps(config.configs_to_dict(
                configs, [k for k in configs if k != "train"])))
            self.sets[run.name] = [argv[i + 1] for i, a in enumerate(argv) if a == "--set"]
            if "vae" in methods.stages(arg("--model")):  # a finished autoencoder stage
                (run / "vae").mkdir(exist_ok=True)
                (run / "vae" / "stop.json").write_text("{}")
            for stage in [arg("--stage")] if "--stage" in argv else methods.stages(arg("--model")):
                (run / stage).mkdir(exist_ok=True)  # each stage's record of why it stopped, and its curve
                (run / stage / "stop.json").write_text(json.dumps({"reason": "step cap", "stage": stage}))
                (run / stage / "loss.png").write_bytes(b"png")
        elif mod == "evaluate":
            run = Path(arg("--run"))
            ev = Path(arg("--out")) if "--out" in argv else run / "eval"
            ev.mkdir(parents=True, exist_ok=True)
            method, n = self.methods[str(run)], int(arg("--N")) if "--N" in argv else None
            oracle = "--retrieval" in argv and arg("--retrieval") == "cheat"
            rank = int(arg("--rank")) if oracle else 1
            noise = float(arg("--noise")) if "--noise" in argv else 0.0
            bright = float(arg("--brightness")) if "--brightness" in argv else 1.0
            name = (f"cheat{rank}_N{n}" if oracle else f"spe_N{n}") if n is not None else f"cheat{rank}" if oracle \
                else "direct"
            name += (f"_noise{noise:g}" if noise else "") + (f"_bright{bright:g}" if bright != 1.0 else "")
            k = int(arg("--episodes"))
            ok = self.media_outcome if "--out" in argv else self.read_top if (n == 100 and not oracle) else 1
            fp = json.loads((Path(arg("--data")) / run.parent.name / "test" / "summary.json").read_text())["fingerprint"]
            (ev / f"{name}.json").write_text(json.dumps({
                "task": run.parent.name, "method": method, "name": name, "episodes": k, "test_fingerprint": fp,
                "success_rate": float(ok), "eval_config": {
                    "episodes": k, "N": n, "retrieval": "cheat" if oracle else "spe", "rank": rank, "candidates": 1,
                    "rounds": 1,
                    "image_noise": noise, "brightness": bright,
                                "refine_update": "renoise" if method in REFINING else None},
                # READ and its ablations refine with their run's update (here the paper's, one round); a
                # run records only its method's sections (no SDE for the baselines)
                "configs": {**self.recipes.get(str(run), {}), "sde": {
                    **self.recipes.get(str(run), {}).get("sde", {}), "update": "renoise", "rounds": 1}}
                if method in REFINING else {k: v for k, v in self.recipes.get(str(run), {}).items() if k != "sde"},
                "seeds": list(range(1000000, 1000000 + k)), "success": [ok] * k}))
            (ev / f"{name}_overlay.png").write_bytes(b"png")
            if int(arg("--videos")):
                (ev / f"{name}_rollouts.mp4").write_bytes(b"mp4")
        return subprocess.CompletedProcess(argv, 0)


def test_grid_runs_in_order_then_skips_everything(tmp_path):
    cfg = _cfg(tmp_path)
    steps = pipeline.plan_steps(cfg)
    kinds = [(s.task, s.kind) for s in steps[:7]]
    assert kinds == [("reach_target", "generate"), ("reach_target", "verify"), ("reach_target", "generate"),
                     ("reach_target", "train"), ("reach_target", "evaluate"), ("reach_target", "evaluate"),
                     ("reach_target", "media")]
    runner, lines = FakeRunner(), []
    out = run_in_order(steps, log=lines.append, runner=runner)
    assert len(steps) == 2 * (3 + 1 + 2 + 1 + 2 + 1 + 1)
    # READ scores 100 % at N = 100: its oracle-start evaluations (for a task below 80 %) are skipped
    assert out["ran"] == len(steps) - 4 and out["skipped"] == 4
    assert sum("skipped: skip" in ln for ln in lines) == 4
    assert any("ETA" in ln for ln in lines[2:])
    assert (tmp_path / "results" / "push_button" / "read" / "eval" / "spe_N0.json").exists()
    assert (tmp_path / "results" / "push_button" / "deterministic" / "eval" / "direct.json").exists()
    # each training's records (why it stopped, its loss curve) are committed beside its evaluations
    for run, stages in (("read", ("vae", "read")), ("deterministic", ("deterministic",))):
        training = tmp_path / "results" / "push_button" / run / "training"
        assert sorted(f.name for f in training.iterdir()) == sorted(stages)
        for stage in stages:
            assert sorted(f.name for f in (training / stage).iterdir()) == ["loss.png", "stop.json"]
            assert json.loads((training / stage / "stop.json").read_text())["stage"] == stage
    # the rendered episodes go to media/, apart from the evaluations a table reads
    media = tmp_path / "results" / "push_button" / "read" / "media"
    assert sorted(f.name for f in media.iterdir()) == ["spe_N100.json", "spe_N100_overlay.png", "spe_N100_rollouts.mp4"]
    assert len(json.loads((media / "spe_N100.json").read_text())["seeds"]) == 4  # which episodes they show
    argv = next(a for m, a in runner.calls if m == "evaluate" and "--out" in a)
    assert argv[argv.index("--episodes") + 1] == "4" and argv[argv.index("--N") + 1] == "100"
    assert not (tmp_path / "results" / "push_button" / "read" / "eval" / "spe_N100_rollouts.mp4").exists()
    # every step's wall clock is recorded beside the task's results, and the report tabulates it
    record = json.loads((tmp_path / "results" / "reach_target" / "pipeline_timing.json").read_text())
    assert record["task"] == "reach_target" and len(record["steps"]) == len(steps) // 2 - 2
    assert {st["kind"] for st in record["steps"].values()} == {"generate", "verify", "train", "evaluate", "media"}
    assert all(st["seconds"] >= 0 and st["cpus"] >= 1 for st in record["steps"].values())
    prior = timing.prior_costs(tmp_path / "results")  # both tasks' records, for a later run's ETA
    recorded = [json.loads((tmp_path / "results" / t / "pipeline_timing.json").read_text())["steps"]["train read"]
                ["seconds"] for t in ("push_button", "reach_target")]
    assert prior["label"]["train read"] == recorded and len(prior["kind"]["verify"]) == 2
    costs = cost_table.cost_lines(tmp_path / "results")
    assert ("| task | generate | verify | train deterministic | train read | evaluate | media | total | CPU | cores "
            "| load |") in costs
    assert all(" | – | " in ln for ln in costs if ln.startswith(("| RT", "| PB")))  # fakes: no CPU time recorded
    assert [ln.split(" |")[0] for ln in costs if ln.startswith("| ") and not ln.startswith("| task")] == [
        "| RT", "| PB", "| all 2"]
    # a step run again (a replicate, a regenerated split) keeps the first record and adds a repeat
    gen = next(s for s in steps if s.task == "reach_target" and s.kind == "generate")
    first = record["steps"][gen.label]
    timing.record_timing(gen, 297.3, 4.3)
    timing.record_timing(gen, 12.0, None)
    record = json.loads((tmp_path / "results" / "reach_target" / "pipeline_timing.json").read_text())
    assert record["steps"][gen.label] == first
    assert [r["seconds"] for r in record["repeats"][gen.label]] == [297.3, 12.0]
    assert cost_table.cost_lines(tmp_path / "results") == costs
    again = FakeRunner()
    assert run_in_order(pipeline.plan_steps(cfg), log=lines.append, runner=again)["ran"] == 0
    assert again.calls == []
    # each version of a split keeps its replay record, named by its content hash
    assert (tmp_path / "results" / "push_button" / "verify" / "test_a-test.json").exists()


def test_a_fresh_machine_needs_only_the_results(tmp_path):
    """With datasets and runs gone (another machine, the committed results/ only), the grid is done;
    with one evaluation missing, it regenerates, re-verifies and retrains only what that one needs."""
    import shutil

    cfg = _cfg(tmp_path)
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=FakeRunner())
    shutil.rmtree(tmp_path / "data")
    shutil.rmtree(tmp_path / "runs")
    fresh = FakeRunner(machine="b")
    assert run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=fresh)["ran"] == 0
    (tmp_path / "results" / "push_button" / "deterministic" / "eval" / "direct.json").unlink()
    steps = pipeline.plan_steps(cfg)
    assert [(s.task, s.label) for s in steps if not s.done()] == [
        ("push_button", "generate test 4"), ("push_button", "verify test (ground truth replay = 100 %)"),
        ("push_button", "generate train 8"), ("push_button", "train deterministic"),
        ("push_button", "evaluate deterministic")]
    assert [s.status() for s in steps if s.task == "push_button"] == [
        "todo", "todo", "todo", "skip", "done", "done", "done", "skip", "skip", "todo", "todo"]  # train read: not needed
    run_in_order(steps, log=lambda m: None, runner=fresh)
    assert [m for m, _ in fresh.calls] == ["generate", "verify", "generate", "train", "evaluate"]
    # machine b's split has its own replay record beside machine a's
    assert sorted(f.name for f in (tmp_path / "results" / "push_button" / "verify").iterdir()) == [
        "test_a-test.json", "test_b-test.json"]


def test_an_evaluation_counts_only_on_a_verified_split(tmp_path):
    """An evaluation in results/ whose test split has no 100 % replay on record is not done: the
    grid verifies the split here and evaluates again."""
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("deterministic",))
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=FakeRunner())
    record = tmp_path / "results" / "reach_target" / "verify" / "test_a-test.json"
    record.unlink()
    assert [s.label for s in pipeline.plan_steps(cfg) if not s.done()] == [
        "verify test (ground truth replay = 100 %)", "evaluate deterministic"]
    record.parent.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps({"task": "reach_target", "split": "test", "dataset_fingerprint": "a-test",
                                  "episodes": 4, "success_rate": 0.99}))
    assert not pipeline.plan_steps(cfg)[-1].done()  # a record below 100 % verifies nothing


def test_run_names_keep_a_recipe_apart(tmp_path):
    cfg = _cfg(tmp_path, tasks=("RT",), run_names=(("read", "read_v3_5k"),))
    steps = pipeline.plan_steps(cfg)
    train = [s for s in steps if s.kind == "train"]
    assert [s.argv[s.argv.index("--name") + 1] for s in train] == ["read_v3_5k", "deterministic"]
    run_in_order(steps, log=lambda m: None, runner=FakeRunner())
    assert (tmp_path / "results" / "reach_target" / "read_v3_5k" / "eval" / "spe_N100.json").exists()
    assert (tmp_path / "runs" / "reach_target" / "read_v3_5k" / "pipeline_trained.json").exists()
    with pytest.raises(ValueError, match="not among --methods"):
        _cfg(tmp_path, run_names=(("vpsde", "v"),))
    with pytest.raises(ValueError, match="one folder name"):
        _cfg(tmp_path, run_names=(("read", "a/b"),))


def test_a_failed_replay_stops_before_training(tmp_path):
    runner = FakeRunner(verify_rate=0.97)
    with pytest.raises(PipelineError, match="100 %"):
        run_in_order(pipeline.plan_steps(_cfg(tmp_path)), log=lambda m: None, runner=runner)
    assert [c[0] for c in runner.calls] == ["generate", "verify"]


def test_rendered_episodes_must_match_the_evaluation(tmp_path):
    """A video whose outcomes differ from the table's on the same seeds stops the grid."""
    with pytest.raises(PipelineError, match="depends on its batch"):
        run_in_order(pipeline.plan_steps(_cfg(tmp_path, tasks=("RT",))), log=lambda m: None,
                            runner=FakeRunner(media_outcome=0))
    steps = pipeline.plan_steps(_cfg(tmp_path, tasks=("RT",), media_episodes=0))
    assert "media" not in {s.kind for s in steps}
    with pytest.raises(ValueError, match="--media-episodes"):
        _cfg(tmp_path, media_episodes=-1)


def test_a_weak_task_is_evaluated_from_the_oracles_start(tmp_path):
    """READ below --diagnose-below % at its largest N: the grid evaluates it from the oracle's start
    at each N too (retrieval or refinement: which limits the task); at or above, it does not."""
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read",))
    runner = FakeRunner(read_top=0, media_outcome=0)
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=runner)
    oracle = [a for m, a in runner.calls if m == "evaluate" and "cheat" in a]
    assert [a[a.index("--N") + 1] for a in oracle] == ["0", "100"] and all(a[a.index("--rank") + 1] == "1" for a in oracle)
    ev = tmp_path / "results" / "reach_target" / "read" / "eval"
    assert sorted(f.name for f in ev.glob("*.json")) == ["cheat1_N0.json", "cheat1_N100.json", "spe_N0.json",
                                                         "spe_N100.json"]
    assert [s.status() for s in pipeline.plan_steps(cfg)][-2:] == ["done", "done"]
    never = _cfg(tmp_path / "b", tasks=("RT",), methods=("read",), diagnose_below=0.0)
    assert not any("oracle" in s.label for s in pipeline.plan_steps(never))
    with pytest.raises(ValueError, match="--diagnose-below"):
        _cfg(tmp_path, diagnose_below=120.0)


def test_variants_train_with_their_own_overrides_in_their_own_runs(tmp_path):
    """A --variant is its method trained with extra overrides (after the grid's) in a run folder of its
    own, evaluated as its method is: its own row; READ's media and diagnosis stay with READ itself."""
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read", "read_o_em", "read_kin"), overrides=("train.steps=7",),
               variants=(("read_o_em", "read_o", ("read_o.sampler=em",)), ("read_kin", "read", ("vae.kinematic=true",))))
    runner = FakeRunner(read_top=0, media_outcome=0)
    steps = pipeline.plan_steps(cfg)
    assert [Path(s.argv[s.argv.index("--run") + 1]).name for s in steps if s.kind == "media"] == ["read"]
    assert [s.label for s in steps if s.kind in ("train", "evaluate") and "read_" in s.label] == [
        "train read_o_em", "evaluate read_o_em", "train read_kin", "evaluate read_kin --N 0", "evaluate read_kin --N 100"]
    run_in_order(steps, log=lambda m: None, runner=runner)
    trained = {a[a.index("--name") + 1]: a[a.index("--model") + 1] for m, a in runner.calls if m == "train"}
    assert trained == {"read": "read", "read_o_em": "read_o", "read_kin": "read"}
    assert runner.sets == {"read": ["train.steps=7"], "read_o_em": ["train.steps=7", "read_o.sampler=em"],
                           "read_kin": ["train.steps=7", "vae.kinematic=true"]}
    res = tmp_path / "results" / "reach_target"
    assert sorted(f.name for f in (res / "read_o_em" / "eval").iterdir()) == ["direct.json"]
    assert sorted(f.name for f in (res / "read_kin" / "eval").iterdir()) == ["spe_N0.json", "spe_N100.json"]
    assert sorted(f.name for f in (res / "read" / "eval").iterdir()) == ["cheat1_N0.json", "cheat1_N100.json",
                                                                         "spe_N0.json", "spe_N100.json"]
    assert [p.parent.name for p in res.glob("*/media")] == ["read"]
    assert all(s.status() == "done" for s in pipeline.plan_steps(cfg))
    for bad, match in [(dict(variants=(("read", "read", ()),)), "must differ"),
                       (dict(variants=(("v", "nope", ()),)), "nope"),
                       (dict(methods=("v",), variants=(("v", "read", ("vae.nofield=1",)),)), "v: .*no field"),
                       (dict(methods=("v",), variants=(("v", "read", ("kinematic",)),)), "KEY=VALUE"),
                       (dict(overrides=("steps=x",)), "read: ")]:
        with pytest.raises(ValueError, match=match):
            _cfg(tmp_path, **bad)


def test_a_variant_with_reads_autoencoder_starts_from_it(tmp_path):
    """A READ variant that changes only what comes after the autoencoder (the SDE, the denoiser, K)
    starts from READ's autoencoder stage (--vae-from), trained once by a step of its own: READ's full
    training is not redone for it when READ's evaluations are already in results/. One that changes
    the autoencoder trains its own."""
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read", "read_sf", "read_kin", "read_l"),
               variants=(("read_sf", "read", ("sde.self_feed=0.5", "train.K=3")),
                         ("read_kin", "read", ("vae.kinematic=true",))))
    steps = pipeline.plan_steps(cfg)
    trains = {s.label: s for s in steps if s.kind == "train"}
    source = tmp_path / "runs" / "reach_target" / "read"
    vae_from = {label: s.argv[s.argv.index("--vae-from") + 1] if "--vae-from" in s.argv else None
                for label, s in trains.items()}
    assert vae_from == {"train read": None, "train read (autoencoder only)": None, "train read_sf": str(source),
                        "train read_kin": None, "train read_l": str(source)}
    shared = trains["train read (autoencoder only)"]
    assert shared.argv[shared.argv.index("--stage") + 1] == "vae"
    assert shared.users == [trains["train read_sf"], trains["train read_l"]]
    assert [s.label for s in steps if s.kind == "train"].index(shared.label) < \
        [s.label for s in steps if s.kind == "train"].index("train read_sf")
    runner = FakeRunner(read_top=0, media_outcome=0)
    run_in_order(steps, log=lambda m: None, runner=runner)
    stages = [a[a.index("--stage") + 1] if "--stage" in a else "all" for m, a in runner.calls if m == "train"]
    # the autoencoder step first (listed before READ's training, which waits on it); READ's training then
    # resumes past that finished stage in the same run folder, and the variants start from it
    assert stages == ["vae", "all", "all", "all", "all"]
    # READ's evaluations done: a new variant needs READ's autoencoder only, and it is there
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read", "read_sf2"),
               variants=(("read_sf2", "read", ("sde.self_feed=1.0",)),))
    status = {s.label: s.status() for s in pipeline.plan_steps(cfg) if s.kind == "train"}
    assert status == {"train read": "done", "train read (autoencoder only)": "done", "train read_sf2": "todo"}


def test_protocols_add_reads_evaluations_for_the_papers_other_tables(tmp_path):
    """--protocols oracle poor perturbed: READ from the oracle's 1st / 3rd / 10th neighbour at N = 0 and
    the top N (Tables 4, 5), from its 500th at N = 0 / 1 / top (Table 8), and on noisy and darkened
    images at the top N (Table 9); each once (the diagnosis's oracle start is not repeated), each
    done when results/ holds it."""
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read",), media_episodes=0, protocols=("oracle", "poor", "perturbed"),
               noise=0.1, brightness=0.6, train_episodes=1000)
    steps = pipeline.plan_steps(cfg)
    labels = [s.label for s in steps if s.kind == "evaluate"]
    assert labels == ["evaluate read --N 0", "evaluate read --N 100",
                      "evaluate read from the oracle's start --N 0", "evaluate read from the oracle's start --N 100",
                      "evaluate read from the oracle's 3rd neighbour --N 0",
                      "evaluate read from the oracle's 3rd neighbour --N 100",
                      "evaluate read from the oracle's 10th neighbour --N 0",
                      "evaluate read from the oracle's 10th neighbour --N 100",
                      "evaluate read from the oracle's 500th neighbour --N 0",
                      "evaluate read from the oracle's 500th neighbour --N 1",
                      "evaluate read from the oracle's 500th neighbour --N 100",
                      "evaluate read on noisy images (std 0.1) --N 100", "evaluate read at brightness x0.6 --N 100"]
    runner = FakeRunner(read_top=0)
    run_in_order(steps, log=lambda m: None, runner=runner)
    names = sorted(f.stem for f in (tmp_path / "results" / "reach_target" / "read" / "eval").glob("*.json"))
    assert names == sorted(["spe_N0", "spe_N100", "cheat1_N0", "cheat1_N100", "cheat3_N0", "cheat3_N100", "cheat10_N0",
                            "cheat10_N100", "cheat500_N0", "cheat500_N1", "cheat500_N100", "spe_N100_noise0.1",
                            "spe_N100_bright0.6"])
    again = FakeRunner()
    assert run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=again)["ran"] == 0
    assert not again.calls
    # READ-O and READ-L (and their variants) from the oracle's neighbours too, at their default N (Table 4)
    abl = _cfg(tmp_path / "abl", tasks=("RT",), methods=("read", "read_l", "read_o_em"), media_episodes=0,
               variants=(("read_o_em", "read_o", ("read_o.sampler=em",)),), protocols=("oracle",))
    steps = pipeline.plan_steps(abl)
    labels = [s.label for s in steps if s.kind == "evaluate" and not s.label.startswith("evaluate read ")]
    assert labels == ["evaluate read_l", "evaluate read_l from the oracle's start",
                      "evaluate read_l from the oracle's 3rd neighbour", "evaluate read_l from the oracle's 10th neighbour",
                      "evaluate read_o_em", "evaluate read_o_em from the oracle's start",
                      "evaluate read_o_em from the oracle's 3rd neighbour",
                      "evaluate read_o_em from the oracle's 10th neighbour"]
    run_in_order(steps, log=lambda m: None, runner=FakeRunner())
    names = sorted(f.stem for f in (tmp_path / "abl" / "results" / "reach_target" / "read_o_em" / "eval").glob("*.json"))
    assert names == ["cheat1", "cheat10", "cheat3", "direct"]
    assert run_in_order(pipeline.plan_steps(abl), log=lambda m: None, runner=FakeRunner())["ran"] == 0
    # without --protocols the weak task's oracle start is still evaluated, as the diagnosis
    diag = [s.label for s in pipeline.plan_steps(dataclasses.replace(cfg, protocols=())) if "oracle" in s.label]
    assert diag == ["evaluate read from the oracle's start --N 0 (READ below 80 %)",
                    "evaluate read from the oracle's start --N 100 (READ below 80 %)"]
    for bad, match in [(dict(protocols=("table9",)), "unknown"),
                       (dict(protocols=("oracle",), methods=("deterministic",)), "add read"),
                       (dict(protocols=("perturbed",), noise=0.0), "noise > 0"), (dict(brightness=0.0), "brightness"),
                       (dict(protocols=("poor",)), "at least 500")]:
        with pytest.raises(ValueError, match=match):
            _cfg(tmp_path, **bad)


def test_a_run_name_of_another_recipe_is_refused(tmp_path, capsys):
    """results/ holding a run of the same name trained another way: the grid refuses before any
    work, since its finished evaluations would count as this recipe's; the fields that change
    inference only, or that training fills from the data, are not the recipe."""
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read",), media_episodes=0)
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=FakeRunner())
    f = tmp_path / "results" / "reach_target" / "read" / "eval" / "spe_N0.json"
    r = json.loads(f.read_text())
    r["configs"]["sde"].update(update="cold", rounds=3)  # inference only
    r["configs"]["denoiser"]["motion_std"] = [0.1] * 10  # from the training set
    f.write_text(json.dumps(r))
    assert all(s.done() for s in pipeline.plan_steps(cfg))
    with pytest.raises(PipelineError, match=r"another recipe .*differs in sde\.lam\).*--run-name read=NEW_NAME"):
        pipeline.plan_steps(dataclasses.replace(cfg, overrides=("L=0.1",)))
    assert pipeline.plan_steps(dataclasses.replace(cfg, overrides=("L=0.1",), run_names=(("read", "read_L01"),)))
    r["configs"]["train"]["steps"] = 7
    f.write_text(json.dumps(r))
    argv = ["--tasks", "RT", "--methods", "read", "--data", cfg.data, "--runs", cfg.runs, "--results", cfg.results,
            "--dry-run"]
    assert _cli.run(pipeline_cli.main, argv) == 1
    assert "differs in train.steps" in capsys.readouterr().err


def test_runs_trained_before_the_preset_self_fed_are_kept_by_an_explicit_override(tmp_path):
    """The cpu preset trains READ's denoiser on its own predictions (sde.self_feed = 0.5). A READ run
    recorded before the field existed trained with 0: under the current preset the grid refuses its
    run name, and the README's grid commands keep it with --set sde.self_feed=0."""
    from readjax import config
    assert config.presets("cpu")["sde"].self_feed == 0.5 and config.presets("paper")["sde"].self_feed == 0.0
    cfg = _cfg(tmp_path, tasks=("RT",), methods=("read",), media_episodes=0)
    run_in_order(pipeline.plan_steps(cfg), log=lambda m: None, runner=FakeRunner())
    evals = sorted((tmp_path / "results" / "reach_target" / "read" / "eval").glob("*.json"))
    assert evals
    for f in evals:
        r = json.loads(f.read_text())
        assert r["configs"]["sde"]["self_feed"] == 0.5
        del r["configs"]["sde"]["self_feed"]  # an older readjax's record
        f.write_text(json.dumps(r))
    with pytest.raises(PipelineError, match=r"differs in sde\.self_feed"):
        pipeline.plan_steps(cfg)
    kept = dataclasses.replace(cfg, overrides=("sde.self_feed=0",))
    assert all(s.done() for s in pipeline.plan_steps(kept))


def test_eta_prices_each_step_by_its_own_label(tmp_path):
    """The ETA uses the time of the same step on an earlier task, not the mean of its kind."""
    steps = [s for s in pipeline.plan_steps(_cfg(tmp_path, tasks=("RT",))) if s.kind == "train"]
    read, det = steps
    by_label = {read.label: [2100.0]}
    by_kind = {"train": [2100.0]}
    assert timing.eta([det], by_label, by_kind) == 2100.0  # nothing known of the regressor yet
    by_label[det.label] = [420.0]
    by_kind["train"].append(420.0)
    assert timing.eta([read, det], by_label, by_kind) == 2520.0
    assert timing.eta([read], {}, {}) is None
    # earlier runs' timings (results/<task>/pipeline_timing.json) price what this run has not timed yet
    prior = {"label": {det.label: [400.0, 440.0]}, "kind": {"train": [2000.0, 420.0], "verify": [60.0]}}
    assert timing.eta([read, det], {}, {}, prior) == 1210.0 + 420.0
    assert timing.eta([det], {det.label: [300.0]}, {"train": [300.0]}, prior) == 300.0  # this run first


def test_cli_dry_run_and_errors(tmp_path, capsys):
    argv = ["--tasks", "RT", "--data", str(tmp_path / "d"), "--runs", str(tmp_path / "r"), "--results",
            str(tmp_path / "res"), "--dry-run"]
    assert _cli.run(pipeline_cli.main, argv) == 0
    out = capsys.readouterr().out
    assert "todo  ~?  reach_target: generate test 100" in out and "no timing records" in out
    # earlier runs' records price the steps: a training by its own label, the rest by their kind
    record = tmp_path / "res" / "push_button" / timing.TIMING_FILE
    record.parent.mkdir(parents=True)
    record.write_text(json.dumps({"task": "push_button", "steps": {
        "train read": {"kind": "train", "seconds": 2100.0}, "generate test 100": {"kind": "generate", "seconds": 60.0}}}))
    assert _cli.run(pipeline_cli.main, argv + ["--ray-address", "127.0.0.1:1"]) == 0  # a dry run starts no Ray
    out = capsys.readouterr().out
    assert "todo  ~0:35:00  reach_target: train read" in out and "todo  ~0:01:00  reach_target: generate test 100" in out
    todo = [ln for ln in out.splitlines() if ln.startswith("todo")]
    total = sum(int(h) * 3600 + int(m) * 60 + int(sec) for h, m, sec in
                (ln.split("~")[1].split()[0].split(":") for ln in todo))
    assert f"to run: {len(todo)} steps, about {timing.hms(total)} of work" in out
    for bad, match in ((["--resources", "train:num_gpus"], "must be a number"),
                       (["--resources", "fit:num_cpus=1"], "KIND one of"), (["--resources", "train:gpus=1"], "KEY is")):
        assert _cli.run(pipeline_cli.main, argv + bad) == 2
        assert match in capsys.readouterr().err
    assert _cli.run(pipeline_cli.main, argv + ["--run-name", "read"]) == 2
    assert "METHOD=NAME" in capsys.readouterr().err
    assert _cli.run(pipeline_cli.main, ["--tasks", "XX", "--dry-run"]) == 2
    with pytest.raises(SystemExit):  # no hand-made concurrency: Ray runs as many steps as the nodes allow
        _cli.run(pipeline_cli.main, argv + ["--jobs", "2"])
    assert "unrecognized arguments: --jobs" in capsys.readouterr().err
    assert _cli.run(pipeline_cli.main, argv + ["--variant", "read_kin"]) == 2
    assert "LABEL METHOD" in capsys.readouterr().err
    variant = ["--methods", "read", "--variant", "read_kin", "read", "vae.kinematic=true",
               "--protocols", "poor"]
    assert _cli.run(pipeline_cli.main, argv + variant) == 0
    out = capsys.readouterr().out
    assert "reach_target: train read_kin" in out and "500th neighbour --N 1" in out


def test_steps_are_handed_to_ray_after_what_they_need(tmp_path):
    """Ray starts a step once the steps it needs have finished (their tasks' results are its
    arguments): data and replay before training, READ's autoencoder trained once before its
    variants and READ's denoiser, an evaluation before the media and the diagnosis that compare with
    it; the listed order already respects them, and READ's autoencoder step is listed right before
    READ's training, so READ (then its evaluations) is handed over before the baselines listed after."""
    cfg = _cfg(tmp_path, methods=("read", "deterministic", "vpsde", "read_l", "read_sf"),
               variants=(("read_sf", "read", ("sde.self_feed=0.5",)),), read_N=(0, 100))
    steps = pipeline.plan_steps(cfg)
    assert ray_grid._in_dependency_order(steps) == list(range(len(steps)))
    for task in ("reach_target", "push_button"):
        mine = [s for s in steps if s.task == task]
        by_label = {s.label: s for s in mine}
        shared, read = by_label["train read (autoencoder only)"], by_label["train read"]
        assert shared in read.needs and shared in by_label["train read_l"].needs and shared in by_label["train read_sf"].needs
        assert all(n.kind in ("generate", "verify") for n in shared.needs) and len(shared.needs) == 3
        media = next(s for s in mine if s.kind == "media")
        assert by_label["evaluate read --N 100"] in media.needs
        for s in mine:
            if s.kind == "evaluate":  # its training, and the task's data and replay
                assert {n.kind for n in s.needs} >= {"generate", "verify", "train"}
        trains = [s.label for s in mine if s.kind == "train"]
        assert trains[:3] == ["train read (autoencoder only)", "train read", "train deterministic"]
    # a step that needs a step listed after it is handed over after it; a cycle is refused
    a, b = (Step("train", "reach_target", x, ["x"], made=lambda: False) for x in "ab")
    a.needs.append(b)
    assert ray_grid._in_dependency_order([a, b]) == [1, 0]
    b.needs.append(a)
    with pytest.raises(PipelineError, match="needs itself"):
        ray_grid._in_dependency_order([a, b])


def test_what_a_step_asks_of_a_node(tmp_path):
    """Each kind asks for a CPU and memory; a training also a share of a GPU where the cluster has
    GPUs (the GPU nodes take the trainings, the CPU nodes the rest); --resources changes any of it,
    and a kind no node could run is refused instead of waiting for ever."""
    plain = ray_resources.step_resources()
    assert all(d["num_cpus"] == 1 and d["memory"] >= ray_resources.GIB and "num_gpus" not in d for d in plain.values())
    gpu = ray_resources.step_resources(gpus=2)
    assert gpu["train"]["num_gpus"] == pytest.approx(1 / ray_resources.TRAININGS_PER_GPU)
    assert "num_gpus" not in gpu["evaluate"]
    mine = ray_resources.step_resources(ray_resources.parse_resources(["train:num_gpus=0.5,memory=1.5", "evaluate:num_cpus=2"]), 2)
    assert mine["train"] == {"num_cpus": 1, "num_gpus": 0.5, "memory": int(1.5 * ray_resources.GIB)}
    assert mine["evaluate"]["num_cpus"] == 2
    node = {"Alive": True, "Resources": {"CPU": 2.0, "memory": 2.5 * ray_resources.GIB}}
    ray_resources.check_fits(mine, ["evaluate"], [node])
    with pytest.raises(PipelineError, match=r"a train step asks \(CPU 1, GPU 0.5, memory 1.5 GiB\).*--resources train:"):
        ray_resources.check_fits(mine, ["evaluate", "train"], [node, {"Alive": False, "Resources": {"GPU": 1.0}}])


def test_steps_go_to_free_cpus_in_the_grids_order_and_a_failed_steps_users_are_not_run():
    """ray_grid.next_steps: the first ready steps in the grid's order (a later task's data waits while an earlier
    task has a ready step), as many as CPUs are free; the steps needing a failed step, directly or not, leave."""
    # task A: 0 data -> 1 train -> 2 evaluate; task B: 3 data -> 4 train -> 5 evaluate
    needs = {0: [], 1: [0], 2: [1], 3: [], 4: [3], 5: [4]}
    waiting = [0, 1, 2, 3, 4, 5]
    assert ray_grid.next_steps(waiting, needs, set(), set(), 1) == ([0], [])
    assert ray_grid.next_steps(waiting, needs, set(), set(), 2) == ([0, 3], [])
    waiting = [1, 2, 3, 4, 5]  # A's data finished: A's training goes before B's data
    assert ray_grid.next_steps(waiting, needs, {0}, set(), 1) == ([1], [])
    assert ray_grid.next_steps(waiting, needs, {0}, set(), 0) == ([], [])
    waiting = [2, 3, 4, 5]
    go, unrunnable = ray_grid.next_steps(waiting, needs, {0}, {1}, 2)  # A's training failed
    assert go == [3] and unrunnable == [(2, [1])] and waiting == [3, 4, 5]  # the caller takes out what goes
    waiting = [4, 5]  # B's data failed: its training and, through it, its evaluation are not run
    assert ray_grid.next_steps(waiting, needs, set(), {3}, 2) == ([], [(4, [3]), (5, [4])]) and waiting == []
