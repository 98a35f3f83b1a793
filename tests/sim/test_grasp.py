"""Grasping by kinematic attachment: pad contacts, attach/release, rigid carrying.

Built from the compiled MJCF only (no MJX environment): pick_up_cup has two graspable bodies
(cup, distractor), reach_target none. Contacts are synthetic (geom pairs and distances).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from readjax import geometry as geo
from readjax.sim.grasp import TOUCH_DIST, GraspSpec
from readjax.sim.kinematics import HOME_Q, chain_from_model, fk
from readjax.sim.scene import load_model
from readjax.tasks.pick_up_cup import PickUpCup
from readjax.tasks.reach_target import ReachTarget


@pytest.fixture(scope="module")
def cup():
    model = load_model(PickUpCup.xml)
    spec = GraspSpec(model, PickUpCup.graspable)
    return model, spec, chain_from_model(model)


def geom_of(model, spec, k: int) -> int:
    return int(np.nonzero(spec.geom_mask[k])[0][0])


def contacts(pairs, dists):
    return jnp.asarray(np.array(pairs, np.int32).reshape(-1, 2)), jnp.asarray(np.array(dists, np.float32))


def qpos_at_home(model, chain) -> np.ndarray:
    q = np.array(model.qpos0, np.float32)
    q[chain.qpos_adr] = HOME_Q
    return q


def test_spec_reads_the_free_joints_and_geoms(cup):
    model, spec, _ = cup
    assert spec.n == 2 and spec.bodies == ("cup", "distractor")
    assert spec.geom_mask.shape == (2, model.ngeom)
    assert not np.any(spec.geom_mask[0] & spec.geom_mask[1])
    for k, b in enumerate(spec.body_ids):
        assert np.array_equal(np.nonzero(spec.geom_mask[k])[0], np.nonzero(model.geom_bodyid == b)[0])
    assert np.all(spec.qpos_adr + 7 <= model.nq) and np.all(spec.qvel_adr + 6 <= model.nv)


def test_init_holds_nothing(cup):
    _, spec, _ = cup
    g = spec.init()
    assert g.attached.shape == (2,) and not bool(g.any)
    np.testing.assert_array_equal(np.asarray(g.rel_quat), np.tile([1.0, 0, 0, 0], (2, 1)))
    np.testing.assert_array_equal(np.asarray(g.rel_pos), np.zeros((2, 3)))


def test_a_body_that_is_not_free_is_refused():
    model = load_model(PickUpCup.xml)
    with pytest.raises(ValueError, match="free joint"):
        GraspSpec(model, ("link3",))


def test_pad_contacts_either_order_and_only_close_ones(cup):
    model, spec, _ = cup
    cup_g, dis_g = geom_of(model, spec, 0), geom_of(model, spec, 1)
    lp, rp = spec.left_pad, spec.right_pad
    geom, dist = contacts([[lp, cup_g], [dis_g, rp], [rp, cup_g], [0, cup_g]],
                          [0.0, -0.001, TOUCH_DIST + 0.01, 0.0])
    left, right = spec.pad_contacts(geom, dist)
    np.testing.assert_array_equal(np.asarray(left), [True, False])
    np.testing.assert_array_equal(np.asarray(right), [False, True])  # the far right-pad contact on the cup does not count


def test_attach_needs_both_pads_and_a_close_command(cup):
    model, spec, chain = cup
    qpos = jnp.asarray(qpos_at_home(model, chain))
    cup_g = geom_of(model, spec, 0)
    both = contacts([[spec.left_pad, cup_g], [cup_g, spec.right_pad]], [0.0, 0.0])
    one = contacts([[spec.left_pad, cup_g], [0, cup_g]], [0.0, 0.0])
    g0 = spec.init()
    attach = lambda c, close: spec.update(g0, chain, qpos, *c, jnp.asarray(close), jnp.asarray(0.02))  # noqa: E731
    assert not bool(attach(both, False).any)
    assert not bool(attach(one, True).any)
    g = attach(both, True)
    np.testing.assert_array_equal(np.asarray(g.attached), [True, False])
    assert float(g.finger_hold) == pytest.approx(0.02)
    # opening releases; keeping it closed keeps holding even without contact
    none = contacts([[0, 1]], [1.0])
    assert not bool(spec.update(g, chain, qpos, *none, jnp.asarray(False), jnp.asarray(0.04)).any)
    kept = spec.update(g, chain, qpos, *none, jnp.asarray(True), jnp.asarray(0.04))
    np.testing.assert_array_equal(np.asarray(kept.attached), [True, False])
    assert float(kept.finger_hold) == pytest.approx(0.02)


def test_one_object_at_a_time(cup):
    model, spec, chain = cup
    qpos = jnp.asarray(qpos_at_home(model, chain))
    cg, dg = geom_of(model, spec, 0), geom_of(model, spec, 1)
    c = contacts([[spec.left_pad, cg], [spec.right_pad, cg], [spec.left_pad, dg], [spec.right_pad, dg]], [0.0] * 4)
    g = spec.update(spec.init(), chain, qpos, *c, jnp.asarray(True), jnp.asarray(0.02))
    np.testing.assert_array_equal(np.asarray(g.attached), [True, False])
    # while holding the cup, the distractor is not picked up as well
    c2 = contacts([[spec.left_pad, dg], [spec.right_pad, dg]], [0.0, 0.0])
    g2 = spec.update(g, chain, qpos, *c2, jnp.asarray(True), jnp.asarray(0.01))
    np.testing.assert_array_equal(np.asarray(g2.attached), [True, False])


def test_carried_object_moves_rigidly_with_the_end_effector(cup):
    model, spec, chain = cup
    qpos0 = qpos_at_home(model, chain)
    cg = geom_of(model, spec, 0)
    c = contacts([[spec.left_pad, cg], [spec.right_pad, cg]], [0.0, 0.0])
    g = spec.update(spec.init(), chain, jnp.asarray(qpos0), *c, jnp.asarray(True), jnp.asarray(0.02))
    qvel0 = jnp.zeros(model.nv)
    # at the attaching configuration, applying the grasp leaves the object where it was
    q_same, _ = spec.apply(g, chain, jnp.asarray(qpos0), qvel0)
    a = int(spec.qpos_adr[0])
    np.testing.assert_allclose(np.asarray(q_same)[a:a + 3], qpos0[a:a + 3], atol=1e-5)
    np.testing.assert_allclose(np.abs(np.dot(np.asarray(q_same)[a + 3:a + 7], qpos0[a + 3:a + 7])), 1.0, atol=1e-5)
    # move the arm: the object keeps its pose relative to the end effector; the distractor stays put
    qpos1 = qpos0.copy()
    qpos1[chain.qpos_adr] = HOME_Q + np.array([0.3, 0.2, -0.2, 0.25, 0.1, -0.2, 0.3], np.float32)
    qvel1 = np.zeros(model.nv, np.float32)
    qvel1[chain.qvel_adr] = 0.5
    q_new, v_new = spec.apply(g, chain, jnp.asarray(qpos1), jnp.asarray(qvel1))
    q_new, v_new = np.asarray(q_new), np.asarray(v_new)

    def rel(qp):
        p, r = fk(chain, jnp.asarray(qp[chain.qpos_adr]))
        r = np.asarray(r)
        return r.T @ (qp[a:a + 3] - np.asarray(p)), r.T @ np.asarray(geo.quat_to_mat(jnp.asarray(qp[a + 3:a + 7])))

    (p0, r0), (p1, r1) = rel(qpos0), rel(q_new)
    np.testing.assert_allclose(p1, p0, atol=1e-5)
    np.testing.assert_allclose(r1, r0, atol=1e-5)
    d, vd = int(spec.qpos_adr[1]), int(spec.qvel_adr[1])
    np.testing.assert_array_equal(q_new[d:d + 7], qpos1[d:d + 7])
    np.testing.assert_array_equal(v_new[vd:vd + 6], qvel1[vd:vd + 6])
    assert np.linalg.norm(v_new[int(spec.qvel_adr[0]):int(spec.qvel_adr[0]) + 3]) > 0  # carried with the arm's motion


def test_nothing_attached_leaves_the_state_alone(cup):
    model, spec, chain = cup
    qpos = jnp.asarray(qpos_at_home(model, chain))
    qvel = jnp.arange(model.nv, dtype=jnp.float32)
    q, v = spec.apply(spec.init(), chain, qpos, qvel)
    np.testing.assert_array_equal(np.asarray(q), np.asarray(qpos))
    np.testing.assert_array_equal(np.asarray(v), np.asarray(qvel))


def test_a_task_without_graspables_is_a_no_op():
    model = load_model(ReachTarget.xml)
    chain = chain_from_model(model)
    spec = GraspSpec(model, ReachTarget.graspable)
    assert spec.n == 0
    left, right = spec.pad_contacts(*contacts([[spec.left_pad, 0]], [0.0]))
    assert left.shape == (0,) and right.shape == (0,)
    g = spec.init()
    qpos = jnp.asarray(qpos_at_home(model, chain))
    assert spec.update(g, chain, qpos, *contacts([[0, 1]], [0.0]), jnp.asarray(True), jnp.asarray(0.0)) is g
    qvel = jnp.zeros(model.nv)
    q, v = spec.apply(g, chain, qpos, qvel)
    assert q is qpos and v is qvel
