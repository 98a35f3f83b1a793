"""PR — put rubbish: pick up the paper ball and drop it into the bin; two tomatoes are distractors.

RLBench (``rlbench/tasks/put_rubbish_in_bin.py``): one success condition, the rubbish detected by
the bin's ``success`` proximity sensor (nothing about the tomatoes); only the rubbish is registered
graspable. The model is rigid (no spawn boundary): bin, rubbish and two tomatoes at fixed points
of the task frame, except that ``init_episode`` swaps the rubbish with tomato2 (``randint(3) ==
0``), with tomato1 (``== 2``) or leaves it (``== 1``): 3 layouts, equally likely. No
``base_rotation_bounds`` override: the whole model is placed by ``Scene._place_task`` at a random
workspace position with yaw +-pi.

Here the task frame's origin is the bin's centre; the three item spots are fixed in it
(:data:`SPOTS`: the rubbish's own spot, tomato1's and tomato2's, in front of the bin's -y side),
and the swap is drawn as RLBench draws it. The frame is placed by
:func:`readjax.sim.placement.place_task` with yaw +-pi; its footprint is the bounding box of the bin
and the three items, x [-0.13, 0.13], y [-0.22, 0.088]. The sensor is the bin's interior (site
``bin_region``, turned with the bin), checked on the rubbish's centre. Only the rubbish is
graspable (the gripper can still push a tomato). Sizes (the .ttm is unreadable): a 17.6 cm square,
12 cm tall waste-paper bin, a 5.4 cm paper ball, 6 cm tomatoes, the spots 10 cm apart: real-world
sizes.

Expert: a top-down grasp of the ball (fingers across the direction to the bin, so the hand's
capsule clears the bin's walls; the yaw folded modulo pi, the gripper being symmetric, to where
joint 7 is mid-range), lift, carry it over the bin at 0.26 m, lower to 0.19 m, open: the ball
drops in.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

RUBBISH_R = 0.027
TOMATO_R = 0.03
BIN_HALF = np.array([0.08, 0.08, 0.06], np.float32)  # interior region half sizes (site bin_region)
BIN_REGION_Z = 0.06  # region centre above the table
# item spots in the task frame (bin centre at the origin): the rubbish's, tomato1's, tomato2's
SPOTS = np.array([[0.0, -0.19], [-0.10, -0.17], [0.10, -0.17]], np.float32)
FOOT_MIN = np.array([-0.13, -0.22], np.float32)
FOOT_MAX = np.array([0.13, 0.088], np.float32)
CARRY_Z = 0.26  # tcp height while carrying
DROP_Z = 0.19  # tcp height where the rubbish is released (bin top at 0.12)
# RLBench's randint(3): 0 swaps the rubbish with tomato2, 1 leaves it, 2 swaps it with tomato1.
# Rows: the spot index of (rubbish, tomato1, tomato2) for each draw; the bodies "tomato0" and
# "tomato1" are RLBench's tomato1 and tomato2.
LAYOUTS = np.array([[2, 1, 0], [0, 1, 2], [1, 0, 2]], np.int32)


class PutRubbish(TaskEnv):
    name = "put_rubbish"
    code = "PR"
    xml = "put_rubbish.xml"
    description = "put the rubbish (white paper ball) into the bin; the two tomatoes are distractors"
    graspable = ("rubbish",)
    # above, descend, close, lift, over the bin, lower, open, hold
    expert_durations = (45, 25, 25, 25, 45, 15, 15, 10)

    def setup(self):
        m = self.mj_model
        self.rubbish_qadr = free_adr(m, "rubbish")
        self.tomato_qadr = np.array([free_adr(m, "tomato0"), free_adr(m, "tomato1")], np.int32)
        self.bin_mocap = mocap_index(m, "bin")

    def draw_scene(self, key):
        k_place, k_swap = jax.random.split(key)
        xy, yaw, fits = placement.place_task(k_place, FOOT_MIN, FOOT_MAX)
        layout = jax.random.randint(k_swap, (), 0, 3)
        spots = placement.to_world(xy, yaw, jnp.asarray(SPOTS))[jnp.asarray(LAYOUTS)[layout]]
        scene = self.default_scene()
        quat = geo.yaw_quat(yaw)
        rubbish = jnp.append(spots[0], RUBBISH_R)
        qpos = set_free_body(scene.qpos, self.rubbish_qadr, rubbish, quat)
        for k in range(2):
            qpos = set_free_body(qpos, int(self.tomato_qadr[k]), jnp.append(spots[k + 1], TOMATO_R), quat)
        bin_pos = jnp.append(xy, 0.0)
        mpos = scene.mocap_pos.at[self.bin_mocap].set(bin_pos)
        mquat = scene.mocap_quat.at[self.bin_mocap].set(quat)
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"rubbish": rubbish, "bin": bin_pos, "yaw": yaw, "layout": layout,
                                     "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

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
        rot = geo.quat_to_mat(data.mocap_quat[self.bin_mocap])
        centre = data.mocap_pos[self.bin_mocap] + jnp.array([0.0, 0.0, BIN_REGION_Z])
        return in_box(point, centre, rot, BIN_HALF)

    def is_success(self, progress, data, grasp, scene):
        return self.in_bin(data, data.qpos[self.rubbish_qadr:self.rubbish_qadr + 3])
