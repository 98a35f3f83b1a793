"""SS — scoop with spatula: grab the spatula, slide it under the cube with momentum, lift the cube.

RLBench (``scoop_with_spatula.py``): success = the cube (``Cuboid``) detected by the ``success``
sensor (on the spatula, above its blade) AND the spatula grasped (``GraspedCondition``); no
failure condition; one variation. There is no spawn boundary: spatula and cube are one rigid
model, and the whole task is placed by ``Scene._place_task`` at a random workspace position with
yaw in ``base_rotation_bounds()`` (the default ±π); only the spatula is graspable.

Here the same: spatula and cube sit at fixed offsets in one task frame (the cube square to the
spatula on its axis, 5 cm beyond the blade's tip; ``tasks_mjcf/scoop_with_spatula.xml``), placed by
:func:`readjax.sim.placement.place_task` with yaw ±π; the footprint is the model's bounding box in
its frame (handle end to the cube's far face, the blade's width). Unreachable placements are
rejected by ``TaskEnv.sample_scene``. The sensor is a region fixed to the spatula: the blade's
footprint, from its top face to 4 cm above it, tested on the cube's centre (RLBench's sensor volume
is in the unreadable .ttm). Sizes: a kitchen turner (blade 10 x 7 cm, 1 mm steel; 15 cm handle)
and a 4 cm toy block.

The blade lies on the table and collides with it (a box-plane pair). A rigid blade of finite
thickness cannot get under a cube that rests flat on a rigid table: the cube's lower edge meets
the blade's front face, whose contact normal points forward and down (it pushes, never lifts).
A real turner is pressed flat on the table, where its thin edge flexes; so, as a cook does, the
expert presses the leading edge into the table: its top edge DEPTH (1 mm) below the table
surface, i.e. the blade's lower front edge 2 mm into the table's soft contact.

Expert: top-down grasp on the handle (fingers across it; of the two hand yaws, the one whose IK
path keeps the larger joint margin), lift, pitch the blade 10 deg tip-down, lower it so the
leading edge is 2 cm before the cube, a fast ~0.09 m stroke (0.28 s, ~0.5 m/s peak) under the
cube (the cube is detected over the blade during the stroke: success, as in RLBench, latches
there), then lift while levelling the blade. Spatula waypoints map to tcp waypoints through the
grasp. Known limit (shared grasp model): a grasped body is moved kinematically after each
substep, so within the solver step the lifted spatula falls freely and the cube on it feels
almost no friction: off the table the cube slides off the blade during the lift in most seeds
(measured: at about the frictionless rate, while a blade held still keeps it), after success has
latched. Success is unaffected: RLBench also ends at the first step where its conditions hold.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import DOWN, free_adr, set_free_body

BLADE_HALF = np.array([0.05, 0.035, 0.0005], np.float32)
CUBE_HALF = 0.02
GRASP = np.array([-0.1563, 0.0, 0.0355], np.float32)  # tcp in the spatula frame (on the handle)
CUBE_X = 0.12  # cube centre on the task's x axis (the blade's centre is the origin)
FOOTPRINT_MIN = np.array([-0.205, -0.035], np.float32)  # the handle's end, the blade's side
FOOTPRINT_MAX = np.array([CUBE_X + CUBE_HALF, 0.035], np.float32)  # the cube's far face
PITCH = np.deg2rad(10.0)  # blade tip-down angle while scooping
DEPTH = 0.001  # leading top edge of the blade below the table surface
START_GAP = 0.02  # leading edge this far before the cube at the start of the stroke
PUSH_END = 0.0  # blade centre target at the stroke's end, past the cube centre (the arm lags ~2 cm)
REGION_HEIGHT = 0.04
HAND_YAWS = np.array([0.0, np.pi], np.float32)  # the hand's yaw about its axis, in the spatula frame


def _pitch_quat(angle) -> jax.Array:
    """Rotation about y by ``angle`` (positive: the blade's +x end goes down)."""
    a = jnp.asarray(angle, jnp.float32) / 2
    return jnp.array([jnp.cos(a), 0.0, jnp.sin(a), 0.0])


def spatula_to_tcp(pos, quat, hand_yaw):
    """Tcp pose holding the spatula at (pos, quat), with the planned grasp."""
    rot = geo.quat_to_mat(quat)
    return pos + rot @ jnp.asarray(GRASP), geo.quat_mul(quat, geo.quat_mul(geo.yaw_quat(hand_yaw), DOWN))


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

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, FOOTPRINT_MIN, FOOTPRINT_MAX)
        sp_pos = jnp.concatenate([xy, jnp.array([BLADE_HALF[2]])])
        cube_xy = placement.to_world(xy, yaw, jnp.array([CUBE_X, 0.0]))
        cube_pos = jnp.concatenate([cube_xy, jnp.array([CUBE_HALF])])
        q = geo.yaw_quat(yaw)
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.spatula_qadr, sp_pos, q)
        qpos = set_free_body(qpos, self.cube_qadr, cube_pos, q)
        params = {"spatula": sp_pos, "cube": cube_pos, "yaw": yaw, "fits": fits}
        return scene.replace(qpos=qpos, params=params)

    def scene_ok(self, scene):
        return scene.params["fits"]

    def candidate_plan(self, scene: Scene, hand_yaw: jax.Array) -> WaypointPlan:
        p0, yaw, cube = scene.params["spatula"], scene.params["yaw"], scene.params["cube"]
        q0 = geo.yaw_quat(yaw)
        q_scoop = geo.quat_mul(q0, _pitch_quat(PITCH))  # tip down
        # blade centre height that puts the leading top edge DEPTH below the table
        z_scoop = -DEPTH + BLADE_HALF[0] * np.sin(PITCH) - BLADE_HALF[2] * np.cos(PITCH)
        lead = BLADE_HALF[0] * np.cos(PITCH)  # leading edge ahead of the blade centre
        fwd = jnp.array([jnp.cos(yaw), jnp.sin(yaw), 0.0])
        start = cube.at[2].set(z_scoop) - (CUBE_HALF + START_GAP + lead) * fwd
        end = cube.at[2].set(z_scoop) + PUSH_END * fwd
        up = jnp.array([0.0, 0.0, 1.0])
        poses = [
            (p0, q0), (p0, q0), (p0, q0),  # descend, settle, close
            (p0 + 0.08 * up, q0),  # lift
            (start + 0.04 * up, q_scoop),  # behind the cube, above the table
            (start, q_scoop), (start, q_scoop),  # lower, settle
            (end, q_scoop), (end, q_scoop),  # the stroke, let the arm catch up
            # up while levelling the blade
            (end + 0.1 * up, q0), (end + 0.1 * up, q0),
        ]
        tcp = [spatula_to_tcp(p, q, hand_yaw) for p, q in poses]
        pos = jnp.stack([tcp[0][0] + 0.1 * up] + [t[0] for t in tcp])
        quat = jnp.stack([tcp[0][1]] + [t[1] for t in tcp])
        grip = jnp.array([1.0, 1.0, 1.0] + [0.0] * (len(poses) - 2))
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        """Of the two hand yaws (the gripper is symmetric), the one the arm follows most easily."""
        return self.easiest_plan(jax.vmap(lambda h: self.candidate_plan(scene, h))(jnp.asarray(HAND_YAWS)))

    # ------------------------------------------------------------------ predicates
    def cube_on_blade(self, data) -> jax.Array:
        """RLBench's ``success`` sensor: the cube's centre in the region above the blade."""
        c = data.qpos[self.cube_qadr:self.cube_qadr + 3]
        p = data.qpos[self.spatula_qadr:self.spatula_qadr + 3]
        rot = geo.quat_to_mat(data.qpos[self.spatula_qadr + 3:self.spatula_qadr + 7])
        local = rot.T @ (c - p)
        inside = (jnp.abs(local[0]) <= BLADE_HALF[0]) & (jnp.abs(local[1]) <= BLADE_HALF[1])
        height = local[2] - BLADE_HALF[2]
        return inside & (height >= 0.0) & (height <= REGION_HEIGHT)

    def is_success(self, progress, data, grasp, scene):
        return self.cube_on_blade(data) & grasp.attached[0]
