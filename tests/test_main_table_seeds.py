"""The paper's main table over several trainings per role (experiments.report --main with
comma-separated runs, readjax.lab.main_table_seeds): each cell's mean, range and count over the
trainings, the averages over trainings, the pooled paired tests and each training's own row."""

import json

from experiments import _cli
from experiments import report as report_cli
from readjax import tasks
from readjax.lab import paper, readme_tables, verification
from readjax.lab.report import collect
from tests.test_main_table import _section, _write


def _edit(runs, task, run, name, **fields):
    f = runs / task / run / "eval" / f"{name}.json"
    f.write_text(json.dumps(dict(json.loads(f.read_text()), **fields)))


def _row(label, cells, cols):
    return f"| {label} | " + " | ".join(cells.get(c, "–") for c in cols) + " |"


def _three_trainings(runs):
    """Three READ trainings and three Deterministic ones on RT (and PB in some), 10 test episodes."""
    T, F = True, False
    read = {"read_s2": ([T] * 9 + [F], [F] * 3 + [T] * 7, [T] * 10),  # RT N=100, RT N=0, PB N=100
            "read_s2_seed1": ([T] * 7 + [F] * 3, [T] * 2 + [F] * 8, [T] * 8 + [F] * 2),
            "read_s2_seed2": ([T] * 8 + [F] * 2, [T] * 4 + [F] * 6, None)}
    for run, (n100, n0, pb) in read.items():
        _write(runs, "reach_target", run, "spe_N100_now", n100)
        _write(runs, "reach_target", run, "spe_N0", n0, N=0)
        if pb is not None:
            _write(runs, "push_button", run, "spe_N100_now", pb)
    for run, rt in (("det_s2", [F] * 2 + [T] * 8), ("det_s2_seed1", [T] * 6 + [F] * 4),
                    ("det_s2_seed2", [T] * 5 + [F] * 5)):
        _write(runs, "reach_target", run, "direct", rt, method="deterministic", N=None)
    _write(runs, "push_button", "det_s2_seed1", "direct", [T] * 4 + [F] * 6, method="deterministic", N=None)
    _edit(runs, "reach_target", "det_s2_seed2", "direct", seeds=list(range(10, 20)))  # other episodes: not paired
    verification.write(runs, {"task": "reach_target", "split": "test", "dataset_fingerprint": "fp-reach_target",
                              "episodes": 10, "success_rate": 1.0})


READS, DETS = "read_s2,read_s2_seed1,read_s2_seed2", "det_s2,det_s2_seed1,det_s2_seed2"


def test_several_trainings_per_role_give_each_cell_their_mean_range_and_count(tmp_path):
    runs = tmp_path / "results"
    _three_trainings(runs)
    other_suite = 1 if tasks.SUITE_VERSION != 1 else 2  # another suite's result fills nothing
    _write(runs, "pick_up_cup", "read_s2", "spe_N100_now", [True] * 10)
    _edit(runs, "pick_up_cup", "read_s2", "spe_N100_now", suite=other_suite)
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", READS, DETS]) == 0
    section = _section(out)
    cols = list(tasks.AVG16) + ["Avg12", "Avg16", "Avg (1)"]  # PB is not in every READ training: RT only
    assert "| method | " + " | ".join(cols) + " |" in section
    assert _row("READ (N=100): mean of 3 trainings",
                {"RT": "80.0 (70-90)", "PB": "90.0 (80-100) n=2‡", "Avg (1)": "80.0 (70-90)"}, cols) in section
    assert _row("retrieval only (N=0): mean of 3 trainings",
                {"RT": "43.3 (20-70)", "Avg (1)": "43.3 (20-70)"}, cols) in section
    assert _row("Deterministic: mean of 3 trainings",
                {"RT": "63.3 (50-80)", "PB": "40.0 n=1‡", "Avg (1)": "63.3 (50-80)"}, cols) in section
    assert next(ln for ln in section.splitlines() if ln.startswith(f"| {paper.READ_LABEL}")).endswith(
        "| 88.8 | 70.2 | 99.0 |")  # the paper's row as it is, its Avg (1) over RT
    # pooled over the trainings: RT N=100 vs N=0 +3/-1, +5/-0, +4/-0; vs Deterministic +2/-1, +1/-0 and the
    # third pair left out (other episodes); PB only in the second pair
    assert "| RT | +12 / -1, p=0.0034, 3 pairs | +3 / -1, p=0.62, 2 pairs |" in section
    assert "| PB | – | +4 / -0, p=0.12, 1 pair |" in section
    assert "- `read_s2_seed2` / `det_s2_seed2`, RT vs Deterministic: not the same test episodes" in section
    assert "not a result until it has one: READ (N=100) `read_s2` PB, READ (N=100) `read_s2_seed1` PB, " \
           "Deterministic `det_s2_seed1` PB." in section


