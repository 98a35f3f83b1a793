"""PB: success-predicate truth table (RLBench's JointCondition: |q - q0| > 3 mm), the button's
physical invariants (rest at q0, the expert's press switches it without bottoming out), placement
with yaw +-pi, and expert success."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from readjax import geometry as geo
from readjax import tasks
from readjax.sim import ik, placement
from readjax.tasks.common import down_quat
from readjax.tasks.push_button import CAP_TOP, PAD_HALF, PRESS_DEPTH, PRESSED, TRAVEL
from tests.tasks.helpers import expert_run, grasping, hand_built, judge


@pytest.fixture(scope="module")
def env():
    return tasks.make("push_button")


@pytest.mark.parametrize("travel, expected", [(0.0, False), (-0.002, False), (-0.0029, False), (-0.0032, True),
                                              (-0.0055, True)])
def test_truth_table(env, travel, expected):
    scene = env.sample_scene(jax.random.key(3))
    qpos = np.array(scene.qpos)
    qpos[env.button_qadr] = travel
    ok, fail, _ = judge(env, scene, hand_built(env, qpos), grasping(env, None))
    assert (ok, fail) == (expected, False)


def test_button_geometry(env):
    m = env.mj_model
    lo, hi = m.jnt_range[m.joint("button").id]
    assert hi == 0.0 and -lo == pytest.approx(TRAVEL) and PRESSED < TRAVEL <= 0.008  # a few mm of travel
    half = m.geom_size[m.geom("cap").id]
    assert 0.01 <= half[0] <= 0.02 and 0.01 <= half[1] <= 0.02  # a 2-4 cm cap
    cap_top = m.body("button").pos[2] + half[2]
    assert cap_top == pytest.approx(CAP_TOP)


def _settle(env, scene, arm_q=None, ctrl_q=None, steps=400):
    """C MuJoCo with the base pinned as TaskEnv pins it; returns the button joint at the end."""
    m = env.mj_model
    d = mujoco.MjData(m)
    q0 = np.asarray(scene.qpos)
    d.qpos[:] = q0
    if arm_q is not None:
        d.qpos[env.chain.qpos_adr] = arm_q
        d.qpos[env.finger_qpos_adr] = 0.0
        d.ctrl[:7], d.ctrl[7:] = ctrl_q, 0.0
    for _ in range(steps):
        mujoco.mj_step(m, d)
        d.qpos[env.pinned_qpos_adr] = q0[env.pinned_qpos_adr]
        d.qvel[env.pinned_qvel_adr] = 0.0
    return float(d.qpos[env.button_qadr])


def test_button_rests_at_its_start(env):
    scene = env.sample_scene(jax.random.key(1))
    assert abs(_settle(env, scene) - float(scene.qpos[env.button_qadr])) < 3e-4


def test_expert_press_switches_without_bottoming_out(env):
    """The expert's press pose (pads' underside PRESS_DEPTH below the rest top) moves the cap past the
    3 mm switch point and stops short of the end of the stroke: a press, not a push through."""
    scene = env.sample_scene(jax.random.key(2))
    b = np.asarray(scene.params["button"])
    rot = geo.quat_to_mat(down_quat(0.0))
    q_home = jnp.asarray(np.asarray(scene.qpos)[env.chain.qpos_adr])
    q_above = ik.solve_ik(env.chain, q_home, jnp.asarray(b + [0, 0, CAP_TOP + PAD_HALF + 0.01]), rot, 200)
    q_press = ik.solve_ik(env.chain, q_above, jnp.asarray(b + [0, 0, CAP_TOP + PAD_HALF - PRESS_DEPTH]), rot, 200)
    travel = -_settle(env, scene, np.asarray(q_above), np.asarray(q_press))
    assert PRESSED + 0.001 < travel < TRAVEL - 0.001


def test_placement_turns_fully(env):
    keys = jax.vmap(jax.random.key)(jnp.arange(64))
    scenes = jax.jit(jax.vmap(env.sample_scene))(keys)
    yaw = np.asarray(scenes.params["yaw"])
    assert yaw.min() < -2.5 and yaw.max() > 2.5
    xy = np.asarray(scenes.params["button"])[:, :2]
    assert np.all(xy >= placement.WORKSPACE_LOW + 0.05 - 1e-6) and np.all(xy <= placement.WORKSPACE_HIGH - 0.05 + 1e-6)


def test_expert_succeeds(env):
    _, ok, _, _ = expert_run("push_button")
    assert ok.sum() >= len(ok) - 1
