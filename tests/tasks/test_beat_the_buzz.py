"""BB: wire-touch geometry, truth table (finish reached, released, wire touched) and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import placement
from readjax.tasks.beat_the_buzz import FINISH_X, FOOTPRINT, START_X, WIRE_Z, segment_distance
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("beat_the_buzz")


@pytest.fixture(scope="module")
def scene(env):
    return env.sample_scene(jax.random.key(7))


def wand_state(env, scene, local):
    """Hand-built data with the wand's ring centre at ``local`` in the base frame (upright)."""
    base, yaw = np.asarray(scene.params["base"]), float(scene.params["yaw"])
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    qpos = np.array(scene.qpos)
    a = env.wand_qadr
    qpos[a:a + 3] = base + rot @ np.asarray(local)
    qpos[a + 3:a + 7] = [np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


def test_segment_distance_matches_brute_force():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(64, 4, 3)).astype(np.float32)
    p[:8, 3] = p[:8, 2] + 2 * (p[:8, 1] - p[:8, 0])  # some parallel pairs
    got = np.asarray(segment_distance(jnp.asarray(p[:, 0]), jnp.asarray(p[:, 1]), jnp.asarray(p[:, 2]),
                                      jnp.asarray(p[:, 3])))
    t = np.linspace(0, 1, 401)
    for k in range(len(p)):
        a = p[k, 0] + t[:, None] * (p[k, 1] - p[k, 0])
        b = p[k, 2] + t[:, None] * (p[k, 3] - p[k, 2])
        brute = np.min(np.linalg.norm(a[:, None] - b[None], axis=-1))
        assert got[k] == pytest.approx(brute, abs=2e-3)
        assert got[k] <= brute + 1e-5


def test_start_state_is_clear_of_the_wire(env, scene):
    data = hand_built(env, np.array(scene.qpos), scene.mocap_pos, scene.mocap_quat)
    assert float(env.wire_clearance(data, scene)) == pytest.approx(0.025, abs=1e-3)
    assert judge(env, scene, data, grasping(env, None))[:2] == (False, False)


@pytest.mark.parametrize(
    "local, attached, expected",
    [
        ((START_X, 0.0, WIRE_Z), None, (False, False)),  # at the start
        ((0.0, 0.0, WIRE_Z), 0, (False, False)),  # carried, half way, centred
        ((0.0, 0.0, WIRE_Z + 0.015), 0, (False, False)),  # off centre but still 1 cm clear
        ((FINISH_X, 0.0, WIRE_Z), None, (True, False)),  # at the far end, released
        ((FINISH_X + 0.02, 0.0, WIRE_Z + 0.01), None, (True, False)),  # inside the finish region
        ((FINISH_X, 0.0, WIRE_Z), 0, (False, False)),  # at the far end but still held
        ((FINISH_X - 0.05, 0.0, WIRE_Z), None, (False, False)),  # short of the finish region
        ((0.0, 0.0, WIRE_Z + 0.025), 0, (False, True)),  # ring's bottom bar on the wire: buzz
        ((0.0, 0.026, WIRE_Z), 0, (False, True)),  # ring's side on the wire: buzz
        ((FINISH_X, 0.0, WIRE_Z - 0.026), None, (False, True)),  # at the end but resting on the wire
    ],
)
def test_truth_table(env, scene, local, attached, expected):
    data = wand_state(env, scene, local)
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == expected


def test_placement_is_rlbench_task_placement(env):
    """The whole base is placed with yaw +-pi and its footprint inside the workspace; the wand starts
    on the start rest of the turned base."""
    keys = jax.vmap(lambda i: jax.random.fold_in(jax.random.key(0), i))(jnp.arange(256))
    scenes = jax.jit(jax.vmap(env.draw_scene))(keys)
    fits = np.asarray(scenes.params["fits"])
    assert fits.mean() > 0.99
    yaw, base = np.asarray(scenes.params["yaw"]), np.asarray(scenes.params["base"])
    assert yaw.min() < -2.8 and yaw.max() > 2.8 and np.histogram(yaw, 4, (-np.pi, np.pi))[0].min() > 40
    c, s = np.cos(yaw), np.sin(yaw)
    for sx in (-1, 1):
        for sy in (-1, 1):
            corner = base[:, :2] + np.stack([c * sx * FOOTPRINT[0] - s * sy * FOOTPRINT[1],
                                             s * sx * FOOTPRINT[0] + c * sy * FOOTPRINT[1]], -1)
            inside = np.all((corner >= placement.WORKSPACE_LOW - 1e-5) & (corner <= placement.WORKSPACE_HIGH + 1e-5), -1)
            assert np.all(inside[fits])
    wand = np.asarray(scenes.qpos[:, env.wand_qadr:env.wand_qadr + 3])
    start = base[:, :2] + START_X * np.stack([c, s], -1)
    np.testing.assert_allclose(wand[:, :2], start, atol=1e-5)


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("beat_the_buzz")
    assert scenes.params["feasible"].all() and ok.sum() >= len(ok) - 1
    # the demo ends with the gripper open, away from the wand (it was let go)
    assert np.all(trace.grip[:, -1] > 0.9)
