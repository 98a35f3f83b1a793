"""The dataset store on a tiny synthetic split (no simulation): shards written with write_shard read
back by load_dataset as the same data, in seed order; take_scenes, subsets, limits, progress."""

import jax
import numpy as np
import pytest

from readjax.data import store
from readjax.sim.camera import CameraParams
from readjax.sim.env import Scene
from readjax.tasks import SUITE_VERSION

SIZE = 8


def _camera() -> CameraParams:
    k = np.array([[10.0, 0.0, SIZE / 2], [0.0, 10.0, SIZE / 2], [0.0, 0.0, 1.0]])
    return CameraParams(k, np.eye(4), SIZE, SIZE)


def _episodes(seeds, rng) -> dict:
    """One shard's worth of random episodes; depth is stored exactly (multiples of 1/65535)."""
    n = len(seeds)
    return dict(
        rgb=rng.integers(0, 256, (n, SIZE, SIZE, 3), dtype=np.uint8),
        depth01=rng.integers(0, 65536, (n, SIZE, SIZE)) / 65535.0,
        motion=rng.normal(size=(n, 101, 10)).astype(np.float32),
        joints=rng.normal(size=(n, 101, 7)).astype(np.float32),
        seeds=np.asarray(seeds, np.int64),
        raw_frames=rng.integers(100, 200, n).astype(np.int32),
        scenes=Scene(qpos=rng.normal(size=(n, 9)), mocap_pos=rng.normal(size=(n, 2, 3)),
                     mocap_quat=rng.normal(size=(n, 2, 4)), rgba=rng.uniform(size=(n, 3, 4)),
                     params={"target": rng.normal(size=(n, 3)), "choice": rng.integers(0, 4, n)}),
    )


def _write_split(path, shard_seeds, rng) -> list[dict]:
    store.write_meta(path, {"task": "reach_target", "split": "test", "image_size": SIZE,
                            "camera": _camera().to_dict(), "format_version": store.FORMAT_VERSION,
                            "suite": SUITE_VERSION})
    written = []
    for i, seeds in enumerate(shard_seeds):
        ep = _episodes(seeds, rng)
        store.write_shard(path, i, **ep, attempted_seeds=np.asarray(seeds + [100 + i], np.int64),
                          failed_seeds=np.asarray([100 + i], np.int64))
        written.append(ep)
    return written


def _concat(written: list[dict]) -> dict:
    out = {k: np.concatenate([w[k] for w in written]) for k in written[0] if k != "scenes"}
    out["scenes"] = jax.tree.map(lambda *xs: np.concatenate(xs), *[w["scenes"] for w in written])
    return out


def _assert_scenes_equal(a: Scene, b: Scene):
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_round_trip_is_the_identity(tmp_path):
    # seeds out of order within and across shards: loading sorts by seed
    written = _write_split(tmp_path, [[5, 1, 3], [0, 4]], np.random.default_rng(0))
    ds = store.load_dataset(tmp_path)
    full = _concat(written)
    order = np.argsort(full["seeds"], kind="stable")
    np.testing.assert_array_equal(ds.seeds, [0, 1, 3, 4, 5])
    assert (ds.task, ds.split, ds.image_size, len(ds)) == ("reach_target", "test", SIZE, 5)
    assert ds.camera == _camera() and ds.meta["format_version"] == store.FORMAT_VERSION
    assert ds.rgbd.dtype == np.float32 and ds.rgbd.shape == (5, SIZE, SIZE, 4)
    np.testing.assert_array_equal(np.round(ds.rgbd[..., :3] * 255).astype(np.uint8), full["rgb"][order])
    np.testing.assert_array_equal(store.encode_depth(ds.rgbd[..., 3]), store.encode_depth(full["depth01"][order]))
    np.testing.assert_array_equal(ds.motion, full["motion"][order])
    np.testing.assert_array_equal(ds.joints, full["joints"][order])
    _assert_scenes_equal(ds.scenes, store.take_scenes(full["scenes"], order))
    # a second load is the same data (the fingerprint is a content hash)
    assert store.load_dataset(tmp_path).fingerprint == ds.fingerprint


def test_limit_subset_and_progress(tmp_path):
    written = _write_split(tmp_path, [[5, 1, 3], [0, 4]], np.random.default_rng(1))
    first3 = store.load_dataset(tmp_path, limit=3)  # the first shard only, then sorted
    np.testing.assert_array_equal(first3.seeds, [1, 3, 5])
    np.testing.assert_array_equal(first3.motion, written[0]["motion"][[1, 2, 0]])
    with pytest.raises(store.DatasetError, match="fewer than"):
        store.load_dataset(tmp_path, limit=6)
    ds = store.load_dataset(tmp_path)
    sub = ds.subset([4, 0])
    np.testing.assert_array_equal(sub.seeds, [5, 0])
    np.testing.assert_array_equal(sub.rgbd, ds.rgbd[[4, 0]])
    _assert_scenes_equal(sub.scenes, store.take_scenes(ds.scenes, np.array([4, 0])))
    progress = store.read_progress(tmp_path)
    assert (progress.kept, progress.next_shard) == (5, 2)
    np.testing.assert_array_equal(np.sort(progress.attempted), [0, 1, 3, 4, 5, 100, 101])
    np.testing.assert_array_equal(progress.failed, [100, 101])


def test_take_scenes():
    scenes = _episodes([7, 8, 9], np.random.default_rng(2))["scenes"]
    one = store.take_scenes(scenes, 1)
    assert one.qpos.shape == (9,) and one.params["target"].shape == (3,)
    np.testing.assert_array_equal(one.mocap_pos, scenes.mocap_pos[1])
    two = store.take_scenes(scenes, [2, 0])
    np.testing.assert_array_equal(two.params["choice"], scenes.params["choice"][[2, 0]])
    np.testing.assert_array_equal(two.rgba, scenes.rgba[[2, 0]])


def test_write_shard_checks_shapes_and_leaves_no_temporary(tmp_path):
    ep = _episodes([0, 1], np.random.default_rng(3))
    bad = dict(ep, motion=ep["motion"][:, :50])
    with pytest.raises(ValueError, match="shard motion"):
        store.write_shard(tmp_path, 0, **bad, attempted_seeds=np.zeros(0), failed_seeds=np.zeros(0))
    path = store.write_shard(tmp_path, 3, **ep, attempted_seeds=np.arange(2), failed_seeds=np.zeros(0))
    assert path.name == "shard_00003.h5" and store.shards(tmp_path) == [path]
    assert not list(tmp_path.glob("*.tmp")) and store.clean_partial(tmp_path) == 0
