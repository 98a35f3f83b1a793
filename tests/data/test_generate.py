"""Demo generation: determinism, resume after interruption, and clear errors for bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from experiments import _cli
from experiments import generate as generate_cli
from readjax.data import store
from readjax.tasks import SUITE_VERSION
from readjax.data.generate import GenerateConfig, generate

pytestmark = pytest.mark.timeout(600)

SMALL = dict(task="reach_target", batch_size=4, image_size=32)


def _gen(out, episodes, **kw):
    return generate(GenerateConfig(out=str(out), episodes=episodes, **SMALL), progress=False, **kw)


def test_same_seeds_same_bits_and_resume(tmp_path):
    a = tmp_path / "a"
    b = tmp_path / "b"
    summary = _gen(a, 6)
    assert summary["episodes_kept"] == 6 and summary["episodes_attempted"] >= 6
    assert 0.95 <= summary["expert_success_rate"] <= 1.0
    for key in ("episodes_kept", "episodes_attempted", "expert_success_rate", "seconds", "versions"):
        assert key in json.loads((a / "reach_target" / "train" / "summary.json").read_text())

    # interrupted after one batch, then resumed: same demos, no duplicates, none lost
    partial = _gen(b, 6, stop_after_batches=1)
    assert partial["interrupted"] and partial["episodes_kept"] == 4
    (b / "reach_target" / "train" / "shard_00009.h5.tmp").write_bytes(b"half-written")  # a crash leftover
    _gen(b, 6)
    da = store.load_dataset(a / "reach_target" / "train")
    db = store.load_dataset(b / "reach_target" / "train")
    assert len(db) == 6 and len(set(db.seeds.tolist())) == 6
    np.testing.assert_array_equal(da.seeds, db.seeds)
    np.testing.assert_array_equal(da.rgbd, db.rgbd)  # same seed -> identical image, bit for bit
    np.testing.assert_array_equal(da.motion, db.motion)  # ... and identical motion
    np.testing.assert_array_equal(da.joints, db.joints)
    assert not list((b / "reach_target" / "train").glob("*.tmp"))

    # a no-op re-run keeps the summary (its wall time is summed, not reset)
    before = json.loads((a / "reach_target" / "train" / "summary.json").read_text())["seconds"]
    again = _gen(a, 6)
    assert again["episodes_kept"] == 6 and again["seconds"] >= before > 0

    # asking for more extends the dataset with new seeds only
    _gen(b, 9)
    dc = store.load_dataset(b / "reach_target" / "train")
    assert len(dc) == 9 and np.all(dc.seeds[:6] == da.seeds)


def test_dataset_contents(tmp_path):
    _gen(tmp_path, 4)
    ds = store.load_dataset(tmp_path / "reach_target" / "train")
    assert ds.rgbd.shape == (4, 32, 32, 4) and ds.motion.shape == (4, 101, 10) and ds.joints.shape == (4, 101, 7)
    assert ds.rgbd.min() >= 0 and ds.rgbd.max() <= 1
    assert np.all(ds.seeds < 1_000_000)
    # motion starts at the home pose, open gripper; uv inside the image
    assert np.all(ds.motion[:, 0, 9] == 1.0)
    assert np.all(np.abs(ds.motion[..., :2]) < 1.0)
    assert ds.camera.width == 32
    assert len(ds.fingerprint) == 16 and ds.fingerprint == store.load_dataset(
        tmp_path / "reach_target" / "train").fingerprint
    small = ds.resized(16)
    assert small.rgbd.shape == (4, 16, 16, 4) and small.camera.width == 16


def test_test_split_seeds_are_disjoint(tmp_path):
    generate(GenerateConfig(out=str(tmp_path), episodes=4, split="test", **SMALL), progress=False)
    ds = store.load_dataset(tmp_path / "reach_target" / "test")
    assert np.all(ds.seeds >= 1_000_000)


def test_cli_errors(tmp_path, capsys):
    assert _cli.run(generate_cli.main, ["--task", "reach_targte", "--out", str(tmp_path)]) == 2
    assert "unknown task 'reach_targte'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        generate_cli.main(["--task", "RT", "--episodes", "0", "--out", str(tmp_path)])
    assert e.value.code == 2 and "positive integer" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        generate_cli.main(["--task", "RT", "--episodes", "many", "--out", str(tmp_path)])
    assert "positive integer" in capsys.readouterr().err
    # an existing dataset of another task in the output folder is not touched
    path = tmp_path / "reach_target" / "train"
    store.write_meta(path, {"task": "push_button", "split": "train", "image_size": 32, "camera_name": "front",
                            "format_version": store.FORMAT_VERSION, "suite": SUITE_VERSION})
    before = (path / "meta.json").read_text()
    assert _cli.run(generate_cli.main, ["--task", "RT", "--episodes", "2", "--batch-size", "2",
                                        "--image-size", "32", "--out", str(tmp_path), "--quiet"]) == 2
    assert "task='push_button'" in capsys.readouterr().err
    assert (path / "meta.json").read_text() == before


def test_missing_and_corrupted_datasets(tmp_path):
    with pytest.raises(store.DatasetError, match="meta.json missing"):
        store.load_dataset(tmp_path / "nothing")
    _gen(tmp_path, 4)
    shard = tmp_path / "reach_target" / "train" / "shard_00000.h5"
    shard.write_bytes(shard.read_bytes()[:200])
    with pytest.raises(store.DatasetError, match="unreadable"):
        store.load_dataset(tmp_path / "reach_target" / "train")