def test_each_trainings_own_row_stays_below_the_means(tmp_path):
    runs = tmp_path / "results"
    _three_trainings(runs)
    # read_s2_seed1's RT: the setting chosen on its validation split fills its cell before the preset's
    _write(runs, "reach_target", "read_s2_seed1", "spe_N100_chosen", [True] * 10, refine_update="renoise", rounds=1)
    _edit(runs, "reach_target", "read_s2_seed1", "spe_N100_chosen", chosen_on="val",
          choice={"chosen": {"rounds": 1, "refine": "renoise", "candidates": 1}})
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", READS, DETS]) == 0
    section = _section(out)
    per_training = section.split("Each training's row")[1].split("‡ ran on")[0]
    cols = list(tasks.AVG16) + ["Avg12", "Avg16", "Avg (1)"]
    expected = [
        _row("READ (N=100): `read_s2`", {"RT": "90.0", "PB": "100.0‡", "Avg (1)": "90.0"}, cols),
        _row("READ (N=100): `read_s2_seed1`", {"RT": "100.0", "PB": "80.0‡", "Avg (1)": "100.0"}, cols),
        _row("READ (N=100): `read_s2_seed2`", {"RT": "80.0", "Avg (1)": "80.0"}, cols),
        _row("retrieval only (N=0): `read_s2`", {"RT": "70.0", "Avg (1)": "70.0"}, cols),
        _row("retrieval only (N=0): `read_s2_seed1`", {"RT": "20.0", "Avg (1)": "20.0"}, cols),
        _row("retrieval only (N=0): `read_s2_seed2`", {"RT": "40.0", "Avg (1)": "40.0"}, cols),
        _row("Deterministic: `det_s2`", {"RT": "80.0", "Avg (1)": "80.0"}, cols),
        _row("Deterministic: `det_s2_seed1`", {"RT": "60.0", "PB": "40.0‡", "Avg (1)": "60.0"}, cols),
        _row("Deterministic: `det_s2_seed2`", {"RT": "50.0", "Avg (1)": "50.0"}, cols)]
    assert [ln for ln in per_training.splitlines() if ln.startswith("| ") and "`" in ln] == expected
    assert _row("READ (N=100): mean of 3 trainings", {"RT": "90.0 (80-100)", "PB": "90.0 (80-100) n=2‡",
                                                      "Avg (1)": "90.0 (80-100)"}, cols) in section
    assert "spe_N100_now.json` also qualifies" in section
    assert "| RT | +15 / -1, p=0.00052, 3 pairs | +6 / -1, p=0.12, 2 pairs |" in section


def test_averages_over_trainings_are_each_trainings_own_average(tmp_path):
    """Avg12 / Avg16: the mean and range of the trainings' own averages where every training has every
    member task; where one lacks a task, the mean over the tasks of each task's mean over the trainings
    that have it (§, no range): every training counts where it was measured."""
    runs = tmp_path / "results"
    for run, outcome in (("read_s2", [True, True]), ("read_s2_seed1", [True, False]),
                         ("read_s2_seed2", [False, False])):
        for code in tasks.AVG16:
            if (run, code) != ("read_s2_seed2", "SB"):
                _write(runs, tasks.canonical_name(code), run, "spe_N100_now", outcome)
    for run in ("det_s2", "det_s2_seed1"):
        _write(runs, "reach_target", run, "direct", [True, False], method="deterministic", N=None)
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", READS,
                                      "det_s2,det_s2_seed1"]) == 0
    section = _section(out)
    read_row = next(ln for ln in section.splitlines() if ln.startswith("| READ (N=100): mean of 3 trainings"))
    assert "| Avg12 | Avg16 | Avg (15) |" in section  # SB is not in every READ training
    # SB, Avg12 (100, 50, 0), Avg16 (the third has no SB: 15 task means of 50 and SB's 75, 51.6; the two
    # complete trainings' own averages would give 75), Avg (15) (100, 50, 0)
    assert read_row.endswith("| 75.0 (50-100) n=2‡ | 50.0 (0-100) | 51.6§ | 50.0 (0-100) |")
    assert "Not paired against the other role (no training at the same position in its list): `read_s2_seed2`." \
        in section
    # README's compact table: the same averages over trainings
    readme = readme_tables.main_lines(collect(str(runs)), READS, "det_s2,det_s2_seed1", tasks.SUITE_VERSION)
    assert f"| READ, N = 100 | {tasks.SUITE_VERSION} | 50.0 (0-100)‡ | 51.6§‡ | `read_s2`, " \
           "`read_s2_seed1`, `read_s2_seed2` |" in readme
    assert f"| Deterministic | {tasks.SUITE_VERSION} | – | – | `det_s2`, `det_s2_seed1` |" in readme


