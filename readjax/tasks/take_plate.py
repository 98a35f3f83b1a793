"""TP — take plate: take the plate out of the dish rack and put it on top of the blue cube.

RLBench's ``take_plate_off_colored_dish_rack`` (``rlbench/tasks/take_plate_off_colored_dish_rack.py``):
3 variations = the rack slot the plate stands in (l.8, 26-30); no ``SpawnBoundary``, so the rack,
the target and the sensors form one rigid model, placed as a whole by ``Scene._place_task`` with the
default ``base_rotation_bounds`` +-3.14; success = plate NOT detected by ``success_source`` AND
detected by ``success_target`` AND NothingGrasped (l.18-23). The target is the paper's: "place it on
top of a blue cube". Here:

* Task frame (:func:`readjax.sim.placement.place_task`, yaw +-pi): the rack centred at (0, -0.15)
  with its slots along x (offsets -0.04, 0, 0.04; the plates' faces along x), the cube (rigid in the
  model, as RLBench's target) centred at (0, 0.15); footprint x [-0.08, 0.08] x y [-0.25, 0.20].
* Variation: the slot, drawn per episode (all 3 variations in one split; RLBench keeps one per
  variation index).
* Success: ``success_source`` = the rack's volume (0.16 x 0.2 x 0.2 m), ``success_target`` = a
  cylinder of radius 0.045 m over the cube from its top face to 0.04 m above, both tested on the
  plate centre (its body origin); AND nothing grasped.
* Sizes (real-world; RLBench's are in the unreadable .ttm): an 18 cm plate, a 16 x 20 cm dish rack,
  a 10 cm cube (the hand, fingers vertical, spans 0.24 m and must clear the table at release).

Expert: top-down grasp on the upright plate's top rim (fingers across the plate), lift it straight
up out of the slot, carry it over the cube while turning the hand to point sideways (fingers
vertical) so that the plate lies flat in front of the fingers, lower it to ~2.5 cm above the cube,
open, back off. The plate is round, so the hand's heading at the cube is free: of a few headings
(+-40 or +-75 deg from the cube's bearing) and the two finger signs at the pick, the expert takes
the one its IK follows best (:meth:`TakePlate.choose`).
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

SLOTS = np.array([-0.04, 0.0, 0.04], np.float32)  # slot offsets along the rack's x from its centre
RACK_LOCAL = np.array([0.0, -0.15], np.float32)  # rack centre in the task frame
CUBE_LOCAL = np.array([0.0, 0.15], np.float32)  # cube centre in the task frame
FOOTPRINT_MIN, FOOTPRINT_MAX = np.array([-0.08, -0.25], np.float32), np.array([0.08, 0.20], np.float32)
PLATE_UP_Z = 0.0831  # plate centre height when standing in the rack (flat edge on the table)
GRASP_R = 0.07  # tcp distance from the plate centre (on the rim side)
LIFT = 0.12  # straight lift out of the slot
CUBE = 0.10  # cube edge length
RELEASE_Z = 0.13  # tcp height at release: the plate ~2.5 cm above the cube
TARGET_RADIUS = 0.045  # plate centre within this distance of the cube's axis
TARGET_HEIGHT = 0.04  # ... and at most this far above its top face
# the expert's choices: finger sign at the pick, side of the heading at the cube, heading angle
COMBOS = np.array(list(itertools.product((1.0, -1.0), (1.0, -1.0), (0.7, 1.3))), np.float32)


def task_to_world(origin, yaw, local):
    """A task-frame point (2,) -> world (3,) on the table (:func:`readjax.sim.placement.to_world`)."""
    return placement.to_world(origin, yaw, jnp.stack([local[0], local[1], jnp.zeros_like(yaw)]))


class TakePlate(TaskEnv):
    name = "take_plate"
    code = "TP"
    xml = "take_plate.xml"
    description = "take the plate out of the dish rack and put it on top of the blue cube"
    graspable = ("plate",)
    # above, descend, close, lift, carry+turn, lower, settle, open, back off
    expert_durations = (40, 20, 25, 30, 60, 25, 8, 15, 20)

    def setup(self):
        m = self.mj_model
        self.plate_qadr = free_adr(m, "plate")
        self.rack_mocap = mocap_index(m, "rack")
        self.cube_mocap = mocap_index(m, "cube")
        self.guard_mocap = mocap_index(m, "slot_guard")
        site = m.site("rack_region")
        self.rack_region_pos = np.array(site.pos, np.float32)  # in the rack's frame
        self.rack_region_half = np.array(site.size, np.float32)
        self.plate_quat0 = np.array(m.body("plate").quat, np.float32)  # upright, facing the rack's x

    def draw_scene(self, key):
        k_task, k_slot = jax.random.split(key)
        origin, yaw, fits = placement.place_task(k_task, FOOTPRINT_MIN, FOOTPRINT_MAX)
        slot = jax.random.randint(k_slot, (), 0, len(SLOTS))
        rack = task_to_world(origin, yaw, RACK_LOCAL)
        cube = task_to_world(origin, yaw, CUBE_LOCAL)
        plate = task_to_world(origin, yaw, jnp.asarray(RACK_LOCAL) + jnp.stack([jnp.asarray(SLOTS)[slot], 0.0]))
        q = geo.yaw_quat(yaw)
        scene = self.default_scene()
        idx = jnp.array([self.rack_mocap, self.cube_mocap, self.guard_mocap])
        mocap_pos = scene.mocap_pos.at[idx].set(jnp.stack([rack, cube, plate]))
        mocap_quat = scene.mocap_quat.at[idx].set(jnp.stack([q, q, q]))
        qpos = set_free_body(scene.qpos, self.plate_qadr, plate + jnp.array([0.0, 0.0, PLATE_UP_Z]),
                             geo.quat_mul(q, jnp.asarray(self.plate_quat0)))
        return scene.replace(qpos=qpos, mocap_pos=mocap_pos, mocap_quat=mocap_quat,
                             params={"slot": slot, "plate": plate, "cube": cube, "rack": rack, "yaw": yaw,
                                     "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    # ------------------------------------------------------------------ expert
    def plan_with(self, scene: Scene, combo) -> WaypointPlan:
        sigma, side, rel = combo[0], combo[1], combo[2]
        yaw, cube = scene.params["yaw"], scene.params["cube"]
        # pick: fingers along the plate's normal (the rack's x), sign sigma
        down = down_quat(yaw - sigma * jnp.pi / 2)
        grasp = scene.params["plate"] + jnp.array([0.0, 0.0, PLATE_UP_Z + GRASP_R])
        lifted = grasp + jnp.array([0.0, 0.0, LIFT])
        # place: the hand horizontal, heading d (rel from the cube's bearing), fingers vertical
        head = jnp.arctan2(cube[1], cube[0]) + side * rel
        d = jnp.stack([jnp.cos(head), jnp.sin(head), 0.0])
        y = jnp.array([0.0, 0.0, -1.0]) * side
        flat = geo.mat_to_quat(jnp.stack([jnp.cross(y, d), y, d], -1))
        place = cube + jnp.array([0.0, 0.0, RELEASE_Z]) - GRASP_R * d  # plate centre over the cube's
        over = place + jnp.array([0.0, 0.0, 0.1])
        back = place - 0.06 * d + jnp.array([0.0, 0.0, 0.04])
        above = grasp + jnp.array([0.0, 0.0, 0.1])
        pos = jnp.stack([above, grasp, grasp, lifted, over, place, place, place, back])
        quat = jnp.stack([down] * 4 + [flat] * 5)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        """Of the symmetric options (``COMBOS``), the one the arm follows most easily."""
        return self.easiest_plan(jax.vmap(lambda c: self.plan_with(scene, c))(jnp.asarray(COMBOS)))

    # ------------------------------------------------------------------ predicates
    def plate_pos(self, data) -> jax.Array:
        return data.qpos[self.plate_qadr:self.plate_qadr + 3]

    def in_rack(self, data) -> jax.Array:
        rot = geo.quat_to_mat(data.mocap_quat[self.rack_mocap])
        centre = data.mocap_pos[self.rack_mocap] + rot @ jnp.asarray(self.rack_region_pos)
        return in_box(self.plate_pos(data), centre, rot, self.rack_region_half)

    def on_cube(self, data, scene) -> jax.Array:
        p = self.plate_pos(data)
        c = data.mocap_pos[self.cube_mocap]
        above = p[2] - (c[2] + CUBE)
        return (jnp.linalg.norm(p[:2] - c[:2]) <= TARGET_RADIUS) & (above >= 0.0) & (above <= TARGET_HEIGHT)

    def is_success(self, progress, data, grasp, scene):
        return ~self.in_rack(data) & self.on_cube(data, scene) & ~grasp.any
