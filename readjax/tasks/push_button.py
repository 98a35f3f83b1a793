"""PB — push button: press the red button on its base with the closed gripper.

RLBench (``rlbench/tasks/push_button.py``): success is ``ConditionSet([JointCondition(
target_button_joint, 0.003)])`` (l.39, 48-49), i.e. the button joint moved more than 3 mm from its
start (``backend/conditions.py:30-40``); no failure condition. The task overrides neither
``is_static_workspace`` nor ``base_rotation_bounds``, so the whole model (base and button) is placed
at a random workspace pose with yaw +-pi (``backend/scene.py:529-537``). Its 18 variations change
only the base colour; variation 0 (maroon) is the one we render.

readjax: the base and button are the task model; its bounding box is the 10 x 10 cm base, placed by
:func:`readjax.sim.placement.place_task` with yaw +-pi. Success: the slide joint more than 3 mm from
its start (latched like every condition). Sizes (RLBench's are in ``push_button.ttm``, unreadable
here): a square 30 x 30 mm cap (a common panel push button), 6 mm of travel with the 3 mm switch
point of RLBench's condition inside it, a 400 N/m spring unloaded at rest (1.2 N at the switch point,
2.4 N at the stop).

Expert: above the cap with the gripper closing, straight down, a hold, then back up. The press is
meant to go just past the switch point, not through the stroke: the pads' underside is commanded
PRESS_DEPTH = 6.8 mm below the cap's rest top, which moves the cap about 4.6 mm (measured: under the
spring's ~2 N the position servo stays ~0.7 mm above its target and the pad-cap contact of this
simulation overlaps ~1.6 mm), 1.6 mm past the switch point and 1.4 mm short of the stop. The margin
is what a replay of the recorded motion needs: replaying the measured hand path through IK presses
~1.3 mm less deep (the cap then moves ~3.4 mm), and ground-truth replay must still succeed. So a
plan whose press is ~0.4 mm shallower than the recording fails. Pressing top-down does not depend
on the yaw, so the hand keeps its home yaw.
"""

from __future__ import annotations

import jax.numpy as jnp

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim import placement
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, set_free_body

PRESSED = 0.003  # m the button joint must travel (RLBench's JointCondition)
TRAVEL = 0.006  # m to the end of the stroke (tasks_mjcf/push_button.xml)
CAP_TOP = 0.046  # cap top above the table at rest
PAD_HALF = 0.009  # finger pad half height below the tcp
FOOTPRINT = jnp.array([0.05, 0.05])  # the base's half size: the task's bounding box
PRESS_DEPTH = 0.0068  # pads' underside below the rest top (commanded): the cap moves ~4.6 mm (docstring)


class PushButton(TaskEnv):
    name = "push_button"
    code = "PB"
    xml = "push_button.xml"
    description = "press the red button on its base"
    fixtures = ("button_base",)
    expert_durations = (40, 25, 15, 20)  # above (gripper closing), press, hold, retreat

    def setup(self):
        m = self.mj_model
        self.base_qadr = free_adr(m, "button_base")
        self.button_qadr = int(m.joint("button").qposadr[0])

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, -FOOTPRINT, FOOTPRINT)
        scene = self.default_scene()
        pos = jnp.array([xy[0], xy[1], 0.0])
        qpos = set_free_body(scene.qpos, self.base_qadr, pos, geo.yaw_quat(yaw))
        return scene.replace(qpos=qpos, params={"button": pos, "yaw": yaw, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        b = scene.params["button"]
        above = b + jnp.array([0.0, 0.0, CAP_TOP + 0.08])
        press = b + jnp.array([0.0, 0.0, CAP_TOP + PAD_HALF - PRESS_DEPTH])
        pos = jnp.stack([above, press, press, above])
        quat = jnp.stack([down_quat(0.0)] * 4)
        return WaypointPlan(pos=pos, quat=quat, grip=jnp.zeros(4))

    def goal(self, scene):
        """The cap's top at rest: the base's origin raised by CAP_TOP."""
        return scene.qpos[..., self.base_qadr:self.base_qadr + 3] + jnp.array([0.0, 0.0, CAP_TOP])

    def move_goal(self, scene, delta):
        delta = jnp.asarray(delta, jnp.float32)
        qpos = jnp.asarray(scene.qpos).at[..., self.base_qadr:self.base_qadr + 3].add(delta)
        return scene.replace(qpos=qpos, params={**scene.params, "button": scene.params["button"] + delta})

    def is_success(self, progress, data, grasp, scene):
        """RLBench's JointCondition(target_button_joint, 0.003): moved more than 3 mm from its start."""
        return jnp.abs(data.qpos[self.button_qadr] - scene.qpos[self.button_qadr]) > PRESSED
