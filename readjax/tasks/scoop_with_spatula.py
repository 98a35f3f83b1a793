"""SS — scoop with spatula: grab the spatula, slide it under the cube with momentum, lift the cube.

RLBench's ``scoop_with_spatula``: success = the cube detected by the sensor above the spatula's
blade AND the spatula grasped. Here the sensor is a region fixed to the spatula: the blade's
footprint, from its top face to 4 cm above it, tested on the cube centre; "lifted" adds that the
cube centre is more than 5 cm above the table (so a cube merely touching a blade lying on the
table does not count). Only the spatula is graspable, so the cube cannot be picked and placed.

Expert: top-down grasp on the handle (fingers across it), lift, turn the spatula to point away
from the robot, square to a face of the cube, with the blade pitched 10 deg tip-down; lower it
behind the cube with the blade's leading edge 3 mm below the table surface (the blade has no
contact with the table, and a grasped body follows the hand kinematically), so the cube meets the
blade's sloped top face rather than its edge; a fast ~0.09 m stroke (0.28 s, ~0.5 m/s peak)
under the cube; then lift it while levelling the blade. All spatula waypoints are mapped to tcp
waypoints through the planned grasp transform.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import DOWN, free_adr, set_free_body

BLADE_HALF = np.array([0.05, 0.035, 0.0015], np.float32)
CUBE_HALF = 0.02
GRASP = np.array([-0.1563, 0.0, 0.0365], np.float32)  # tcp in the spatula frame (on the handle)
SPATULA_LOW, SPATULA_HIGH = (0.5, 0.12), (0.62, 0.28)
SPATULA_YAW = np.pi / 6
CUBE_LOW, CUBE_HIGH = (0.55, -0.22), (0.66, 0.0)
PITCH = np.deg2rad(10.0)  # blade tip-down angle while scooping
DEPTH = 0.003  # leading top edge of the blade below the table surface
START_GAP = 0.02  # leading edge this far before the cube at the start of the stroke
PUSH_END = 0.0  # blade centre target at the stroke's end, past the cube centre (the arm lags ~2 cm)
LIFTED = 0.05  # cube centre height for "lifted"
REGION_HEIGHT = 0.04


def _pitch_quat(angle) -> jax.Array:
    """Rotation about y by ``angle`` (positive: the blade's +x end goes down)."""
    a = jnp.asarray(angle, jnp.float32) / 2
    return jnp.array([jnp.cos(a), 0.0, jnp.sin(a), 0.0])


def spatula_to_tcp(pos, quat):
    """Tcp pose holding the spatula at (pos, quat), with the planned grasp."""
    rot = geo.quat_to_mat(quat)
    return pos + rot @ jnp.asarray(GRASP), geo.quat_mul(quat, DOWN)


class ScoopWithSpatula(TaskEnv):
    name = "scoop_with_spatula"
    code = "SS"
    xml = "scoop_with_spatula.xml"
    description = "grab the spatula and scoop up the cube with it"
    graspable = ("spatula",)
    # above, descend, settle, close, lift, to the cube, lower, settle, stroke, catch up, lift, hold
    expert_durations = (40, 20, 8, 25, 25, 45, 20, 8, 14, 6, 30, 12)

    def setup(self):
        m = self.mj_model
        self.spatula_qadr = free_adr(m, "spatula")
        self.cube_qadr = free_adr(m, "cube")

    def sample_scene(self, key):
        k_sp, k_syaw, k_cube, k_cyaw = jax.random.split(key, 4)
        sp = sampling.uniform(k_sp, jnp.array(SPATULA_LOW), jnp.array(SPATULA_HIGH), (2,))
        sp_yaw = sampling.uniform(k_syaw, -SPATULA_YAW, SPATULA_YAW)
        cube = sampling.uniform(k_cube, jnp.array(CUBE_LOW), jnp.array(CUBE_HIGH), (2,))
        cube_yaw = sampling.uniform(k_cyaw, -jnp.pi / 4, jnp.pi / 4)
        sp_pos = jnp.array([sp[0], sp[1], BLADE_HALF[2]])
        cube_pos = jnp.array([cube[0], cube[1], CUBE_HALF])
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.spatula_qadr, sp_pos, geo.yaw_quat(sp_yaw))
        qpos = set_free_body(qpos, self.cube_qadr, cube_pos, geo.yaw_quat(cube_yaw))
        return scene.replace(qpos=qpos, params={"spatula": sp_pos, "spatula_yaw": sp_yaw, "cube": cube_pos,
                                                "cube_yaw": cube_yaw})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        p0, yaw0, cube = scene.params["spatula"], scene.params["spatula_yaw"], scene.params["cube"]
        q0 = geo.yaw_quat(yaw0)
        # the stroke runs square to a face of the cube (its yaw is drawn in [-pi/4, pi/4])
        yaw = scene.params["cube_yaw"]
        q_scoop = geo.quat_mul(geo.yaw_quat(yaw), _pitch_quat(PITCH))  # tip down
        q_level = geo.yaw_quat(yaw)
        # blade centre height that puts the leading top edge DEPTH below the table
        z_scoop = -DEPTH + BLADE_HALF[0] * np.sin(PITCH) - BLADE_HALF[2] * np.cos(PITCH)
        lead = BLADE_HALF[0] * np.cos(PITCH)  # leading edge ahead of the blade centre
        fwd = jnp.array([jnp.cos(yaw), jnp.sin(yaw), 0.0])
        start = cube.at[2].set(z_scoop) - (CUBE_HALF + START_GAP + lead) * fwd
        end = cube.at[2].set(z_scoop) + PUSH_END * fwd
        poses = [
            (p0, q0), (p0, q0), (p0, q0),  # descend, settle, close
            (p0 + jnp.array([0.0, 0.0, 0.08]), q0),  # lift
            (start + jnp.array([0.0, 0.0, 0.04]), q_scoop),  # behind the cube, above the table
            (start, q_scoop), (start, q_scoop),  # lower, settle
            (end, q_scoop), (end, q_scoop),  # the stroke, let the arm catch up
            # up while levelling the blade (on the slope the cube would creep towards the tip)
            (end + jnp.array([0.0, 0.0, 0.1]), q_level), (end + jnp.array([0.0, 0.0, 0.1]), q_level),
        ]
        tcp = [spatula_to_tcp(p, q) for p, q in poses]
        above = (tcp[0][0] + jnp.array([0.0, 0.0, 0.1]), tcp[0][1])
        pos = jnp.stack([above[0]] + [t[0] for t in tcp])
        quat = jnp.stack([above[1]] + [t[1] for t in tcp])
        grip = jnp.array([1.0, 1.0, 1.0] + [0.0] * (len(poses) - 2))
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    # ------------------------------------------------------------------ predicates
    def cube_on_blade(self, data) -> jax.Array:
        c = data.qpos[self.cube_qadr:self.cube_qadr + 3]
        p = data.qpos[self.spatula_qadr:self.spatula_qadr + 3]
        rot = geo.quat_to_mat(data.qpos[self.spatula_qadr + 3:self.spatula_qadr + 7])
        local = rot.T @ (c - p)
        inside = (jnp.abs(local[0]) <= BLADE_HALF[0]) & (jnp.abs(local[1]) <= BLADE_HALF[1])
        height = local[2] - BLADE_HALF[2]
        return inside & (height >= 0.0) & (height <= REGION_HEIGHT) & (c[2] > LIFTED)

    def is_success(self, progress, data, grasp, scene):
        return self.cube_on_blade(data) & grasp.attached[0]
