"""PC — pick up cup: grasp the red cup by its rim and lift it; the other cup is a distractor."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import down_quat, free_adr, set_free_body

LIFT = 0.1  # m above the start height
WALL_CENTRE = 0.0345  # radius of the wall boxes' centres
RIM = 0.09
LOW, HIGH = (0.38, -0.25), (0.65, 0.25)
MIN_DIST = 0.15


class PickUpCup(TaskEnv):
    name = "pick_up_cup"
    code = "PC"
    xml = "pick_up_cup.xml"
    description = "grasp and lift the red cup; the other cup is a distractor"
    graspable = ("cup", "distractor")
    recolour_geoms = ("distractor_bottom",) + tuple(f"distractor_wall{k}" for k in range(8))
    expert_durations = (45, 25, 25, 35, 10)  # above, descend, close, lift, hold

    def setup(self):
        m = self.mj_model
        self.cup_qadr = free_adr(m, "cup")
        self.distractor_qadr = free_adr(m, "distractor")
        self.cup_body = m.body("cup").id

    def sample_scene(self, key):
        k_pos, k_col = jax.random.split(key)
        xy = sampling.separated_points(k_pos, 2, LOW, HIGH, MIN_DIST)
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.cup_qadr, jnp.array([xy[0, 0], xy[0, 1], 0.0]),
                             jnp.array([1.0, 0, 0, 0]))
        qpos = set_free_body(qpos, self.distractor_qadr, jnp.array([xy[1, 0], xy[1, 1], 0.0]),
                             jnp.array([1.0, 0, 0, 0]))
        colour = sampling.distractor_colours(k_col, 1)
        rgba = jnp.tile(colour, (len(self.recolour_geoms), 1))
        return scene.replace(qpos=qpos, rgba=rgba, params={"cup": jnp.array([xy[0, 0], xy[0, 1], 0.0])})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        cup = scene.params["cup"]
        grasp = cup + jnp.array([-WALL_CENTRE, 0.0, RIM - 0.02])
        above = grasp + jnp.array([0.0, 0.0, 0.12])
        lift = grasp + jnp.array([0.0, 0.0, 0.2])
        pos = jnp.stack([above, grasp, grasp, lift, lift])
        quat = jnp.stack([down_quat(jnp.pi / 2)] * 5)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def is_success(self, progress, data, grasp, scene):
        z = data.qpos[self.cup_qadr + 2]
        return grasp.attached[0] & (z > LIFT)

    def is_failure(self, progress, data, grasp, scene):
        return grasp.attached[1]
