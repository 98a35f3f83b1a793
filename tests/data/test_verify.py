"""The evaluation path measures what it says: stored scenes, the scene guard, the ground-truth replay
(`experiments.verify`) and the refusal of format-1 datasets."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

from experiments import _cli
from experiments import verify as verify_cli
from readjax import tasks
from readjax.data import store
from readjax.data.generate import GenerateConfig, generate
from readjax.data.guard import SceneMismatchError, check_scene_images, scene_image_errors

pytestmark = pytest.mark.timeout(900)

TASK = "reach_target"


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A test split of 9 episodes generated in batches of 4: three generation batches."""
    root = tmp_path_factory.mktemp("verify")
    generate(GenerateConfig(task=TASK, split="test", episodes=9, out=str(root), batch_size=4, image_size=32),
             progress=False)
    return root


def test_stored_scenes_are_the_sampled_ones(data):
    ds = store.load_dataset(store.split_dir(data, TASK, "test"))
    env = tasks.make(TASK)
    assert np.asarray(ds.scenes.qpos).shape[0] == len(ds) == 9
    for i in (0, 4, 8):  # one episode of each generation batch
        again = env.sample_scene(jax.random.key(int(ds.seeds[i])))
        for a, b in zip(jax.tree.leaves(again), jax.tree.leaves(store.take_scenes(ds.scenes, i))):
            np.testing.assert_array_equal(np.asarray(a), b)


def test_ground_truth_replays_at_100_percent_across_generation_batches(data, capsys, tmp_path):
    out = tmp_path / "verify.json"
    rc = _cli.run(verify_cli.main, ["--task", "RT", "--data", str(data), "--out", str(out)])
    assert rc == 0, capsys.readouterr()
    result = json.loads(out.read_text())
    assert result["episodes"] == 9 and result["success"] == [1] * 9 and result["success_rate"] == 1.0
    assert "9/9 = 100.0 %" in capsys.readouterr().out


def test_guard_passes_and_fires_on_swapped_scenes(data):
    env = tasks.make(TASK)
    ds = store.load_dataset(store.split_dir(data, TASK, "test"))
    rgb_err, depth_err = scene_image_errors(env, ds)
    assert rgb_err.max() <= 2 / 255 and depth_err.max() <= 2 / 255
    check_scene_images(env, ds)
    swapped = ds.subset(np.arange(len(ds)))
    swapped.scenes = store.take_scenes(ds.scenes, [1, 0] + list(range(2, len(ds))))
    with pytest.raises(SceneMismatchError, match=r"2 of 9 stored scenes .*#0 \(seed 1000000.*#1 \(seed 1000001"):
        check_scene_images(env, swapped)
    # evaluated at the planner's resolution, the guard compares the shrunken images
    check_scene_images(env, ds.resized(16))


def test_verify_fails_below_min_and_names_the_failed_seeds(data, capsys, tmp_path):
    """A ground truth that does not succeed makes verify exit 1 (here: motions scrambled)."""
    split = store.split_dir(data, TASK, "test")
    broken = tmp_path / TASK / "test"
    broken.mkdir(parents=True)
    for f in split.iterdir():
        if f.name != "verify.json":
            (broken / f.name).write_bytes(f.read_bytes())
    import h5py

    with h5py.File(broken / "shard_00000.h5", "r+") as f:
        f["motion"][...] = np.asarray(f["motion"])[::-1]  # episodes 0-3 get another episode's motion
    rc = _cli.run(verify_cli.main, ["--task", TASK, "--data", str(tmp_path), "--min", "100"])
    assert rc == 1
    assert "FAIL" in capsys.readouterr().err


def test_a_wide_grasp_replays_as_closed(tmp_path):
    """put_rubbish's ball keeps the closed fingers 65 % open: a motion records the gripper command
    (1 open, 0 closed), not that opening, or the protocol (open if grip > 0.5) never grasps it.
    Format 2 recorded the opening and replayed 0 of 100 test episodes."""
    generate(GenerateConfig(task="put_rubbish", split="test", episodes=4, out=str(tmp_path), batch_size=4,
                            image_size=32), progress=False)
    ds = store.load_dataset(store.split_dir(tmp_path, "put_rubbish", "test"))
    assert set(np.unique(ds.motion[..., 9]).round(6)) >= {0.0, 1.0}
    from readjax.evaluation import replay_ground_truth

    assert replay_ground_truth(tasks.make("put_rubbish"), ds)["success"] == [1, 1, 1, 1]


