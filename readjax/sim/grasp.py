"""Grasping by kinematic attachment (RLBench's semantics: an object closed on is carried).

An object becomes attached when the gripper is commanded closed and BOTH finger pads touch it;
from then on, after every physics substep its free joint is set to follow the end-effector
frame with the relative pose it had at attachment (velocities included, so contacts with the
carried object still push other objects). Opening the gripper releases it. This is as robust
under MJX's few-iteration solvers as a weld, and cheaper; see tests/sim/test_grasp.py.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct

from readjax import geometry as geo
from readjax.sim.kinematics import ArmChain, fk_jacobian

TOUCH_DIST = 0.002  # a pad "touches" a geom when their contact distance is below this (m)


@struct.dataclass
class GraspState:
    attached: jax.Array  # (n_objects,) bool
    rel_pos: jax.Array  # (n_objects, 3) object origin in the end-effector frame
    rel_quat: jax.Array  # (n_objects, 4) object orientation in the end-effector frame
    finger_hold: jax.Array  # () finger opening held while something is attached

    @property
    def any(self) -> jax.Array:
        return jnp.any(self.attached)


class GraspSpec:
    """Static description (numpy) of the graspable objects of a model."""

    def __init__(self, model: mujoco.MjModel, bodies: tuple[str, ...]):
        self.bodies = tuple(bodies)
        self.body_ids = np.array([model.body(b).id for b in bodies], np.int32)
        qadr, vadr, masks = [], [], []
        for b in self.body_ids:
            jnt = model.body_jntadr[b]
            if model.body_jntnum[b] != 1 or model.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
                raise ValueError(f"graspable body {model.body(b).name!r} needs exactly one free joint")
            qadr.append(model.jnt_qposadr[jnt])
            vadr.append(model.jnt_dofadr[jnt])
            masks.append(model.geom_bodyid == b)
        self.qpos_adr = np.array(qadr, np.int32)
        self.qvel_adr = np.array(vadr, np.int32)
        self.geom_mask = np.array(masks, bool).reshape(len(bodies), model.ngeom)
        self.left_pad = model.geom("left_pad").id
        self.right_pad = model.geom("right_pad").id

    @property
    def n(self) -> int:
        return len(self.bodies)

    def init(self) -> GraspState:
        return GraspState(
            attached=jnp.zeros((self.n,), bool),
            rel_pos=jnp.zeros((self.n, 3)),
            rel_quat=jnp.tile(jnp.array([1.0, 0, 0, 0]), (self.n, 1)),
            finger_hold=jnp.zeros(()),
        )

    def pad_contacts(self, contact_geom: jax.Array, contact_dist: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Per object: (left pad touches it, right pad touches it)."""
        if self.n == 0:
            return jnp.zeros((0,), bool), jnp.zeros((0,), bool)
        g1, g2 = contact_geom[:, 0], contact_geom[:, 1]
        close = contact_dist < TOUCH_DIST
        mask = jnp.asarray(self.geom_mask)

        def touches(pad):
            other = jnp.where(g1 == pad, g2, jnp.where(g2 == pad, g1, -1))
            hit = (other >= 0) & close
            return jnp.any(hit[None, :] & mask[:, jnp.clip(other, 0)], axis=1)

        return touches(self.left_pad), touches(self.right_pad)

    def update(self, g: GraspState, chain: ArmChain, qpos: jax.Array, contact_geom: jax.Array,
               contact_dist: jax.Array, close_cmd: jax.Array, finger_open: jax.Array) -> GraspState:
        """Attach/detach after a control step. ``close_cmd``: gripper commanded closed."""
        if self.n == 0:
            return g
        left, right = self.pad_contacts(contact_geom, contact_dist)
        candidates = left & right & close_cmd & ~g.any
        first = jnp.arange(self.n) == jnp.argmax(candidates)
        new = candidates & first
        tcp_p, tcp_r, _ = fk_jacobian(chain, qpos[chain.qpos_adr])
        obj_p = qpos[self.qpos_adr[:, None] + np.arange(3)]
        obj_q = qpos[self.qpos_adr[:, None] + 3 + np.arange(4)]
        rel_p = jnp.einsum("ji,nj->ni", tcp_r, obj_p - tcp_p)
        rel_q = geo.quat_mul(geo.quat_conj(geo.mat_to_quat(tcp_r))[None], obj_q)
        attached = jnp.where(close_cmd, g.attached | new, False)
        return GraspState(
            attached=attached,
            rel_pos=jnp.where(new[:, None], rel_p, g.rel_pos),
            rel_quat=jnp.where(new[:, None], rel_q, g.rel_quat),
            finger_hold=jnp.where(jnp.any(new), finger_open, g.finger_hold),
        )

    def apply(self, g: GraspState, chain: ArmChain, qpos: jax.Array, qvel: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Move attached objects rigidly with the end effector (after a physics substep)."""
        if self.n == 0:
            return qpos, qvel
        tcp_p, tcp_r, jac = fk_jacobian(chain, qpos[chain.qpos_adr])
        twist = jac @ qvel[chain.qvel_adr]
        v_lin, w = twist[:3], twist[3:]
        obj_p = tcp_p[None] + jnp.einsum("ij,nj->ni", tcp_r, g.rel_pos)
        obj_q = geo.quat_mul(geo.mat_to_quat(tcp_r)[None], g.rel_quat)
        obj_r = geo.quat_to_mat(obj_q)
        lin = v_lin[None] + jnp.cross(w[None], obj_p - tcp_p[None])
        ang_local = jnp.einsum("nji,j->ni", obj_r, w)  # free-joint angular velocity is body-local
        for k in range(self.n):
            a = g.attached[k]
            qa, va = int(self.qpos_adr[k]), int(self.qvel_adr[k])
            qpos = qpos.at[qa:qa + 3].set(jnp.where(a, obj_p[k], qpos[qa:qa + 3]))
            qpos = qpos.at[qa + 3:qa + 7].set(jnp.where(a, obj_q[k], qpos[qa + 3:qa + 7]))
            qvel = qvel.at[va:va + 3].set(jnp.where(a, lin[k], qvel[va:va + 3]))
            qvel = qvel.at[va + 3:va + 6].set(jnp.where(a, ang_local[k], qvel[va + 3:va + 6]))
        return qpos, qvel
