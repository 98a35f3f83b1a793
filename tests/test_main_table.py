"""The paper's main table (experiments.report --main): which evaluation fills each cell, the
averages, the paper's row beside ours, and the paired tests."""

import json

import pytest

from experiments import _cli
from experiments import report as report_cli
from readjax import tasks
from readjax.lab import paper, verification
from readjax.config import preset
from readjax.tables import suite_note


def test_paper_row_reproduces_its_printed_averages():
    assert list(paper.READ_TABLE7_A) == list(tasks.AVG16)
    for name, codes in (("Avg12", tasks.AVG12), ("Avg16", tasks.AVG16)):
        assert paper.mean_over(paper.READ_TABLE7_A, codes) == pytest.approx(paper.READ_TABLE7_A_AVERAGES[name], abs=0.05)
    with pytest.raises(KeyError, match="no rate for RT"):
        paper.mean_over({"PC": 1.0}, ["PC", "RT"])


def _write(root, task, run, name, success, method="read", **eval_config):
    d = root / task / run / "eval"
    d.mkdir(parents=True, exist_ok=True)
    sde = preset("cpu")["sde"]
    cfg = {"N": 100, "retrieval": "spe", "rank": 1, "candidates": 1, "image_noise": 0.0, "brightness": 1.0,
           "rounds": sde.rounds, "refine_update": sde.update, **eval_config}
    (d / f"{name}.json").write_text(json.dumps({
        "task": task, "method": method, "name": name, "success_rate": sum(success) / len(success),
        "episodes": len(success), "test_fingerprint": f"fp-{task}", "suite": tasks.SUITE_VERSION,
        "seeds": list(range(len(success))), "success": success, "eval_config": cfg,
        "configs": {"sde": {"update": "cold", "rounds": 1}}}))  # trained under an older preset


def test_main_table_picks_the_preset_refinement_and_pairs_rows(tmp_path, capsys):
    runs = tmp_path / "results"
    ten = [True] * 10
    _write(runs, "reach_target", "read_a", "spe_N100_now", [True] * 9 + [False])
    _write(runs, "reach_target", "read_a", "spe_N100_cold", [False] * 10, refine_update="cold", rounds=1)
    _write(runs, "reach_target", "read_a", "spe_N100_top3", [False] * 10, candidates=3)
    _write(runs, "reach_target", "read_a", "spe_N100_noise", [False] * 10, image_noise=0.1)
    _write(runs, "reach_target", "read_a", "spe_N0", [True] * 3 + [False] * 7, N=0)
    _write(runs, "reach_target", "read_b", "spe_N100_now", [False] * 10)  # another run: not in the table
    _write(runs, "reach_target", "det_a", "direct", [False] * 2 + [True] * 5 + [False] * 3, method="deterministic",
           N=None)
    _write(runs, "push_button", "read_a", "spe_N100_now", ten)
    f = runs / "push_button" / "read_a" / "eval" / "spe_N100_now.json"
    f.write_text(json.dumps(dict(json.loads(f.read_text()), training={
        "vae": {"steps": 3000, "stop": {"reason": "step cap"}}, "read": {"steps": 2250, "stop": {"reason": "converged"}}})))
    # RT's test split replayed at 100 % on record; PB's has no record, so its cell is marked
    verification.write(runs, {"task": "reach_target", "split": "test", "dataset_fingerprint": "fp-reach_target",
                              "episodes": 10, "success_rate": 1.0})
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det_a"]) == 0
    text = out.read_text()
    section = text.split("## Main table")[1].split("## Methods x tasks")[0]
    head = "| method | " + " | ".join(tasks.AVG16) + " | Avg12 | Avg16 | Avg (2) |"
    assert head in section
    assert "| READ (N=100): `read_a` | – | 90.0 | 100.0‡ | – | – |" in section  # the paper's column order
    assert "not a result until it has one: READ (N=100) PB." in section
    assert section.count("| retrieval only (N=0): `read_a` | – | 30.0 | – |") == 1
    assert "| Deterministic: `det_a` | – | 50.0 | – |" in section
    assert "| – | – | 95.0 |" in section  # READ: no Avg12 / Avg16 yet, mean over RT and PB
    paper_row = [line for line in section.splitlines() if line.startswith(f"| {paper.READ_LABEL}")][0]
    assert paper_row.endswith("| 88.8 | 70.2 | 85.5 |")  # the paper over the same two tasks: (99 + 72) / 2
    # RT: episodes 3-8 solved only at N = 100 (p = 2 / 2^6); 0, 1, 7, 8 only by READ against Deterministic
    assert "| RT | +6 / -0, p=0.031 | +4 / -0, p=0.12 |" in section
    assert "| PB | – | – |" in section
    # the goals against the paper's READ follow, drawn from the same cells: READ above Deterministic on RT
    # (+4 / -0; PB has no Deterministic), pending until all 16 tasks are measured
    assert "| READ N = 100 above Deterministic, pooled (paired, p < 0.05) | +4 / -0, p=0.12, 1 pair; 90.0 / 50.0 % " \
           "| pending | 1 of 16 task x training pairs |" in section
    assert "- READ (N=100): `read_a`: read 2250 (converged) x 1; vae 3000 (step cap) x 1; not recorded x 1" in section
    assert out.with_name("results_main.png").exists() and "![main table](results_main.png)" in section
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "nope", "nada"]) == 2
    assert "no evaluation of run 'nope'" in capsys.readouterr().err


