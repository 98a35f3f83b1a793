"""WP — water plants: pick up the watering can by its handle and pour onto the potted plant.

RLBench's ``water_plants`` spawns 5 drops at the spout once the spout reaches a pour point and
succeeds when all 5 are in the pot. MJX cannot add bodies mid-episode and the task hooks cannot
move parked ones, so the drops are modelled in the progress memory instead: while the can is
tilted spout-down (its forward axis more than :data:`POUR_TILT` below horizontal) it releases one
drop per control step, 5 in all; a drop falls straight down, so it lands in the pot iff the spout
tip is then over the soil (horizontal distance to the pot axis < :data:`POT_RADIUS`, tip height
between the rim and 0.30 m above it). Success: 5 drops landed. Failure (sticky): all 5 released
and at least one spilled.

Expert: top-down grasp of the handle bar (fingers across it), lift, carry the can to face the
plant with the spout tip over the pot, tilt it 50 degrees about the spout tip (two waypoints so
the tip stays over the soil), hold while it pours, tilt back.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import DOWN, free_adr, mocap_index, set_free_body

DROPS = 5
POUR_TILT = np.deg2rad(30.0)
POT_RADIUS = 0.05  # drops landing inside this horizontal radius go into the pot (inner radius 5.2 cm)
RIM_Z = 0.10
POUR_TOP = RIM_Z + 0.30
HANDLE = np.array([-0.02, 0.0, 0.175], np.float32)  # tcp in the can frame when holding the handle
TIP = np.array([0.19, 0.0, 0.12], np.float32)  # spout tip in the can frame
TILT = np.deg2rad(50.0)
TIP_Z = 0.19  # spout tip height while pouring
TIP_BACK = 0.02  # aim this far from the pot axis, on the can's side
LOW, HIGH = (0.35, -0.28), (0.65, 0.28)
MIN_DIST = 0.30
YAW_RANGE = np.pi / 4
DROP = 0.0005


def rot_y(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    z, o = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack([c, z, s, z, o, z, -s, z, c], axis=-1).reshape(jnp.shape(angle) + (3, 3))


def wrap(a):
    return (a + jnp.pi) % (2 * jnp.pi) - jnp.pi


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

    def sample_scene(self, key):
        k_pos, k_yaw = jax.random.split(key)
        xy = sampling.separated_points(k_pos, 2, LOW, HIGH, MIN_DIST)
        can, pot = jnp.append(xy[0], 0.0), jnp.append(xy[1], 0.0)
        heading = jnp.arctan2(pot[1] - can[1], pot[0] - can[0])
        yaw = heading + jax.random.uniform(k_yaw, (), minval=-YAW_RANGE, maxval=YAW_RANGE)
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.can_qadr, can + jnp.array([0.0, 0.0, DROP]), geo.yaw_quat(yaw))
        mpos = scene.mocap_pos.at[self.plant_mocap].set(pot)
        return scene.replace(qpos=qpos, mocap_pos=mpos, params={"can": can, "yaw": yaw, "pot": pot})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        can, yaw, pot = scene.params["can"], scene.params["yaw"], scene.params["pot"]
        heading = jnp.arctan2(pot[1] - can[1], pot[0] - can[0])
        turn = wrap(heading - yaw)
        # the hand's yaw about its axis is free up to pi (symmetric fingers): keep the wrist mid-range
        # (joint 7 = 0.785 - hand yaw, limits +-2.9) over the whole turn
        flip = jnp.abs(wrap(yaw + turn / 2 - 0.5)) > jnp.pi / 2
        rel = geo.quat_to_mat(geo.quat_mul(geo.yaw_quat(jnp.where(flip, jnp.pi, 0.0)), DOWN))

        def tcp(origin, rot):
            return origin + rot @ jnp.asarray(HANDLE), geo.mat_to_quat(rot @ rel)

        r0 = geo.rot_z(yaw)
        g_pos, g_quat = tcp(can, r0)
        aim = pot + jnp.array([-TIP_BACK * jnp.cos(heading), -TIP_BACK * jnp.sin(heading), TIP_Z])

        def pour_pose(tilt, rise):
            rot = geo.rot_z(heading) @ rot_y(tilt)
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
    def pouring(self, data, scene: Scene) -> tuple[jax.Array, jax.Array]:
        """(can tilted spout-down, spout tip over the soil)."""
        a = self.can_qadr
        forward = geo.quat_to_mat(data.qpos[a + 3:a + 7])[:, 0]
        tilted = forward[2] < -jnp.sin(POUR_TILT)
        tip = data.site_xpos[self.tip_site]
        pot = scene.params["pot"]
        over = (jnp.linalg.norm(tip[:2] - pot[:2]) < POT_RADIUS) & (tip[2] > RIM_Z) & (tip[2] < POUR_TOP)
        return tilted, over

    def init_progress(self):
        return {"released": jnp.zeros((), jnp.int32), "landed": jnp.zeros((), jnp.int32)}

    def update_progress(self, progress, data, grasp, scene):
        tilted, over = self.pouring(data, scene)
        drop = tilted & (progress["released"] < DROPS)
        return {"released": progress["released"] + drop.astype(jnp.int32),
                "landed": progress["landed"] + (drop & over).astype(jnp.int32)}

    def is_success(self, progress, data, grasp, scene):
        return progress["landed"] >= DROPS

    def is_failure(self, progress, data, grasp, scene):
        return (progress["released"] >= DROPS) & (progress["landed"] < DROPS)
