"""RT — reach target: put the gripper tip inside the red sphere, ignoring two distractors."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import down_quat, mocap_index

RADIUS = 0.03
LOW, HIGH = (0.3, -0.3, 0.12), (0.7, 0.3, 0.45)
MIN_DIST = 0.2


class ReachTarget(TaskEnv):
    name = "reach_target"
    code = "RT"
    xml = "reach_target.xml"
    description = "move the gripper tip into the red sphere; two other spheres are distractors"
    recolour_geoms = ("distractor0", "distractor1")
    expert_durations = (45, 10)  # reach, settle

    def setup(self):
        m = self.mj_model
        self.target_mocap = mocap_index(m, "target")
        self.distractor_mocap = [mocap_index(m, f"distractor{i}") for i in range(2)]
        self.tcp_site = m.site("tcp").id

    def sample_scene(self, key):
        k_pos, k_col = jax.random.split(key)
        pts = sampling.separated_points(k_pos, 3, LOW, HIGH, MIN_DIST)
        scene = self.default_scene()
        mocap = scene.mocap_pos.at[self.target_mocap].set(pts[0])
        mocap = mocap.at[jnp.array(self.distractor_mocap)].set(pts[1:])
        return scene.replace(mocap_pos=mocap, rgba=sampling.distractor_colours(k_col, 2),
                             params={"target": pts[0]})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        target = scene.params["target"]
        pos = jnp.stack([target, target])
        quat = jnp.stack([down_quat(0.0)] * 2)
        return WaypointPlan(pos=pos, quat=quat, grip=jnp.ones(2))

    def landmarks(self, scene):
        return {"target": scene.mocap_pos[self.target_mocap][None],
                "distractor": scene.mocap_pos[jnp.array(self.distractor_mocap)]}

    def goal(self, scene):
        return scene.mocap_pos[..., self.target_mocap, :]

    def move_goal(self, scene, delta):
        delta = jnp.asarray(delta, jnp.float32)
        mocap = jnp.asarray(scene.mocap_pos).at[..., self.target_mocap, :].add(delta)
        return scene.replace(mocap_pos=mocap, params={**scene.params, "target": scene.params["target"] + delta})

    def is_success(self, progress, data, grasp, scene):
        tip = data.site_xpos[self.tcp_site]
        return jnp.linalg.norm(tip - data.mocap_pos[self.target_mocap]) < RADIUS