def test_format_1_dataset_is_refused_in_one_line(data, tmp_path, capsys):
    old = tmp_path / TASK / "test"
    old.mkdir(parents=True)
    meta = json.loads((store.split_dir(data, TASK, "test") / "meta.json").read_text())
    store.write_meta(old, dict(meta, format_version=1))
    with pytest.raises(store.DatasetError, match="format-1 dataset.*regenerate: python -m experiments.generate"):
        store.load_dataset(old)
    assert _cli.run(verify_cli.main, ["--task", TASK, "--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--task reach_target --split test" in err
    # generation refuses to extend it too, and leaves it as it was
    assert _cli.run(__import__("experiments.generate").generate.main,
                    ["--task", TASK, "--split", "test", "--episodes", "2", "--image-size", "32",
                     "--out", str(tmp_path), "--quiet"]) == 2
    assert "format-1" in capsys.readouterr().err
    assert json.loads((old / "meta.json").read_text())["format_version"] == 1
    store.write_meta(old, dict(meta, format_version=2))
    with pytest.raises(store.DatasetError, match="format-2 dataset: its motions record the measured gripper"):
        store.load_dataset(old)


def test_replay_record_is_kept_per_version_of_the_split(data, capsys, tmp_path):
    """--results keeps the record under the split's content hash, the hash an evaluation of the same
    episodes records and the pipeline computes; another version of the split is not verified by it."""
    from readjax.lab import pipeline, verification

    split = store.split_dir(data, TASK, "test")
    rc = _cli.run(verify_cli.main, ["--task", TASK, "--data", str(data), "--episodes", "8", "--out",
                                    str(tmp_path / "v.json"), "--results", str(tmp_path / "results")])
    assert rc == 0, capsys.readouterr()
    fp = store.load_dataset(split, limit=8).fingerprint
    assert pipeline.split_fingerprint(split, 8) == fp != pipeline.split_fingerprint(split, 9)
    assert pipeline.split_fingerprint(split, 10) is None  # the split holds 9
    record = json.loads(verification.record_path(tmp_path / "results", TASK, fp).read_text())
    assert record["dataset_fingerprint"] == fp and record["episodes"] == 8
    assert verification.is_verified(tmp_path / "results", TASK, fp, 8)
    assert not verification.is_verified(tmp_path / "results", TASK, fp, 9)
    assert not verification.is_verified(tmp_path / "results", TASK, pipeline.split_fingerprint(split, 9), 9)
    assert verification.evaluation_verified(tmp_path / "results", {"task": TASK, "test_fingerprint": fp, "episodes": 8})


def test_tolerance_replays_the_ground_truth_with_a_known_error(data, capsys, tmp_path):
    """No error: the plain replay, 100 %; every waypoint 30 cm off: the reach misses its sphere."""
    from experiments import tolerance as tolerance_cli

    out = tmp_path / "tol.json"
    argv = ["--task", TASK, "--data", str(data), "--shift-cm", "30", "--turn-deg", "45", "--out", str(out), "--quiet"]
    assert _cli.run(tolerance_cli.main, argv) == 0, capsys.readouterr()
    r = json.loads(out.read_text())
    assert list(r["shift_cm"]) == ["0", "30"] and list(r["turn_deg"]) == ["0", "45"]
    assert r["shift_cm"]["0"]["success"] == [1] * 9 and r["shift_cm"]["30"]["success_rate"] < 0.5
    assert r["dataset_fingerprint"] == store.load_dataset(store.split_dir(data, TASK, "test")).fingerprint
    assert out.with_suffix(".png").exists() and "| shift (cm) | 0 | 30 |" in capsys.readouterr().out
    assert _cli.run(tolerance_cli.main, argv[:4] + ["--shift-cm", "-1"]) == 2
