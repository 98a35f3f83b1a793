"""PR — put rubbish: pick up the paper ball and drop it into the bin; two tomatoes are distractors.

Adapted from RLBench's ``put_rubbish_in_bin``: the "success" proximity sensor is the bin's
interior (site ``bin_region``), checked on the rubbish's centre. RLBench registers only the
rubbish as graspable; here the tomatoes can be grasped too (so a policy that goes for a tomato
really picks it up), and a tomato inside the bin region blocks success (TASKS.md: "rubbish
inside the bin region, tomatoes are not"). Grasping a tomato is not a failure by itself.
RLBench swaps the rubbish with one of the tomatoes; here the three spots are sampled and the
rubbish takes a random one of them.

Expert: a top-down grasp of the ball (fingers across the direction to the bin), lift, carry it
over the bin at 0.26 m, lower to 0.19 m, open: the ball drops in.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

RUBBISH_R = 0.027
TOMATO_R = 0.03
BIN_HALF = np.array([0.08, 0.08, 0.06], np.float32)  # interior region half sizes (site bin_region)
BIN_REGION_Z = 0.06  # region centre above the table
BIN_LOW, BIN_HIGH = (0.36, -0.24), (0.62, 0.24)
ITEM_LOW, ITEM_HIGH = (0.33, -0.3), (0.72, 0.3)
ITEM_DIST = 0.10  # between item centres
BIN_DIST = 0.18  # item centre to bin centre
CARRY_Z = 0.26  # tcp height while carrying
DROP_Z = 0.19  # tcp height where the rubbish is released (bin top at 0.12)


def sample_layout(key: jax.Array, tries: int = 128) -> tuple[jax.Array, jax.Array]:
    """Bin centre (2,) and three item spots (3, 2): items >= ITEM_DIST apart, >= BIN_DIST from the bin."""
    k_bin, k_items = jax.random.split(key)
    bins = jax.random.uniform(k_bin, (tries, 2), minval=jnp.array(BIN_LOW), maxval=jnp.array(BIN_HIGH))
    items = jax.random.uniform(k_items, (tries, 3, 2), minval=jnp.array(ITEM_LOW),
                               maxval=jnp.array(ITEM_HIGH))
    d_bin = jnp.linalg.norm(items - bins[:, None], axis=-1).min(axis=1) - BIN_DIST
    d_items = jnp.linalg.norm(items[:, :, None] - items[:, None], axis=-1) + jnp.eye(3) * 1e3
    margin = jnp.minimum(d_bin, d_items.min(axis=(1, 2)) - ITEM_DIST)
    ok = margin >= 0
    pick = jnp.where(jnp.any(ok), jnp.argmax(ok), jnp.argmax(margin))
    return bins[pick], items[pick]


class PutRubbish(TaskEnv):
    name = "put_rubbish"
    code = "PR"
    xml = "put_rubbish.xml"
    description = "put the rubbish (white paper ball) into the bin; the two tomatoes are distractors"
    graspable = ("rubbish", "tomato0", "tomato1")
    # above, descend, close, lift, over the bin, lower, open, hold
    expert_durations = (45, 25, 25, 25, 45, 15, 15, 10)

    def setup(self):
        m = self.mj_model
        self.rubbish_qadr = free_adr(m, "rubbish")
        self.tomato_qadr = np.array([free_adr(m, "tomato0"), free_adr(m, "tomato1")], np.int32)
        self.bin_mocap = mocap_index(m, "bin")

    def sample_scene(self, key):
        k_layout, k_perm = jax.random.split(key)
        bin_xy, spots = sample_layout(k_layout)
        order = jax.random.permutation(k_perm, 3)  # order[0]: the rubbish's spot
        spots = spots[order]
        scene = self.default_scene()
        ident = jnp.array([1.0, 0, 0, 0])
        qpos = set_free_body(scene.qpos, self.rubbish_qadr, jnp.append(spots[0], RUBBISH_R), ident)
        for k in range(2):
            qpos = set_free_body(qpos, int(self.tomato_qadr[k]), jnp.append(spots[k + 1], TOMATO_R), ident)
        bin_pos = jnp.append(bin_xy, 0.0)
        mocap = scene.mocap_pos.at[self.bin_mocap].set(bin_pos)
        return scene.replace(qpos=qpos, mocap_pos=mocap,
                             params={"rubbish": jnp.append(spots[0], RUBBISH_R), "bin": bin_pos})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        r, b = scene.params["rubbish"], scene.params["bin"]
        # The hand's collision capsule spans +-0.12 m along the finger axis, 7 cm above the tcp: turn
        # that axis across the rubbish-to-bin direction so it clears the bin walls at the grasp; fold
        # the yaw (the ball is round, the gripper symmetric) to where joint 7 is mid-range.
        yaw = jnp.arctan2(b[1] - r[1], b[0] - r[0])
        mid = jnp.arctan2(r[1], r[0]) + 0.785  # joint 7 ~ 0.785 + atan2(y, x) - yaw at a down-pointing tcp
        yaw = mid + (yaw - mid + jnp.pi / 2) % jnp.pi - jnp.pi / 2
        above = r.at[2].set(RUBBISH_R + 0.12)
        lift = r.at[2].set(CARRY_Z)
        over = b.at[2].set(CARRY_Z)
        drop = b.at[2].set(DROP_Z)
        pos = jnp.stack([above, r, r, lift, over, drop, drop, drop])
        quat = jnp.tile(down_quat(yaw), (8, 1))
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def in_bin(self, data, point: jax.Array) -> jax.Array:
        centre = data.mocap_pos[self.bin_mocap] + jnp.array([0.0, 0.0, BIN_REGION_Z])
        return in_box(point, centre, jnp.eye(3), BIN_HALF)

    def is_success(self, progress, data, grasp, scene):
        rubbish = data.qpos[self.rubbish_qadr:self.rubbish_qadr + 3]
        tomatoes = data.qpos[self.tomato_qadr[:, None] + np.arange(3)]
        return self.in_bin(data, rubbish) & ~jnp.any(self.in_bin(data, tomatoes))