def test_a_training_list_naming_a_run_without_results_or_twice_is_refused(tmp_path, capsys):
    runs = tmp_path / "results"
    _three_trainings(runs)
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main",
                                      "read_s2,read_s2_sed1", DETS]) == 2
    assert "no evaluation of run(s) 'read_s2_sed1' qualifies" in capsys.readouterr().err
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_s2,read_s2", DETS]) == 2
    assert "a run named twice" in capsys.readouterr().err
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_s2,", DETS]) == 2
    assert "an empty run name" in capsys.readouterr().err


def test_the_papers_recipe_is_a_row_of_its_own_paired_against_read(tmp_path):
    """--paper-recipe: the run's N = 100 evaluation refined with its own config (here cold x 1) fills the
    row; one refined with a choice, or with another setting, does not; READ is paired against it."""
    runs = tmp_path / "results"
    T, F = True, False
    _write(runs, "reach_target", "read_s2", "spe_N100_now", [T] * 9 + [F])
    _write(runs, "reach_target", "read_s2", "spe_N0", [F] * 10, N=0)
    _write(runs, "reach_target", "det_s2", "direct", [F] * 10, method="deterministic", N=None)
    _write(runs, "reach_target", "read_paper", "b_own", [T] * 5 + [F] * 5, refine_update="cold", rounds=1)
    _write(runs, "reach_target", "read_paper", "a_chosen", [T] * 10, refine_update="cold", rounds=1)
    _edit(runs, "reach_target", "read_paper", "a_chosen", chosen_on="val", choice={"chosen": {}})
    _write(runs, "reach_target", "read_paper", "c_preset", [F] * 10)  # the cpu preset's refinement: not its own
    out = tmp_path / "results.md"
    args = ["--runs", str(runs), "--out", str(out), "--main", "read_s2", "det_s2"]
    assert _cli.run(report_cli.main, [*args, "--paper-recipe", "read_paper"]) == 0
    section = _section(out)
    assert "| READ, the paper's recipe (N=100): `read_paper` | – | 50.0‡ |" in section
    assert "| READ (N=100): `read_s2` | – | 90.0‡ |" in section
    assert "| READ N=100 vs Deterministic | READ N=100 vs the paper's recipe |" in section
    assert "| RT | +9 / -0, p=0.0039, 1 pair | +9 / -0, p=0.0039, 1 pair | +4 / -0, p=0.12, 1 pair |" in section
    assert _cli.run(report_cli.main, [*args, "--paper-recipe", "nope"]) == 2  # a run with no such evaluation
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--paper-recipe", "read_paper"]) == 2


def test_a_grid_still_running_lists_the_trainings_not_measured_yet(tmp_path):
    """The pages' current-suite table (grid_plan.GRID) while the grid runs: the trainings measured so far
    fill the means with n=k, the rest are named as not measured yet, positions still pair READ's i-th with
    Deterministic's i-th, and the README's compact rows say how many tasks are in."""
    from readjax.lab import main_table, main_table_seeds
    runs = tmp_path / "results"
    T, F = True, False
    _write(runs, "reach_target", "read_s2", "spe_N100_now", [T] * 9 + [F])
    _write(runs, "reach_target", "read_s2", "spe_N0", [F] * 10, N=0)
    _write(runs, "reach_target", "det_s2_seed1", "direct", [F] * 10, method="deterministic", N=None)
    results = collect(runs)
    reads, dets = ["read_s2", "read_s2_seed1"], ["det_s2", "det_s2_seed1"]
    args = (results, reads, dets, None, "cpu", main_table.refinement_of("cpu"), tasks.SUITE_VERSION, ["read_paper"])
    try:
        main_table_seeds.lines(*args)
        raise AssertionError("a finished table refuses trainings with no evaluation")
    except ValueError as e:
        assert "read_s2_seed1" in str(e)
    text = "\n".join(main_table_seeds.lines(*args, in_progress=True))
    cols = list(tasks.AVG16) + ["Avg12", "Avg16", "Avg (1)"]
    assert _row("READ (N=100): mean of 2 trainings", {"RT": "90.0 n=1‡", "Avg (1)": "90.0 n=1"}, cols) in text
    assert _row("Deterministic: mean of 2 trainings", {"RT": "0.0 n=1‡", "Avg (1)": "0.0 n=1"}, cols) in text
    assert "Still running: no evaluation of `read_s2_seed1`, `det_s2`, `read_paper` yet" in text
    assert "| RT | +9 / -0, p=0.0039, 1 pair | – | – |" in text  # read_s2 has no det_s2 to pair with
    grid = {"read": tuple(reads), "deterministic": tuple(dets), "recipe": ("read_paper",)}
    block = "\n".join(readme_tables.grid_lines(results, grid, tasks.SUITE_VERSION))
    assert f"| READ, N = 100 | {tasks.SUITE_VERSION} | – | – | `read_s2`, `read_s2_seed1` |" in block
    assert "| success % (1 tasks, 10 test episodes each) |" in block
    assert "Still running: 1 of 16 tasks have a READ training measured at N = 100, no evaluation yet of `read_s2_seed1`, " \
           "`det_s2`, `read_paper`" in block
    assert readme_tables.grid_lines(results, {**grid, "read": ("other",)}, tasks.SUITE_VERSION) == []


