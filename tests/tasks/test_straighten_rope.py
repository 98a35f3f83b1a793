"""SR: truth table on straight / S-shaped / shifted ropes, the S layout, expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.tasks.straighten_rope import LINK, N_LINKS, RADIUS, REGION_HALF, SLACK, SPAN
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("straighten_rope")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(8))


def _straight(env, scene, shift=0.0, reverse=False):
    """A straight rope on the axis between the targets (centred), shifted along the axis by ``shift``."""
    qpos = np.array(scene.qpos)
    axis = float(scene.params["axis"]) + (np.pi if reverse else 0.0)
    u = np.array([np.cos(axis), np.sin(axis)])
    h, t = np.asarray(scene.params["head_target"]), np.asarray(scene.params["tail_target"])
    head_mid = 0.5 * (h + t) - 0.5 * SPAN * u + shift * u
    start = head_mid - 0.5 * LINK * u
    qpos[env.rope_qadr:env.rope_qadr + 3] = [start[0], start[1], RADIUS]
    qpos[env.rope_qadr + 3:env.rope_qadr + 7] = np.asarray(geo.yaw_quat(jnp.float32(axis)))
    qpos[env.joint_qadr[:, None] + np.arange(4)] = [1.0, 0, 0, 0]
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


def _judge(env, scene, data):
    return judge(env, scene, data, grasping(env, None))[:2]


def test_start_is_not_solved(env):
    for seed in range(20):
        s = env.sample_scene(jax.random.key(seed))
        data = hand_built(env, np.asarray(s.qpos), s.mocap_pos, s.mocap_quat)
        head, tail = env.ends_in_regions(data)
        assert not bool(head) and not bool(tail)
        # the S's ends lie on the axis, well inside the targets
        u = np.array([np.cos(float(s.params["axis"])), np.sin(float(s.params["axis"]))])
        along = (np.asarray(data.geom_xpos[env.head_geom, :2]) - np.asarray(s.params["head_target"])) @ u
        assert along > REGION_HALF[0] + 0.03


@pytest.mark.parametrize(
    "shift, reverse, expected",
    [
        (0.0, False, True),  # straight, both ends on their patches
        (0.01, False, True),  # within the patches' tolerance
        (-0.01, False, True),
        (0.05, False, False),  # straight but 5 cm off: the head is out
        (-0.05, False, False),  # ... or the tail
        (0.0, True, False),  # straight but head and tail swapped
    ],
)
def test_truth_table(env, scene, shift, reverse, expected):
    assert _judge(env, scene, _straight(env, scene, shift, reverse)) == (expected, False)


def test_one_end_is_not_enough(env, scene):
    """The S as sampled but its head link moved onto the head patch: the tail is still off."""
    data = _straight(env, scene)
    head_only = np.array(scene.qpos)
    h = np.asarray(data.geom_xpos[env.head_geom])
    sampled = hand_built(env, head_only, scene.mocap_pos, scene.mocap_quat)
    off = h - np.asarray(sampled.geom_xpos[env.head_geom])
    head_only[env.rope_qadr:env.rope_qadr + 3] += off  # the whole S translated: head in, tail out
    head, tail = env.ends_in_regions(hand_built(env, head_only, scene.mocap_pos, scene.mocap_quat))
    assert bool(head) and not bool(tail)
    assert _judge(env, scene, hand_built(env, head_only, scene.mocap_pos, scene.mocap_quat)) == (False, False)


def test_targets_match_a_straight_rope(env, scene):
    h, t = np.asarray(scene.params["head_target"]), np.asarray(scene.params["tail_target"])
    assert np.linalg.norm(t - h) == pytest.approx(SLACK * (N_LINKS - 1) * LINK, abs=1e-5)


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("straighten_rope")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.6)  # both ends let go (a closed grip on the rope reads ~0.3)
