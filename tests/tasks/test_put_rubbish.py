"""PR: truth table (rubbish / tomatoes in the bin), layout constraints and expert success."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import tasks
from readjax.tasks.put_rubbish import BIN_DIST, ITEM_DIST, RUBBISH_R, TOMATO_R
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("put_rubbish")


def _state(env, scene, rubbish=None, tomato0=None):
    """qpos with the rubbish / tomato 0 moved to points given relative to the bin (None: left in place)."""
    qpos = np.array(scene.qpos)
    bin_pos = np.asarray(scene.mocap_pos[env.bin_mocap])
    if rubbish is not None:
        qpos[env.rubbish_qadr:env.rubbish_qadr + 3] = bin_pos + rubbish
    if tomato0 is not None:
        a = int(env.tomato_qadr[0])
        qpos[a:a + 3] = bin_pos + tomato0
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


IN_BIN = (0.0, 0.0, RUBBISH_R)
IN_BIN_CORNER = (0.06, -0.06, 0.1)


@pytest.mark.parametrize(
    "rubbish, tomato0, attached, expected",
    [
        (None, None, None, False),  # start: everything on the table
        (IN_BIN, None, None, True),  # rubbish dropped in
        (IN_BIN_CORNER, None, None, True),  # still falling, inside the walls
        ((0.0, 0.0, 0.2), None, 0, False),  # carried above the bin, not in it
        ((0.12, 0.0, RUBBISH_R), None, None, False),  # next to the bin
        (IN_BIN, (0.04, 0.04, TOMATO_R), None, False),  # a tomato went in too
        (None, (0.0, 0.0, TOMATO_R), None, False),  # only a tomato in the bin
        (IN_BIN, None, 1, True),  # holding a tomato is not a failure in itself
    ],
)
def test_truth_table(env, rubbish, tomato0, attached, expected):
    scene = env.sample_scene(jax.random.key(4))
    data = _state(env, scene, rubbish, tomato0)
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_layout(env):
    seen_rubbish_spot = set()
    for seed in range(40):
        s = env.sample_scene(jax.random.key(seed))
        items = np.stack([np.asarray(s.qpos[a:a + 3]) for a in (env.rubbish_qadr, *env.tomato_qadr)])
        bin_xy = np.asarray(s.mocap_pos[env.bin_mocap, :2])
        d_items = np.linalg.norm(items[:, None, :2] - items[None, :, :2], axis=-1) + np.eye(3)
        assert d_items.min() >= ITEM_DIST - 1e-6
        assert np.linalg.norm(items[:, :2] - bin_xy, axis=-1).min() >= BIN_DIST - 1e-6
        assert np.allclose(items[:, 2], [RUBBISH_R, TOMATO_R, TOMATO_R])
        # the rubbish's rank (by x) among the three items
        seen_rubbish_spot.add(int(np.argsort(np.argsort(items[:, 0]))[0]))
    assert len(seen_rubbish_spot) == 3  # the rubbish is not always the nearest / middle / farthest item


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("put_rubbish")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released: the gripper is open at the end