def test_the_readme_shows_the_old_suite_until_the_grid_has_every_task_and_says_how_it_was_tuned(tmp_path):
    """The older suite's rows (READ refined with a setting chosen on test episodes) are said to be so,
    and leave the README once a READ training of the current suite's grid has all 16 tasks."""
    runs = tmp_path / "results"
    T, F = True, False
    for run, name, method, n in (("read_v3", "spe_N100_now", "read", 100), ("read_v3", "spe_N0", "read", 0),
                                 ("det_v3", "direct", "deterministic", None)):
        _write(runs, "reach_target", run, name, [T] * 6 + [F] * 4, method=method, N=n)
        _edit(runs, "reach_target", run, name, suite=tasks.SUITE_VERSION - 1)
    chosen = {"chosen_on": "val", "choice": {"file": "c.json", "chosen": {"refine": "renoise", "rounds": 1}}}
    grid = {"read": ("read_s2",), "deterministic": ("det_s2",), "recipe": ()}
    codes = list(tasks.AVG16)
    for code in codes[:-1]:
        _write(runs, tasks.canonical_name(code), "read_s2", "spe_N100", [T] * 9 + [F], refine_update="renoise",
               rounds=1)
        _edit(runs, tasks.canonical_name(code), "read_s2", "spe_N100", **chosen)
    for task in tasks.names():
        verification.write(runs, {"task": task, "split": "test", "dataset_fingerprint": f"fp-{task}",
                                  "episodes": 10, "success_rate": 1.0})
    readme = tmp_path / "README.md"
    readme.write_text(f"{readme_tables.MAIN_BLOCK}\n{readme_tables.END}\n{readme_tables.BASELINES_BLOCK}\n"
                      f"{readme_tables.END}\n")

    def main_block():
        text = readme_tables.readme(readme, str(runs), ("read_v3", "det_v3"), {"read": "read_v3"},
                                    tasks.SUITE_VERSION - 1, grid, tasks.SUITE_VERSION)
        main, baselines = text.split(readme_tables.BASELINES_BLOCK)
        assert "READ, N = 100 (`read_v3`) |" not in baselines  # its refinement was chosen on test episodes
        assert "READ, N = 100 (`read_v3`): in docs/baselines.md only" in baselines
        return main

    block = main_block()
    assert "| READ, N = 100 | 2 | 90.0 | – | `read_s2` |" in block and "15 of 16 tasks" in block  # SB missing
    assert "| READ, N = 100 | 1 | – | – | `read_v3` |" in block
    assert block.count("was chosen by comparing success on reach_target's test episodes") == 1  # suite 1's rows only
    _write(runs, tasks.canonical_name(codes[-1]), "read_s2", "spe_N100", [T] * 10, refine_update="renoise", rounds=1)
    _edit(runs, tasks.canonical_name(codes[-1]), "read_s2", "spe_N100", **chosen)
    assert readme_tables.grid_has_all_tasks(collect(runs), grid, tasks.SUITE_VERSION)
    block = main_block()
    assert "| READ, N = 100 | 2 | 90.0 | 90.6 | `read_s2` |" in block
    assert "`read_v3`" not in block and "test episodes (BENCHMARKS" not in block
