"""The oracle rows (experiments.difficulty) and the suite version of a dataset: a split's nearest
demonstration to itself is its own ground truth, a split without a 100 % replay is not measured, and
a split of another suite is refused."""

from __future__ import annotations

import json
import shutil

import pytest

from experiments import _cli
from experiments import difficulty as difficulty_cli
from readjax import tasks
from readjax.data import store
from readjax.data.generate import GenerateConfig, generate
from readjax.lab import difficulty, difficulty_why, verification
from readjax.sim.execute import execution_record

pytestmark = pytest.mark.timeout(900)

TASK = "reach_target"


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A 6-episode test split, and a root whose training split is that same split."""
    root = tmp_path_factory.mktemp("difficulty")
    generate(GenerateConfig(task=TASK, split="test", episodes=6, out=str(root / "data"), batch_size=2,
                            image_size=32), progress=False)
    mirror = root / "mirror" / TASK
    mirror.mkdir(parents=True)
    shutil.copytree(root / "data" / TASK / "test", mirror / "test")
    shutil.copytree(root / "data" / TASK / "test", mirror / "train")
    meta = json.loads((mirror / "train" / "meta.json").read_text())
    (mirror / "train" / "meta.json").write_text(json.dumps(dict(meta, split="train")))
    return root


def test_a_split_against_itself_replays_its_own_ground_truth(data, tmp_path, capsys):
    results = tmp_path / "results"
    args = ["--task", "RT", "--data", str(data / "mirror"), "--results", str(results), "--train-episodes", "6",
            "--episodes", "6", "--ranks", "1", "2", "--image-size", "32", "--batch-size", "2"]
    assert _cli.run(difficulty_cli.main, args) == 0
    out = capsys.readouterr().out
    records = difficulty.load_records(results)
    r = records[TASK]
    test = store.load_dataset(store.split_dir(data / "mirror", TASK, "test"))
    assert r["test_fingerprint"] == test.fingerprint and r["suite"] == tasks.SUITE_VERSION
    # the nearest demonstration of each episode is its own (same seed), executed at 100 %
    assert r["ranks"]["1"]["neighbour_seeds"] == r["seeds"] and r["ranks"]["1"]["success_rate"] == 1.0
    assert all(a != b for a, b in zip(r["ranks"]["2"]["neighbour_seeds"], r["seeds"]))
    assert r["replay_verified"] and r["paper_cheat"] == {"1": 96}  # RT's Cheat (i = 1) in Table 5
    assert r["generation"]["test"]["episodes_kept"] == 6
    assert (results / TASK / "difficulty" / f"{test.fingerprint}.json").exists()
    # the why: the own copies land on their key frames (0 cm, no failure), all in the first bin
    first = r["ranks"]["1"]["failures"]
    assert max(first["keyframe_error_cm"]) < 1e-3 and first["counts"] == {} and first["mode"] == [None] * 6
    assert len(r["ranks"]["2"]["failures"]["keyframe_error_cm"]) == 6
    profile = difficulty_why.tolerance_profile(r)
    assert sum(n for _, n in profile) == 12  # both ranks' copies, each in one bin
    assert profile[0][0] >= 6 and profile[0][1] >= 6  # the six own copies: below 1 cm, succeeded
    assert r["execution"]["expert_rate_posture"] is True and r["created"].startswith("20")
    assert "| RT | +4 | 0.0 cm, 0° |" in difficulty_why.table(records)
    assert "| RT | 100 | " in out  # the table, beside the paper's row
    # a second call measures nothing: the record of this split exists
    assert _cli.run(difficulty_cli.main, args) == 0
    assert "record exists" in capsys.readouterr().out


def test_the_newest_record_of_a_task_is_its_created_time_not_its_file_time(tmp_path):
    """A task measured again (its split regenerated) has two records; a fresh clone gives both the same
    file time, so the newest is told by ``created`` (a record without one, written before it existed, is
    the older)."""
    import os
    folder = tmp_path / TASK / difficulty.FOLDER
    folder.mkdir(parents=True)
    rec = {"task": TASK, "code": "RT", "suite": tasks.SUITE_VERSION}
    (folder / "ffff.json").write_text(json.dumps(dict(rec, test_fingerprint="old")))
    (folder / "0000.json").write_text(json.dumps(dict(rec, test_fingerprint="new", created="2026-12-07T09:00:00+00:00")))
    (folder / "1111.json").write_text(json.dumps(dict(rec, test_fingerprint="older", created="2026-12-01T09:00:00+00:00")))
    for name, t in (("0000.json", 1), ("1111.json", 3), ("ffff.json", 2)):  # file times say otherwise
        os.utime(folder / name, (t, t))
    assert difficulty.load_records(tmp_path)[TASK]["test_fingerprint"] == "new"


def test_no_measurement_without_a_full_replay_on_record(data, tmp_path):
    with pytest.raises(store.DatasetError, match="no 100 % ground-truth replay"):
        difficulty.measure(TASK, data / "mirror", tmp_path / "empty_results", ranks=(1,), episodes=6)
    test = store.load_dataset(store.split_dir(data / "mirror", TASK, "test"))
    verification.write(tmp_path / "bad", {"task": TASK, "split": "test", "dataset_fingerprint": test.fingerprint,
                                          "episodes": 6, "success_rate": 5 / 6})
    with pytest.raises(store.DatasetError, match="no 100 % ground-truth replay"):
        difficulty.measure(TASK, data / "mirror", tmp_path / "bad", ranks=(1,), episodes=6)


def test_unverified_measures_a_split_replayed_below_100_percent_and_marks_it(data, tmp_path, capsys):
    test = store.load_dataset(store.split_dir(data / "mirror", TASK, "test"))
    bad = {"task": TASK, "split": "test", "dataset_fingerprint": test.fingerprint, "episodes": 6,
           "success_rate": 5 / 6, "execution": execution_record()}
    verification.write(tmp_path / "bad", bad)
    # no --image-size: the splits on disk (32 px) are measured as they are, not regenerated at another size
    assert store.existing_image_size(data / "mirror", TASK) == 32
    assert store.existing_image_size(tmp_path / "nothing", TASK) is None
    args = ["--task", "RT", "--data", str(data / "mirror"), "--results", str(tmp_path / "bad"), "--train-episodes",
            "6", "--episodes", "6", "--ranks", "1", "--batch-size", "2"]
    # the replay on record (5 / 6, by this execution path) is not run again: the row is measured, marked
    assert _cli.run(difficulty_cli.main, [*args, "--unverified"]) == 0
    assert verification.find(tmp_path / "bad", TASK, test.fingerprint)["success_rate"] == 5 / 6
    r = difficulty.load_records(tmp_path / "bad")[TASK]
    assert not r["replay_verified"] and "| RT ‡ | 100 |" in capsys.readouterr().out


def test_a_split_of_another_suite_is_refused_with_the_command_that_regenerates_it(data, tmp_path):
    old = tmp_path / "old" / TASK / "test"
    shutil.copytree(data / "data" / TASK / "test", old)
    meta = json.loads((old / "meta.json").read_text())
    meta.pop("suite")  # written before suite versions: suite 1
    (old / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(store.DatasetError, match=r"suite 1 of the tasks .* this readjax's tasks are suite "
                                                 rf"{tasks.SUITE_VERSION} .*python -m experiments.generate"):
        store.load_dataset(old)
    with pytest.raises(store.DatasetError, match="suite 1"):  # nor is it extended
        generate(GenerateConfig(task=TASK, split="test", episodes=8, out=str(tmp_path / "old"), batch_size=2,
                                image_size=32), progress=False)


def test_the_comparability_line_sets_the_oracle_averages_beside_the_papers():
    from readjax.lab import paper
    records = {tasks.canonical_name(c): {"code": c, "ranks": {"1": {"success_rate": paper.CHEAT[1][c] / 100}}}
               for c in tasks.AVG16}
    assert difficulty.comparability_line({k: v for k, v in list(records.items())[:-1]}) == ""  # not all 16 yet
    records["reach_target"]["ranks"]["1"]["success_rate"] = 0.5  # the paper's 96: 46 points harder
    records["stack_blocks"]["ranks"]["1"]["success_rate"] = 0.17  # the paper's 1: 16 points easier
    line = difficulty.comparability_line(records)
    ours = difficulty.oracle_rates(records)
    assert ours["Avg16"] == pytest.approx((sum(paper.CHEAT[1].values()) - 46 + 16) / 16)
    assert f"solves {ours['Avg12']:.1f} / {ours['Avg16']:.1f} % (Avg12 / Avg16) here, 79.5 / 60.6 % in the paper" in line
    assert line.endswith("more than 15 points easier here: SB +16; harder: RT -46.")
