"""PB — push button: press the button on its base with the closed gripper."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, set_free_body

PRESSED = 0.003  # m the button joint must travel
CAP_TOP = 0.046  # cap top above the table at rest
PAD_HALF = 0.009  # finger pad half height below the tcp
PRESS_DEPTH = 0.016  # past the 12 mm travel: the recorded (measured) press goes all the way


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

    def sample_scene(self, key):
        k_xy, k_yaw = jax.random.split(key)
        xy = jax.random.uniform(k_xy, (2,), minval=jnp.array([0.35, -0.25]), maxval=jnp.array([0.65, 0.25]))
        yaw = jax.random.uniform(k_yaw, (), minval=-jnp.pi, maxval=jnp.pi)
        scene = self.default_scene()
        pos = jnp.array([xy[0], xy[1], 0.0])
        qpos = set_free_body(scene.qpos, self.base_qadr, pos, geo.yaw_quat(yaw))
        return scene.replace(qpos=qpos, params={"button": pos, "yaw": yaw})

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
        return data.qpos[self.button_qadr] < -PRESSED
