"""The grid that runs (experiments.main_grid's pipeline commands) is the grid the pages report against
(readjax.lab.grid_plan.GRID / GRID_TASKS), and its paper's-recipe row reverts every departure of the cpu
preset."""

from __future__ import annotations

import dataclasses
import sys

import pytest

from experiments import main_grid, pipeline
from readjax import config, tasks
from readjax.lab import grid_plan
from readjax.lab.pipeline_config import label_configs


def _configs():
    return {phase: pipeline.config(pipeline.parser().parse_args(argv))
            for phase, argv in grid_plan.pipeline_argvs().items()}


def test_the_commands_train_each_planned_run_on_exactly_its_planned_tasks():
    trained: dict[str, set[str]] = {}
    for cfg in _configs().values():
        for label in cfg.methods:
            trained.setdefault(cfg.run_name(label), set()).update(tasks.code_of(t) for t in cfg.tasks)
    assert trained == {run: set(codes) for run, codes in grid_plan.GRID_TASKS.items()}


def test_phase_a_runs_before_phase_b_and_b_adds_seeds_recipe_and_protocols():
    cfgs = _configs()
    assert list(cfgs) == ["A", "B"]
    assert cfgs["A"].protocols == () and set(cfgs["B"].protocols) == set(grid_plan.PROTOCOLS)
    # Tables 5 and 8 on a READ training the same command trains (seed 1), and on the paper's recipe
    assert cfgs["B"].run_name("read") == grid_plan.GRID["read"][1]
    assert cfgs["B"].protocol_runs == grid_plan.GRID["recipe"]
    assert cfgs["B"].fixed_refinement == grid_plan.GRID["recipe"]
    for cfg in cfgs.values():
        assert cfg.read_N == grid_plan.READ_N and cfg.val_episodes > 0 and cfg.preset == "cpu"
        assert not any(cfg.chooses(label) for label in grid_plan.GRID["recipe"] if label in cfg.methods)


def _labels(role: str) -> dict:
    """{seed: (the phase's config, the label that trains it)} of a role's trainings."""
    cfgs = _configs()
    out = {}
    for cfg in cfgs.values():
        for label in cfg.methods:
            if cfg.run_name(label) in grid_plan.GRID[role]:
                out[grid_plan.GRID[role].index(cfg.run_name(label))] = (cfg, label)
    return out


def test_each_seed_run_differs_from_seed_0_only_in_its_seed():
    for role in ("read", "deterministic"):
        trainings = _labels(role)
        assert sorted(trainings) == [0, 1, 2]
        configs = {k: label_configs(cfg, label) for k, (cfg, label) in trainings.items()}
        for seed, mine in configs.items():
            assert mine["train"].seed == seed
            assert dataclasses.replace(mine["train"], seed=0) == configs[0]["train"]
            assert {k: v for k, v in mine.items() if k != "train"} == {k: v for k, v in configs[0].items() if k != "train"}


def test_the_papers_recipe_reverts_every_departure_of_the_cpu_preset_but_the_sizes():
    cfg = _configs()["B"]
    mine = label_configs(cfg, grid_plan.GRID["recipe"][0])
    assert mine["train"].seed == 0  # paired with READ's seed 0 (the first of each row)
    paper, cpu = config.presets("paper"), config.presets("cpu")
    sizes = {"denoiser": {"image_size", "conv_dims", "enc_depths", "dec_depths", "drop_path", "feature_channels",
                          "d_model", "layers", "heads", "ffn"},
             "vae": {"width", "layers", "heads", "ffn", "latent_dim"},
             "train": {"vae_steps", "vae_batch", "vae_lr", "steps", "batch", "lr", "lr_decay", "lr_decay_every",
                       "ckpt_every", "log_every"}}
    for section in ("vae", "denoiser", "sde", "train"):
        for field, cpu_value in vars(cpu[section]).items():
            want = cpu_value if field in sizes.get(section, ()) else getattr(paper[section], field)
            assert getattr(mine[section], field) == want, f"{section}.{field}"


@pytest.mark.parametrize("phases", [["A"], ["A", "B"], ["B"]])
def test_main_grid_prints_one_pipeline_command_per_phase_in_order(phases, capsys):
    assert main_grid.main(["--print", "--phases", *phases, "--", "--ray-address", "h:1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in out] == [f"# phase {p}" for p in phases]
    cmds = main_grid.commands(phases, ["--", "--ray-address", "h:1"], dry_run=True)
    assert all(c[:3] == [sys.executable, "-m", "experiments.pipeline"] and c[-3:] == ["--ray-address", "h:1", "--dry-run"]
               for c in cmds)
    # only the separator is dropped: a later "--" is an argument of the pipeline's
    cmd = main_grid.commands(["A"], ["--", "--set", "--"])[0]
    assert cmd[-2:] == ["--set", "--"] and cmd.count("--") == 1
    assert main_grid.commands(["A"], ["--deadline", "+1h"])[0][-2:] == ["--deadline", "+1h"]


def test_a_sigterm_to_main_grid_goes_on_to_the_running_phase():
    """`kill` on main_grid reaches the pipeline it runs (which stops its steps), not only main_grid."""
    import os
    import signal
    import threading

    child = [sys.executable, "-c", "import signal, sys, time\n"
             "signal.signal(signal.SIGTERM, lambda s, f: sys.exit(7))\nprint('ready', flush=True)\ntime.sleep(60)"]
    timer = threading.Timer(2.0, lambda: os.kill(os.getpid(), signal.SIGTERM))
    timer.start()
    try:
        # 7: its handler ran; -SIGTERM: the signal came before it was set (a slow start): it reached it either way
        assert main_grid._run(child) in (7, -signal.SIGTERM)
    finally:
        timer.cancel()
