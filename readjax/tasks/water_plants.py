"""WP — water plants: pick up the watering can by its handle and pour onto the potted plant.

RLBench (``rlbench/tasks/water_plants.py``): can ("waterer", graspable) and plant are one rigid
model (no spawn boundary); no ``base_rotation_bounds`` override, so ``Scene._place_task`` places it
at a random workspace position with yaw +-pi. Until the can's spout ``head`` is detected by the
``pour_point`` sensor the success condition is "waterer detected by ``success``"; at the first step
the head is detected there, 5 dynamic 5 mm cubes ("drops") spawn at the head (position noise
sigma 0.5 mm) and fall, and success becomes "all 5 drops detected by ``success``". No tilt is
required, and there is no fail condition.

Here the task frame is the model's: the plant at (+0.15, 0), the can at (-0.15, 0) facing it (+x),
placed by :func:`readjax.sim.placement.place_task` with yaw +-pi; footprint x [-0.22, 0.21],
y [-0.06, 0.06] (tank, spout, pot and leaves). MJX cannot add bodies mid-episode and the task
hooks cannot move parked ones, so the drops live in the progress memory: at the first control
step where the spout tip (site ``spout_tip``, RLBench's ``head``) is inside the pour point, the 5
drops are released at the tip (offsets of 0.5 mm, RLBench's noise, as a fixed cross pattern). A
released drop falls straight down from rest (RLBench spawns them at rest), so it is detected by the
success sensor iff its xy is over the soil (within :data:`SOIL_R` of the pot's axis). Success:
before the release, the can's origin (its tank's bottom centre) in the success sensor; after it,
5 drops landed (checked at the release; the fall itself is not timed). Sizes (the .ttm is
unreadable; real-world sizes): pot radius 6 cm, soil radius 5.2 cm; success sensor = the soil, a
cylinder of radius 5.2 cm from 5 cm up to 9.5 cm (just under the soil's surface: the can's tank
collides with the pot, so the can cannot get into it); pour point = the space above the soil from
which water falls onto it, a cylinder of radius 4 cm (the soil's radius less the 1.2 cm of the
spout's rose) from 2 cm to 20 cm above the rim (z 0.12-0.30 m).

Expert: top-down grasp of the handle bar (fingers across it), lift, carry the can forward so the
spout tip is over the soil (this releases the drops), tilt it 40 degrees about the spout tip (two
waypoints, the tip staying over the soil), hold, tilt back.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import DOWN, free_adr, mocap_index, set_free_body

DROPS = 5
DROP_OFFSETS = np.array([[0, 0], [5e-4, 0], [-5e-4, 0], [0, 5e-4], [0, -5e-4]], np.float32)
SOIL_R = 0.052  # success sensor radius (the pot's inner radius)
SENSOR_Z = (0.05, 0.095)  # success sensor height range (the soil, under its surface)
POUR_R = 0.04  # pour point radius about the pot's axis
POUR_Z = (0.12, 0.30)  # pour point height range (rim at 0.10)
PLANT = np.array([0.15, 0.0, 0.0], np.float32)  # task frame
CAN = np.array([-0.15, 0.0, 0.0], np.float32)  # task frame, facing +x
FOOT_MIN = np.array([-0.22, -0.06], np.float32)
FOOT_MAX = np.array([0.21, 0.06], np.float32)
HANDLE = np.array([-0.02, 0.0, 0.175], np.float32)  # tcp in the can frame when holding the handle
TIP = np.array([0.19, 0.0, 0.12], np.float32)  # spout tip in the can frame
TILT = np.deg2rad(40.0)  # not required (RLBench has no tilt term); reachable in 96 % of placements, 89 % at 50
TIP_Z = 0.19  # spout tip height while pouring
TIP_BACK = 0.02  # aim this far from the pot axis, on the can's side
DROP = 0.0005


def rot_y(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    z, o = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack([c, z, s, z, o, z, -s, z, c], axis=-1).reshape(jnp.shape(angle) + (3, 3))


def in_cylinder(point, axis_xy, radius, z_range):
    return ((jnp.linalg.norm(point[..., :2] - axis_xy, axis=-1) < radius)
            & (point[..., 2] > z_range[0]) & (point[..., 2] < z_range[1]))


class WaterPlants(TaskEnv):
    name = "water_plants"
    code = "WP"
    xml = "water_plants.xml"
    description = "pick up the watering can and water the plant"
    graspable = ("can",)
    # above, descend, close, lift, carry, tilt half, tilt full, pour, tilt back
    expert_durations = (40, 20, 25, 20, 50, 20, 15, 15, 20)

    def setup(self):
        m = self.mj_model
        self.can_qadr = free_adr(m, "can")
        self.plant_mocap = mocap_index(m, "plant")
        self.tip_site = m.site("spout_tip").id

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, FOOT_MIN, FOOT_MAX)
        can = placement.to_world(xy, yaw, CAN)
        pot = placement.to_world(xy, yaw, PLANT)
        scene = self.default_scene()
        quat = geo.yaw_quat(yaw)
        qpos = set_free_body(scene.qpos, self.can_qadr, can + jnp.array([0.0, 0.0, DROP]), quat)
        mpos = scene.mocap_pos.at[self.plant_mocap].set(pot)
        mquat = scene.mocap_quat.at[self.plant_mocap].set(quat)
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"can": can, "yaw": yaw, "pot": pot, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        can, yaw, pot = scene.params["can"], scene.params["yaw"], scene.params["pot"]
        # the hand's yaw about its axis is free up to pi (symmetric fingers): keep joint 7 mid-range
        # (q7 ~ 0.785 + atan2(y, x) - hand yaw at a down-pointing tcp) at the can
        mid = jnp.arctan2(can[1], can[0]) + 0.785
        flip = jnp.abs((yaw - mid + jnp.pi) % (2 * jnp.pi) - jnp.pi) > jnp.pi / 2
        rel = geo.quat_to_mat(geo.quat_mul(geo.yaw_quat(jnp.where(flip, jnp.pi, 0.0)), DOWN))

        def tcp(origin, rot):
            return origin + rot @ jnp.asarray(HANDLE), geo.mat_to_quat(rot @ rel)

        r0 = geo.rot_z(yaw)
        g_pos, g_quat = tcp(can, r0)
        aim = pot + jnp.array([-TIP_BACK * jnp.cos(yaw), -TIP_BACK * jnp.sin(yaw), TIP_Z])

        def pour_pose(tilt, rise):
            rot = r0 @ rot_y(tilt)
            origin = aim + jnp.array([0.0, 0.0, rise]) - rot @ jnp.asarray(TIP)
            return tcp(origin, rot)

        up = jnp.array([0.0, 0.0, 1.0])
        p_pre, q_pre = pour_pose(0.0, 0.06)
        p_half, q_half = pour_pose(TILT / 2, 0.02)
        p_full, q_full = pour_pose(TILT, 0.0)
        pos = jnp.stack([g_pos + 0.10 * up, g_pos, g_pos, g_pos + 0.15 * up,
                         p_pre, p_half, p_full, p_full, p_pre])
        quat = jnp.stack([g_quat, g_quat, g_quat, g_quat, q_pre, q_half, q_full, q_full, q_pre])
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    # ------------------------------------------------------------------ predicates
    def tip(self, data) -> jax.Array:
        return data.site_xpos[self.tip_site]

    def at_pour_point(self, data, scene: Scene) -> jax.Array:
        """RLBench's ``DetectedCondition(head, pour_point)``: the spout tip in the pour point."""
        return in_cylinder(self.tip(data), scene.params["pot"][:2], POUR_R, POUR_Z)

    def init_progress(self):
        return {"released": jnp.zeros((), bool), "landed": jnp.zeros((), jnp.int32)}

    def update_progress(self, progress, data, grasp, scene):
        release = ~progress["released"] & self.at_pour_point(data, scene)
        drops = self.tip(data)[:2] + jnp.asarray(DROP_OFFSETS)  # fall straight down from rest
        lands = jnp.linalg.norm(drops - scene.params["pot"][:2], axis=-1) < SOIL_R
        landed = jnp.where(release, jnp.sum(lands).astype(jnp.int32), progress["landed"])
        return {"released": progress["released"] | release, "landed": landed}

    def is_success(self, progress, data, grasp, scene):
        can = data.qpos[self.can_qadr:self.can_qadr + 3]
        can_in_sensor = in_cylinder(can, scene.params["pot"][:2], SOIL_R, SENSOR_Z)
        return jnp.where(progress["released"], progress["landed"] >= DROPS, can_in_sensor)
