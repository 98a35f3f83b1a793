"""SW — stack wine: lay the upright bottle on its side in the rack's fixed slot.

RLBench's ``stack_wine`` checks the bottle with a proximity sensor in one fixed slot of the
rack; here the sensor is the box site ``slot_region`` (in the rack frame, around the slot
nearest the robot) and the detected point is the middle of the bottle's body (site
``bottle_centre``). The region is only 5 cm high at the height of a lying bottle's axis, so an
upright bottle can never be "in" it. As in RLBench, success does not require the gripper to be
empty (the expert lets go anyway).

The slots run along world y (the rack is not yawed): the controller's IK (warm-started, pulled
towards the home posture) turns a top-down grasp into a sideways-pointing hand (tcp z along +y)
smoothly anywhere in the workspace, while it cannot track a forward-pointing (+x) hand near the
table (joints 2 and 6 run into their limits). Expert: grasp the neck from above, lift, roll
the hand 90 degrees about world x (the bottle comes down on its side, base towards +y) while
moving over the slot, lower it onto the rails, open, back away.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

SLOT = np.array([-0.1, 0.0, 0.077], np.float32)  # target slot centre in the rack frame (site slot_region)
SLOT_HALF = np.array([0.025, 0.05, 0.025], np.float32)
NECK_GRASP = 0.272  # tcp height on the neck of the upright bottle (bottle frame)
CENTRE = 0.12  # the body's middle (site bottle_centre), bottle frame
RACK_LOW, RACK_HIGH = (0.46, 0.08), (0.56, 0.2)
BOTTLE_X = (0.36, 0.62)
BOTTLE_Y_MIN = -0.3
RACK_GAP = 0.22  # the bottle stands at least this far (in y) on the -y side of the rack centre
# tcp pointing along +y with the fingers along world x: top-down (fingers along x) rolled about x.
# The grasp yaw -pi/2 (not +pi/2: same fingers, joint 7 half a turn away) keeps the IK path away
# from joint 2's limit during the roll (checked on 512 seeds).
TOP = down_quat(-jnp.pi / 2)
SIDE = geo.quat_mul(geo.axis_angle_to_quat(jnp.array([1.0, 0.0, 0.0]), jnp.pi / 2), TOP)


class StackWine(TaskEnv):
    name = "stack_wine"
    code = "SW"
    xml = "stack_wine.xml"
    description = "lay the wine bottle on its side in the rack's slot nearest the robot"
    graspable = ("bottle",)
    # above, descend, close, lift, roll over the slot, lower, open, back away
    expert_durations = (40, 20, 25, 20, 50, 20, 15, 15)

    def setup(self):
        m = self.mj_model
        self.bottle_qadr = free_adr(m, "bottle")
        self.rack_mocap = mocap_index(m, "rack")
        self.centre_site = m.site("bottle_centre").id

    def sample_scene(self, key):
        k_rack, k_bx, k_by, k_yaw = jax.random.split(key, 4)
        rack = jax.random.uniform(k_rack, (2,), minval=jnp.array(RACK_LOW), maxval=jnp.array(RACK_HIGH))
        bx = jax.random.uniform(k_bx, (), minval=BOTTLE_X[0], maxval=BOTTLE_X[1])
        by = jax.random.uniform(k_by, (), minval=BOTTLE_Y_MIN, maxval=rack[1] - RACK_GAP)
        yaw = jax.random.uniform(k_yaw, (), minval=-jnp.pi, maxval=jnp.pi)
        scene = self.default_scene()
        bottle = jnp.array([bx, by, 0.0])
        qpos = set_free_body(scene.qpos, self.bottle_qadr, bottle, geo.yaw_quat(yaw))
        rack_pos = jnp.array([rack[0], rack[1], 0.0])
        mocap = scene.mocap_pos.at[self.rack_mocap].set(rack_pos)
        return scene.replace(qpos=qpos, mocap_pos=mocap, params={"bottle": bottle, "rack": rack_pos})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        b, slot = scene.params["bottle"], scene.params["rack"] + jnp.asarray(SLOT)
        grasp = b + jnp.array([0.0, 0.0, NECK_GRASP])
        above = grasp + jnp.array([0.0, 0.0, 0.1])
        lift = grasp + jnp.array([0.0, 0.0, 0.09])
        # lying: the bottle axis along +y from the neck; its centre NECK_GRASP - CENTRE beyond the tcp
        place = slot + jnp.array([0.0, -(NECK_GRASP - CENTRE), 0.004])
        over = place + jnp.array([0.0, 0.0, 0.1])
        back = place + jnp.array([0.0, -0.08, 0.05])
        pos = jnp.stack([above, grasp, grasp, lift, over, place, place, back])
        quat = jnp.stack([TOP] * 4 + [SIDE] * 4)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def is_success(self, progress, data, grasp, scene):
        centre = data.mocap_pos[self.rack_mocap] + jnp.asarray(SLOT)
        return in_box(data.site_xpos[self.centre_site], centre, jnp.eye(3), SLOT_HALF)
