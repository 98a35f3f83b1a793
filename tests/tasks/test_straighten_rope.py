"""SR: truth table on straight / S-shaped / shifted ropes, the fixed S placed as a whole (yaw ±pi, full
workspace), invisible sensors, the drag each end needs, expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.sim import placement
from readjax.tasks.straighten_rope import FOOTPRINT, LINK, N_LINKS, RADIUS, REGION_HALF, SLACK, SPAN
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
        assert along > REGION_HALF[0] + 0.07


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


@pytest.fixture(scope="module")
def scenes(env):
    keys = jax.vmap(jax.random.key)(np.arange(64))
    return jax.tree.map(np.asarray, jax.jit(jax.vmap(env.sample_scene))(keys))


def test_placement_is_rlbench_s(env, scenes):
    """The one S shape, turned anywhere in ±pi and placed anywhere its footprint fits the workspace;
    each end must be dragged ~10 cm along the axis (and turned 90 degrees)."""
    p = scenes.params
    assert p["feasible"].mean() > 0.9
    axis = p["axis"]
    assert np.histogram(axis, bins=4, range=(-np.pi, np.pi))[0].min() >= 8  # the full turn
    centre = 0.5 * (p["head_target"] + p["tail_target"])
    assert np.ptp(centre[:, 0]) > 0.15 and np.ptp(centre[:, 1]) > 0.4  # over the workspace
    for c, a in zip(centre, axis):  # the turned footprint inside the workspace
        lo, hi = (np.asarray(v) for v in placement.turned_extent(FOOTPRINT[0], FOOTPRINT[1], a))
        assert np.all(c + lo >= placement.WORKSPACE_LOW - 1e-5)
        assert np.all(c + hi <= placement.WORKSPACE_HIGH + 1e-5)
    drag = [np.linalg.norm(p[e] - p[f"{e}_target"], axis=-1) for e in ("head", "tail")]
    assert np.allclose(drag, 0.099, atol=0.002)  # fixed shape: (0.95 * 0.44 - 0.224) / 2
    turn = np.cos(p["head_heading"] - axis)  # the head link (its middle at s = 1/24) leaves at ~87 degrees
    assert np.allclose(turn, np.cos(np.pi / 2 * np.cos(np.pi / 12)), atol=1e-4)
    # the arm must reach far: some ends or sensors lie beyond 0.7 m from the base
    reach = np.linalg.norm(np.concatenate([p["head_target"], p["tail_target"]]), axis=-1)
    assert reach.max() > 0.7


def test_sensors_are_not_rendered(env):
    m = env.mj_model
    for body in ("head_target", "tail_target"):
        b = m.body(body).id
        assert m.body_geomnum[b] == 0  # no geom to draw
        sites = np.flatnonzero(m.site_bodyid == b)
        assert len(sites) == 1 and m.site_group[sites[0]] > 2  # hidden by the renderer's default groups


def test_expert_succeeds(env):
    _, ok, _, trace = expert_run("straighten_rope")
    assert ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.6)  # both ends let go (a closed grip on the rope reads ~0.3)
