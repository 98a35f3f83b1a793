"""SW — stack wine: lay the upright bottle on its side in the rack's fixed slot.

RLBench (``rlbench/tasks/stack_wine.py``): one success condition, the bottle detected by the rack's
``success`` proximity sensor (no NothingGrasped: it is imported but never registered); no spawn
boundary, so rack and bottle are one rigid model; ``base_rotation_bounds`` = yaw +-pi/4, so the
whole model is placed by ``Scene._place_task`` at a random workspace position turned +-pi/4.

Here the task frame is the rack's centre (x across the three slots, y along them), placed by
:func:`readjax.sim.placement.place_task` with yaw +-pi/4; the bottle stands at a fixed point of
that frame (:data:`BOTTLE`, beside the rack on its -y side). Footprint: the rack, 0.32 x 0.19 m,
and the standing bottle (radius 3.7 cm), i.e. x [-0.16, 0.16], y [-0.287, 0.094] in the task
frame. The sensor is the box site ``slot_region`` around the target slot (the rack's -x slot,
nearest the robot at yaw 0) and the detected point is the middle of the bottle's body (site
``bottle_centre``). The region is only 5 cm high at the height of a lying bottle's axis, so an
upright bottle can never be "in" it. Sizes (the .ttm is unreadable): a 0.30 m, 7.4 cm wide wine
bottle and a cradle rack of three 10 cm slots, real-world sizes.

Expert: grasp the neck from above with the fingers across the slot's axis, lift, roll the hand 90
degrees about the fingers' axis (the bottle comes down on its side, its base along the slot) while
moving over the slot, lower it onto the rails, open, back away. Which way along the slot the base
points is the expert's choice (the sensor does not care): the one pointing away from the robot's
base, so the hand stays between the base and the slot; of the two finger yaws (the gripper is
symmetric) the one whose roll keeps the joints off their limits (:meth:`StackWine.grasp_yaw`).
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

SLOT = np.array([-0.1, 0.0, 0.077], np.float32)  # target slot centre in the rack frame (site slot_region)
SLOT_HALF = np.array([0.025, 0.05, 0.025], np.float32)
BOTTLE = np.array([-0.02, -0.25, 0.0], np.float32)  # where the bottle stands, rack frame
BOTTLE_R = 0.037
FOOT_MIN = np.array([-0.16, BOTTLE[1] - BOTTLE_R], np.float32)
FOOT_MAX = np.array([0.16, 0.094], np.float32)
YAW_BOUNDS = (-np.pi / 4, np.pi / 4)  # StackWine.base_rotation_bounds
NECK_GRASP = 0.272  # tcp height on the neck of the upright bottle (bottle frame)
CENTRE = 0.12  # the body's middle (site bottle_centre), bottle frame


def wrap(a):
    return (a + jnp.pi) % (2 * jnp.pi) - jnp.pi


class StackWine(TaskEnv):
    name = "stack_wine"
    code = "SW"
    xml = "stack_wine.xml"
    description = "lay the wine bottle on its side in the rack's slot"
    graspable = ("bottle",)
    # above, descend, close, lift, roll over the slot, lower, open, back away
    expert_durations = (40, 20, 25, 20, 50, 20, 15, 15)

    def setup(self):
        m = self.mj_model
        self.bottle_qadr = free_adr(m, "bottle")
        self.rack_mocap = mocap_index(m, "rack")
        self.centre_site = m.site("bottle_centre").id

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, FOOT_MIN, FOOT_MAX, YAW_BOUNDS)
        scene = self.default_scene()
        rack = jnp.array([xy[0], xy[1], 0.0])
        quat = geo.yaw_quat(yaw)
        bottle = placement.to_world(xy, yaw, BOTTLE)
        qpos = set_free_body(scene.qpos, self.bottle_qadr, bottle, quat)
        mpos = scene.mocap_pos.at[self.rack_mocap].set(rack)
        mquat = scene.mocap_quat.at[self.rack_mocap].set(quat)
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"bottle": bottle, "rack": rack, "yaw": yaw, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    def slot_world(self, scene: Scene) -> jax.Array:
        return placement.to_world(scene.params["rack"][:2], scene.params["yaw"], SLOT)

    def lay_direction(self, scene: Scene) -> jax.Array:
        """Unit vector (3,) along the slot in which the lying bottle's base points: the slot's axis
        (the rack's y) signed to point away from the robot's base."""
        yaw = scene.params["yaw"]
        axis = jnp.array([-jnp.sin(yaw), jnp.cos(yaw), 0.0])
        slot = self.slot_world(scene)
        return axis * jnp.where(jnp.dot(axis[:2], slot[:2]) >= 0, 1.0, -1.0)

    @staticmethod
    def grasp_yaw(u: jax.Array) -> jax.Array:
        """The top grasp's yaw for a bottle to be laid along u (at angle phi): fingers across u; of the
        two such yaws (the gripper is symmetric), phi - pi, whose roll about the fingers' axis keeps
        joints 2 and 7 off their limits (measured on 256 placements: 92 % of them reachable with
        phi - pi, 39 % with phi; with the base pointing towards the robot 41 % and 25 %)."""
        return jnp.arctan2(u[1], u[0]) - jnp.pi

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        b, slot = scene.params["bottle"], self.slot_world(scene)
        u = self.lay_direction(scene)
        top = down_quat(self.grasp_yaw(u))
        side = geo.quat_mul(geo.axis_angle_to_quat(jnp.cross(u, jnp.array([0.0, 0.0, 1.0])), jnp.pi / 2), top)
        grasp = b + jnp.array([0.0, 0.0, NECK_GRASP])
        above = grasp + jnp.array([0.0, 0.0, 0.1])
        lift = grasp + jnp.array([0.0, 0.0, 0.09])
        # lying: the bottle's axis along u from the neck; its centre NECK_GRASP - CENTRE beyond the tcp
        place = slot - (NECK_GRASP - CENTRE) * u + jnp.array([0.0, 0.0, 0.004])
        over = place + jnp.array([0.0, 0.0, 0.1])
        back = place - 0.08 * u + jnp.array([0.0, 0.0, 0.05])
        pos = jnp.stack([above, grasp, grasp, lift, over, place, place, back])
        quat = jnp.stack([top] * 4 + [side] * 4)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def is_success(self, progress, data, grasp, scene):
        rot = geo.quat_to_mat(data.mocap_quat[self.rack_mocap])
        centre = data.mocap_pos[self.rack_mocap] + rot @ jnp.asarray(SLOT)
        return in_box(data.site_xpos[self.centre_site], centre, rot, SLOT_HALF)
