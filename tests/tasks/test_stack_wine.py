"""SW: slot-region truth table (target slot, other slots, upright, shifted), layout, expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.tasks.stack_wine import CENTRE, RACK_GAP, SLOT
from tests.tasks.helpers import expert_run, grasping, hand_built, judge

# a lying bottle as the expert leaves it: turned 90 degrees about world x, base towards +y
LYING = np.asarray(geo.axis_angle_to_quat(jnp.array([1.0, 0.0, 0.0]), jnp.pi / 2))


@pytest.fixture(scope="module")
def env():
    return tasks.make("stack_wine")


def _bottle_at(env, scene, centre=None, lying=True):
    """State with the bottle's body centre at ``centre`` (rack frame); None: where it was sampled."""
    qpos = np.array(scene.qpos)
    if centre is not None:
        world = np.asarray(scene.params["rack"]) + np.asarray(centre)
        quat = LYING if lying else np.array([1.0, 0, 0, 0])
        rot = np.asarray(geo.quat_to_mat(jnp.asarray(quat)))
        qpos[env.bottle_qadr:env.bottle_qadr + 3] = world - rot @ np.array([0.0, 0.0, CENTRE])
        qpos[env.bottle_qadr + 3:env.bottle_qadr + 7] = quat
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


@pytest.mark.parametrize(
    "centre, lying, attached, expected",
    [
        (None, True, None, False),  # standing where it was placed
        (SLOT, True, None, True),  # lying in the target slot
        (SLOT, True, 0, True),  # still held there (RLBench does not require a release)
        (SLOT + [0.0, 0.04, 0.0], True, None, True),  # a bit along the slot
        (SLOT + [0.0, 0.08, 0.0], True, None, False),  # too far along the slot
        (SLOT + [0.1, 0.0, 0.0], True, None, False),  # lying in the middle slot
        (SLOT + [0.2, 0.0, 0.0], True, None, False),  # lying in the far slot
        (SLOT + [0.0, 0.0, 0.06], True, 0, False),  # held above the slot
        ((SLOT[0], SLOT[1], CENTRE), False, None, False),  # standing upright on the slot
    ],
)
def test_truth_table(env, centre, lying, attached, expected):
    scene = env.sample_scene(jax.random.key(6))
    centre = None if centre is None else np.asarray(centre, np.float32)
    ok, fail, _ = judge(env, scene, _bottle_at(env, scene, centre, lying), grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_centre_site_is_the_body_middle(env):
    scene = env.sample_scene(jax.random.key(1))
    data = _bottle_at(env, scene)
    b = np.asarray(scene.params["bottle"])
    assert np.allclose(np.asarray(data.site_xpos[env.centre_site]), b + [0, 0, CENTRE], atol=1e-5)


def test_layout(env):
    for seed in range(40):
        s = env.sample_scene(jax.random.key(seed))
        b, rack = np.asarray(s.params["bottle"]), np.asarray(s.mocap_pos[env.rack_mocap])
        assert rack[1] - b[1] >= RACK_GAP - 1e-6
        assert 0.36 <= b[0] <= 0.62 and b[1] >= -0.3 - 1e-6


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("stack_wine")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # the bottle was let go