def test_a_second_qualifying_evaluation_is_noted_not_mixed(tmp_path):
    runs = tmp_path / "results"
    _write(runs, "reach_target", "read_a", "a_first", [True] * 4)
    _write(runs, "reach_target", "read_a", "b_second", [False] * 4)
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    section = out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]
    assert "| READ (N=100): `read_a` | – | 100.0‡ |" in section  # no replay record under this root
    assert "b_second.json` also qualifies" in section
    verification.write(runs, {"task": "reach_target", "split": "test", "dataset_fingerprint": "fp-reach_target",
                              "episodes": 4, "success_rate": 1.0})
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    section = out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]
    assert "| READ (N=100): `read_a` | – | 100.0 |" in section and "Every cell ran on a test split" in section


def test_the_setting_chosen_on_the_validation_split_fills_reads_cell_before_the_presets(tmp_path):
    runs = tmp_path / "results"
    _write(runs, "reach_target", "read_a", "a_preset", [True] * 4)  # the preset's refinement, first by name
    _write(runs, "reach_target", "read_a", "b_chosen", [True, False, False, False], refine_update="renoise", rounds=1)
    f = runs / "reach_target" / "read_a" / "eval" / "b_chosen.json"
    chosen = {"rounds": 1, "refine": "renoise", "candidates": 1}
    f.write_text(json.dumps(dict(json.loads(f.read_text()), chosen_on="val", choice={"chosen": chosen})))
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    section = out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]
    assert "| READ (N=100): `read_a` | – | 25.0‡ |" in section and "a_preset.json` also qualifies" in section
    # a record claiming a choice it was not refined with fills nothing as chosen: the preset's does
    f.write_text(json.dumps(dict(json.loads(f.read_text()), choice={"chosen": dict(chosen, rounds=2)})))
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    section = out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]
    assert "| READ (N=100): `read_a` | – | 100.0‡ |" in section


