"""PU: truth table (tip in the stand, released) and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.tasks.put_umbrella import TIP
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

UPRIGHT = np.asarray(geo.mat_to_quat(jnp.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])))  # handle up, tip down


@pytest.fixture(scope="module")
def env():
    return tasks.make("put_umbrella")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(11))


def umbrella_tip_at(env, scene, tip, quat=UPRIGHT):
    qpos = np.array(scene.qpos)
    a = env.umbrella_qadr
    rot = np.asarray(geo.quat_to_mat(jnp.asarray(quat)))
    qpos[a:a + 3] = np.asarray(tip) - rot @ TIP
    qpos[a + 3:a + 7] = quat
    data = hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)
    np.testing.assert_allclose(np.asarray(env.tip(data)), tip, atol=1e-5)
    return data


@pytest.mark.parametrize(
    "offset, attached, expected",
    [
        ((0.0, 0.0, 0.01), None, True),  # standing in the stand, let go
        ((0.03, -0.03, 0.05), None, True),  # leaning, tip off centre but inside
        ((0.0, 0.0, 0.01), 0, False),  # in the stand but still held
        ((0.0, 0.0, 0.2), None, False),  # above the rim
        ((0.07, 0.0, 0.01), None, False),  # beside the stand
    ],
)
def test_truth_table(env, scene, offset, attached, expected):
    data = umbrella_tip_at(env, scene, np.asarray(scene.params["stand"]) + np.asarray(offset))
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_start_lying_on_the_crate(env):
    for seed in range(8):
        scene = env.sample_scene(jax.random.key(seed))
        data = hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat)
        assert judge(env, scene, data, grasping(env, None))[:2] == (False, False)
        tip = np.asarray(env.tip(data))
        stand = np.asarray(scene.params["stand"])
        # on the crate, away from the stand
        assert tip[2] > 0.1 and np.linalg.norm(tip[:2] - stand[:2]) > 0.15
        crate = np.asarray(scene.mocap_pos[env.crate_mocap])
        assert np.linalg.norm(crate[:2] - stand[:2]) > 0.16  # crate and stand apart


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("put_umbrella")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # let go
