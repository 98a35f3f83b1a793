"""SS: cube in the lifted region above the blade AND spatula grasped; sampling; expert."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.tasks.scoop_with_spatula import BLADE_HALF, CUBE_HALF
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

LIFTED_BLADE = np.array([0.6, -0.1, 0.1])
ON_BLADE = BLADE_HALF[2] + CUBE_HALF + 0.001  # cube centre above the blade centre when resting on it


@pytest.fixture(scope="module")
def env():
    return tasks.make("scoop_with_spatula")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(1))


def state(env, scene, blade, cube_local, yaw=0.0):
    qpos = np.array(scene.qpos)
    quat = np.asarray(geo.yaw_quat(np.float32(yaw)))
    rot = np.asarray(geo.quat_to_mat(quat))
    s, c = env.spatula_qadr, env.cube_qadr
    qpos[s:s + 3], qpos[s + 3:s + 7] = blade, quat
    qpos[c:c + 3], qpos[c + 3:c + 7] = blade + rot @ np.asarray(cube_local), quat
    return hand_built(env, qpos)


@pytest.mark.parametrize(
    "blade, cube_local, yaw, attached, expected",
    [
        (LIFTED_BLADE, (0.0, 0.0, ON_BLADE), 0.0, 0, True),  # scooped and lifted, spatula held
        (LIFTED_BLADE, (0.0, 0.0, ON_BLADE), 0.0, None, False),  # spatula not grasped
        (LIFTED_BLADE, (0.03, -0.02, ON_BLADE), 1.2, 0, True),  # off-centre, turned spatula
        (LIFTED_BLADE, (0.0, 0.06, ON_BLADE), 1.2, 0, False),  # beside the blade
        (LIFTED_BLADE, (0.07, 0.0, ON_BLADE), 0.0, 0, False),  # past the tip
        (LIFTED_BLADE, (0.0, 0.0, 0.09), 0.0, 0, False),  # far above the blade (e.g. thrown)
        (np.array([0.6, -0.1, 0.0015]), (0.0, 0.0, ON_BLADE), 0.0, 0, False),  # on the blade, not lifted
    ],
)
def test_truth_table(env, scene, blade, cube_local, yaw, attached, expected):
    ok, fail, _ = judge(env, scene, state(env, scene, blade, cube_local, yaw), grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_start_state_is_not_success(env, scene):
    ok, fail, _ = judge(env, scene, hand_built(env, np.array(scene.qpos)), grasping(env, 0))
    assert not ok and not fail


def test_scene_sampling(env):
    keys = jax.vmap(jax.random.key)(np.arange(64))
    scenes = jax.vmap(env.sample_scene)(keys)
    sp = np.asarray(scenes.params["spatula"])
    cube = np.asarray(scenes.params["cube"])
    assert np.all(sp[:, 1] - cube[:, 1] > 0.11)  # the spatula lies clear of the cube
    assert np.allclose(cube[:, 2], CUBE_HALF) and np.allclose(sp[:, 2], BLADE_HALF[2])


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("scoop_with_spatula")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] < 0.5)  # still holding the spatula
