"""TP — take plate: take the plate out of the dish rack and put it on top of the blue cube.

RLBench's ``take_plate_off_colored_dish_rack`` (plate in one of the rack's slots; success = plate
not detected by the rack's sensor AND detected by the target sensor AND nothing grasped), with the
target of the READ paper: the top of a blue cube. Regions are tested on the plate centre (its
body origin): the rack region is the rack's volume (0.16 x 0.2 x 0.2 m), the target region a
cylinder of radius 0.045 m over the cube, from its top face to 0.04 m above it.

Expert: top-down grasp on the upright plate's top rim (fingers across the plate), lift it
straight up out of the slot, carry it to the cube while turning the hand to point sideways
(tcp along +y, fingers vertical) so that the plate lies flat in front of the fingers, lower it to
~2.5 cm above the cube and open (the hand's 0.24 m span along the fingers must stay above the
table, hence the release height and the cube's 0.10 m size), back off. Pointing the hand forward
instead is outside the Panda's reach at that height.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

SLOTS = np.array([-0.04, 0.0, 0.04], np.float32)  # slot offsets along x from the rack centre
PLATE_UP_Z = 0.0831  # plate centre height when standing in the rack (flat edge on the table)
GRASP_R = 0.07  # tcp distance from the plate centre (on the rim side)
LIFT = 0.12  # straight lift out of the slot
CUBE = 0.10  # cube edge length
CUBE_LOW, CUBE_HIGH = (0.45, 0.05), (0.65, 0.25)
RELEASE_Z = 0.13  # tcp height at release: the plate ~2.5 cm above the cube
TARGET_RADIUS = 0.045  # plate centre within this distance of the cube's axis
TARGET_HEIGHT = 0.04  # ... and at most this far above its top face
# Tcp orientation with the plate flat: z along +y (plate ahead of the fingers), fingers vertical.
_FLAT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], np.float32)  # columns x, y, z


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
        self.cube_mocap = mocap_index(m, "cube")
        self.guard_mocap = mocap_index(m, "slot_guard")
        self.rack_pos = np.array(m.body("rack").pos, np.float32)
        site = m.site("rack_region")
        self.rack_region_pos = self.rack_pos + np.array(site.pos, np.float32)
        self.rack_region_half = np.array(site.size, np.float32)
        self.plate_quat0 = np.array(m.body("plate").quat, np.float32)  # upright, facing +x

    def sample_scene(self, key):
        k_slot, k_xy, k_yaw = jax.random.split(key, 3)
        slot = jax.random.randint(k_slot, (), 0, len(SLOTS))
        plate = jnp.asarray(self.rack_pos) + jnp.array([1.0, 0.0, 0.0]) * jnp.asarray(SLOTS)[slot]
        xy = jax.random.uniform(k_xy, (2,), minval=jnp.array(CUBE_LOW), maxval=jnp.array(CUBE_HIGH))
        yaw = jax.random.uniform(k_yaw, (), minval=-jnp.pi / 4, maxval=jnp.pi / 4)
        cube = jnp.array([xy[0], xy[1], 0.0])
        scene = self.default_scene()
        mocap_pos = scene.mocap_pos.at[self.cube_mocap].set(cube).at[self.guard_mocap].set(plate)
        mocap_quat = scene.mocap_quat.at[self.cube_mocap].set(geo.yaw_quat(yaw))
        qpos = set_free_body(scene.qpos, self.plate_qadr, plate + jnp.array([0.0, 0.0, PLATE_UP_Z]),
                             jnp.asarray(self.plate_quat0))
        return scene.replace(qpos=qpos, mocap_pos=mocap_pos, mocap_quat=mocap_quat,
                             params={"slot": slot, "plate": plate, "cube": cube, "yaw": yaw})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        grasp = scene.params["plate"] + jnp.array([0.0, 0.0, PLATE_UP_Z + GRASP_R])
        lifted = grasp + jnp.array([0.0, 0.0, LIFT])
        # plate centre over the cube's centre: the tcp sits GRASP_R behind it (-y)
        place = scene.params["cube"] + jnp.array([0.0, -GRASP_R, RELEASE_Z])
        over = place + jnp.array([0.0, 0.0, 0.1])
        back = place + jnp.array([0.0, -0.06, 0.04])
        down = down_quat(jnp.pi / 2)  # fingers along x, across the plate
        flat = geo.mat_to_quat(jnp.asarray(_FLAT))
        above = grasp + jnp.array([0.0, 0.0, 0.1])
        pos = jnp.stack([above, grasp, grasp, lifted, over, place, place, place, back])
        quat = jnp.stack([down, down, down, down, flat, flat, flat, flat, flat])
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    # ------------------------------------------------------------------ predicates
    def plate_pos(self, data) -> jax.Array:
        return data.qpos[self.plate_qadr:self.plate_qadr + 3]

    def in_rack(self, data) -> jax.Array:
        centre = jnp.asarray(self.rack_region_pos)
        return in_box(self.plate_pos(data), centre, jnp.eye(3), self.rack_region_half)

    def on_cube(self, data, scene) -> jax.Array:
        p = self.plate_pos(data)
        c = data.mocap_pos[self.cube_mocap]
        above = p[2] - (c[2] + CUBE)
        return (jnp.linalg.norm(p[:2] - c[:2]) <= TARGET_RADIUS) & (above >= 0.0) & (above <= TARGET_HEIGHT)

    def is_success(self, progress, data, grasp, scene):
        return ~self.in_rack(data) & self.on_cube(data, scene) & ~grasp.any