def test_reads_rendered_episodes_are_shown_for_the_cell_they_belong_to(tmp_path):
    """A task's overlay and video (the pipeline's media/ beside eval/) appear under the table, linked
    relative to the report, only for the evaluation that fills the READ cell."""
    runs = tmp_path / "results"
    _write(runs, "reach_target", "read_a", "spe_N100_now", [True, False, True])
    _write(runs, "push_button", "read_a", "spe_N100_now", [True] * 3)
    media = runs / "reach_target" / "read_a" / "media"
    media.mkdir()
    (media / "spe_N100_now_overlay.png").write_bytes(b"png")
    (media / "spe_N100_now_rollouts.mp4").write_bytes(b"mp4")
    (media / "other_overlay.png").write_bytes(b"png")  # another evaluation's: not shown
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    section = out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]
    assert "### READ's plans and rollouts per task" in section
    assert ("**RT** (reach_target): the first 3 test episodes, 2 succeeded; "
            "[rollout video](../results/reach_target/read_a/media/spe_N100_now_rollouts.mp4).") in section
    assert "(../results/reach_target/read_a/media/spe_N100_now_overlay.png)" in section
    assert "**PB**" not in section and "other_overlay" not in section


def test_rendered_episodes_are_counted_from_the_media_record(tmp_path):
    """The media JSON published beside the pictures names the episodes they show: the caption counts
    those episodes' outcomes in the cell, however many were rendered (without it: the first 8)."""
    runs = tmp_path / "results"
    outcomes = [False, True, True, False] + [True] * 8
    _write(runs, "reach_target", "read_a", "spe_N100_now", outcomes)
    media = runs / "reach_target" / "read_a" / "media"
    media.mkdir()
    (media / "spe_N100_now_overlay.png").write_bytes(b"png")
    (media / "spe_N100_now.json").write_text(json.dumps({"seeds": [0, 1, 2], "success": [False, True, True]}))
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    assert "**RT** (reach_target): the first 3 test episodes, 2 succeeded." in out.read_text()
    (media / "spe_N100_now.json").unlink()  # media from before the record: the pipeline's first 8
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det"]) == 0
    assert "**RT** (reach_target): the first 8 test episodes, 6 succeeded." in out.read_text()


def test_failures_are_counted_by_mode_per_row(tmp_path):
    runs = tmp_path / "results"
    _write(runs, "reach_target", "read_a", "spe_N100_now", [True, False, False, True])
    _write(runs, "reach_target", "det_a", "direct", [False] * 4, method="deterministic", N=None)
    _write(runs, "push_button", "read_a", "spe_N100_now", [True] * 2)  # predates the record: left out
    for run, name, modes, med, rot, wrong in (
            ("read_a", "spe_N100_now", [None, "depth", "wrong place", None], (4.0, 0.5), [1, 30, 20, 3], 1),
            ("det_a", "direct", ["unreachable", "near miss", "depth", "depth"], (3.25, None), [5] * 4, None)):
        f = runs / "reach_target" / run / "eval" / f"{name}.json"
        counts = {m: modes.count(m) for m in dict.fromkeys(modes) if m}
        record = {"tolerance_cm": 2.0, "tolerance_deg": 10.0, "mode": modes, "counts": counts,
                  "median_keyframe_error_cm": {"failed": med[0], "succeeded": med[1]}, "keyframe_rotation_deg": rot}
        if wrong is not None:
            record["failed_from_a_wrong_start"] = wrong
        f.write_text(json.dumps(dict(json.loads(f.read_text()), failures=record)))
    out = tmp_path / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det_a"]) == 0
    section = out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]
    assert "| task | row | failed | unreachable | gripper sequence | wrong place | depth | image position | " \
           "orientation | missed grasp | task failure | near miss | from a wrong start |" in section
    assert "| RT | READ (N=100): `read_a` | 2 |  |  | 1 | 1 |  |  |  |  |  | 1 | 4.0 / 0.5 | 25.0 / 2.0 |" in section
    assert "| RT | Deterministic: `det_a` | 4 | 1 |  |  | 2 |  |  |  |  | 1 | – | 3.2 / – | 5.0 / – |" in section
    assert "| PB |" not in section.split("Failures by mode")[1].split("How the rows")[0]


