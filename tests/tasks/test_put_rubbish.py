"""PR: truth table (only the rubbish in the turned bin counts), RLBench's rigid layout with its 3
swaps and yaw +-pi, only the rubbish graspable, expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import placement
from readjax.tasks.put_rubbish import FOOT_MAX, FOOT_MIN, LAYOUTS, RUBBISH_R, SPOTS, TOMATO_R
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("put_rubbish")


def _state(env, scene, rubbish=None, tomato0=None):
    """qpos with the rubbish / tomato 0 moved to points given in the bin's (turned) frame (None: left
    in place)."""
    qpos = np.array(scene.qpos)
    bin_xy, yaw = scene.params["bin"][:2], scene.params["yaw"]
    if rubbish is not None:
        qpos[env.rubbish_qadr:env.rubbish_qadr + 3] = placement.to_world(bin_xy, yaw, jnp.asarray(rubbish))
    if tomato0 is not None:
        a = int(env.tomato_qadr[0])
        qpos[a:a + 3] = placement.to_world(bin_xy, yaw, jnp.asarray(tomato0))
    return hand_built(env, qpos, scene.mocap_pos, scene.mocap_quat)


IN_BIN = (0.0, 0.0, RUBBISH_R)
IN_BIN_CORNER = (0.07, -0.07, 0.1)  # in the turned bin's corner: outside an unturned box at these yaws


@pytest.mark.parametrize(
    "rubbish, tomato0, attached, expected",
    [
        (None, None, None, False),  # start: everything on the table
        (IN_BIN, None, None, True),  # rubbish dropped in
        (IN_BIN_CORNER, None, None, True),  # still falling, inside the walls
        ((0.0, 0.0, 0.2), None, 0, False),  # carried above the bin, not in it
        ((0.0, 0.0, 0.1), None, 0, True),  # still held but inside (RLBench: no NothingGrasped)
        ((0.12, 0.0, RUBBISH_R), None, None, False),  # next to the bin
        ((0.0, 0.095, RUBBISH_R), None, None, False),  # just beyond the far wall
        (IN_BIN, (0.04, 0.04, TOMATO_R), None, True),  # a tomato went in too: RLBench does not care
        (None, (0.0, 0.0, TOMATO_R), None, False),  # only a tomato in the bin
    ],
)
@pytest.mark.parametrize("seed", [3, 14])  # yaw -2.33 and 0.84: near a diagonal
def test_truth_table(env, seed, rubbish, tomato0, attached, expected):
    scene = env.sample_scene(jax.random.key(seed))
    data = _state(env, scene, rubbish, tomato0)
    ok, fail, _ = judge(env, scene, data, grasping(env, attached))
    assert (ok, fail) == (expected, False)


def test_only_the_rubbish_is_graspable(env):
    assert env.graspable == ("rubbish",) and env.grasp_spec.n == 1


def test_layout_is_rlbench_rigid_template(env):
    """Bin and items move as one model turned by a yaw in +-pi, the footprint inside the workspace;
    the items sit on the three fixed spots, the rubbish on each of them about a third of the time."""
    keys = jax.vmap(lambda i: jax.random.fold_in(jax.random.key(0), i))(jnp.arange(300))
    s = jax.jit(jax.vmap(env.draw_scene))(keys)
    fits = np.asarray(s.params["fits"])
    assert fits.mean() > 0.99
    yaw, bin_xy = np.asarray(s.params["yaw"]), np.asarray(s.params["bin"])[:, :2]
    assert np.histogram(yaw, 4, (-np.pi, np.pi))[0].min() > 50
    c, sn = np.cos(yaw)[:, None], np.sin(yaw)[:, None]

    def local(w):  # world xy -> task frame
        d = w - bin_xy
        return np.concatenate([c * d[:, :1] + sn * d[:, 1:], -sn * d[:, :1] + c * d[:, 1:]], -1)

    items = [np.asarray(s.qpos[:, a:a + 3]) for a in (env.rubbish_qadr, *env.tomato_qadr)]
    assert np.allclose(items[0][:, 2], RUBBISH_R) and np.allclose(items[1][:, 2], TOMATO_R)
    spot_of = np.stack([np.argmin(np.linalg.norm(local(it[:, :2])[:, None] - SPOTS[None], axis=-1), -1)
                        for it in items], -1)
    for it, k in zip(items, range(3)):
        np.testing.assert_allclose(local(it[:, :2]), SPOTS[spot_of[:, k]], atol=1e-5)
    np.testing.assert_array_equal(spot_of, LAYOUTS[np.asarray(s.params["layout"])])
    counts = np.bincount(spot_of[:, 0], minlength=3)
    assert counts.min() > 70  # 100 expected each
    for corner in ((FOOT_MIN[0], FOOT_MIN[1]), (FOOT_MIN[0], FOOT_MAX[1]), (FOOT_MAX[0], FOOT_MIN[1]),
                   (FOOT_MAX[0], FOOT_MAX[1])):
        w = bin_xy + np.concatenate([c * corner[0] - sn * corner[1], sn * corner[0] + c * corner[1]], -1)
        assert np.all((w[fits] >= placement.WORKSPACE_LOW - 1e-5) & (w[fits] <= placement.WORKSPACE_HIGH + 1e-5))


def test_expert_succeeds(env):
    scenes, ok, _, trace = expert_run("put_rubbish")
    assert scenes.params["feasible"].all() and ok.sum() >= len(ok) - 1
    assert np.all(trace.grip[:, -1] > 0.9)  # released: the gripper is open at the end