def _section(out) -> str:
    return out.read_text().split("## Main table")[1].split("## Methods x tasks")[0]


def test_one_run_per_role_prints_the_one_training_table_as_before(tmp_path):
    """One run name per role: the section is the one-training table, character for character as
    before several trainings per role existed."""
    runs = tmp_path / "results"
    _write(runs, "reach_target", "read_a", "spe_N100_now", [True] * 9 + [False])
    _write(runs, "reach_target", "read_a", "spe_N0", [False] * 3 + [True] * 7, N=0)
    _write(runs, "push_button", "read_a", "spe_N100_now", [True, False, True, True])
    _write(runs, "reach_target", "det_a", "direct", [False] * 2 + [True] * 8, method="deterministic", N=None)
    verification.write(runs, {"task": "reach_target", "split": "test", "dataset_fingerprint": "fp-reach_target",
                              "episodes": 10, "success_rate": 1.0})
    out = tmp_path / "docs" / "results.md"
    assert _cli.run(report_cli.main, ["--runs", str(runs), "--out", str(out), "--main", "read_a", "det_a"]) == 0
    dashes = lambda k: " | –" * k  # noqa: E731
    suite = tasks.SUITE_VERSION
    expected = "\n".join([
        f" (the paper's layout), suite {suite}", "", suite_note(suite), "",
        "READ is run `read_a` on each task at N = 100 with the cpu preset's refinement (`sde.update="
        f"{preset('cpu')['sde'].update}`, `sde.rounds={preset('cpu')['sde'].rounds}`), on clean test images with SPE "
        "top-1 retrieval; retrieval only is the same run at N = 0; Deterministic is run `det_a`. Success % over each "
        "task's test episodes; – = not measured yet. Avg12 / Avg16 appear once all their tasks are measured; `Avg (k)` "
        "is the mean over the k tasks READ has been measured on, the paper's row over the same tasks.", "",
        "| method | " + " | ".join(tasks.AVG16) + " | Avg12 | Avg16 | Avg (2) |", "|---" * 20 + "|",
        "| READ (N=100): `read_a` | – | 90.0 | 75.0‡" + dashes(15) + " | 82.5 |",
        "| retrieval only (N=0): `read_a` | – | 70.0" + dashes(17) + " |",
        "| Deterministic: `det_a` | – | 80.0" + dashes(17) + " |",
        f"| {paper.READ_LABEL} | 96.0 | 99.0 | 72.0 | 88.0 | 100.0 | 98.0 | 97.0 | 57.0 | 91.0 | 86.0 | 82.0 | 100.0 | "
        "16.0 | 36.0 | 4.0 | 1.0 | 88.8 | 70.2 | 85.5 |", "",
        "‡ ran on a test split with no 100 % ground-truth replay on record (`results/<task>/verify/test_<fingerprint>"
        ".json`, written by `experiments.verify --results`): not a result until it has one: READ (N=100) PB.", "",
        "![main table](results_main.png)", "",
        "Paired per task (exact McNemar on the same episodes: episodes only the first row solves / only the second, "
        "two-sided p):", "",
        "| task | READ N=100 vs N=0 | READ N=100 vs Deterministic |", "|---|---|---|",
        "| RT | +3 / -1, p=0.62 | +2 / -1, p=1 |", "| PB | – | – |", "",
        "How the rows' models trained (per stage: steps, why it stopped, on how many tasks):", "",
        "- READ (N=100): `read_a`: not recorded x 2", "- retrieval only (N=0): `read_a`: not recorded x 1",
        "- Deterministic: `det_a`: not recorded x 1", "", ""])
    table, goals = _section(out).split("The goals (issue 52)")
    assert table == expected  # then the goals, drawn from the same cells
    assert "| READ N = 100 above Deterministic, pooled (paired, p < 0.05) | +2 / -1, p=1, 1 pair; 90.0 / 80.0 % |" in goals
