"""SS — scoop with spatula: grab the spatula, slide its blade under the cube against a stop, lift it.

RLBench (``scoop_with_spatula.py``): success = the cube (``Cuboid``) detected by the ``success``
sensor (on the spatula, above its blade) AND the spatula grasped (``GraspedCondition``); no
failure condition; one variation. There is no spawn boundary: spatula and cube are one rigid
model, and the whole task is placed by ``Scene._place_task`` at a random workspace position with
yaw in ``base_rotation_bounds()`` (the default ±π); only the spatula is graspable.

Here the same: spatula, cube and stop sit at fixed offsets in one task frame (the cube square to
the spatula on its axis, 5 cm beyond the blade's tip; the stop 2 mm beyond the cube;
``tasks_mjcf/scoop_with_spatula.xml``), placed by :func:`readjax.sim.placement.place_task` with yaw
±π; the footprint is the model's bounding box in its frame (handle end to the stop's far face, the
stop's width). Unreachable placements are rejected by ``TaskEnv.sample_scene``. The sensor is a
region fixed to the spatula: the blade's footprint, from its top face to 4 cm above it, tested on
the cube's centre (RLBench's sensor volume is in the unreadable .ttm). Sizes: a kitchen turner
(blade 10 x 7 cm, 1 mm steel; 15 cm handle), a 4 cm toy block, a wooden stop 2 x 11 x 5 cm.

The blade lies on the table and collides with it (a box-plane pair). A rigid blade of finite
thickness cannot get under a cube that rests flat on a rigid table: the cube's lower edge meets
the blade's front face, whose contact normal points forward and down (it pushes, never lifts).
A real turner is pressed flat on the table, where its thin edge flexes; so, as a cook does, the
expert presses the leading edge into the table: its top edge DEPTH (1 mm) below the table
surface, i.e. the blade's lower front edge 2 mm into the table's soft contact.

The stop: pushed slowly, a 10° ramp cannot lift a cube that rests with table friction 1 (it slides
away once the ramp's vertical force reaches 0.57 of its weight), so without something to hold the
cube the stroke has to rely on an impact, and the impact scatters: 1-2 % of replays of recorded
expert motions failed, on seeds that changed with 0.5 mm of cube jitter (BENCHMARKS 25). As a cook
scoops against a pan's rim, the cube here sits 2 mm before a wooden stop fixed to the table, which
holds it while the blade slides under (the stop meets only the cube: the blade's edge may end
under it). The squeeze needs a finer step than the other tasks': this task steps the physics at
2.5 ms (the XML's timestep: 8 substeps per 20 ms control step; 5 ms and 4 elsewhere), and the stroke is slow (6.2 cm in
0.8 s, smoothstep: peak 0.12 m/s, 0.3 mm per substep; the former fast stroke moved 2.4 mm per 5 ms
substep into a 1 mm blade's contact), which keeps the cube from being squeezed out (BENCHMARKS 26).

Expert: top-down grasp on the handle (fingers across it; of the two hand yaws, the one whose IK
path keeps the larger joint margin), lift, pitch the blade 10 deg tip-down, lower it so the
leading edge is 2 cm before the cube, a slow stroke (40 control steps, 0.8 s) whose target puts the
edge at the stop (the cube is detected over the blade during the stroke: success, as in RLBench,
latches there), then lift while levelling the blade. Spatula waypoints map to tcp waypoints
through the grasp. Known limit (shared grasp model): a grasped body is moved kinematically after
each substep, so within the solver step the lifted spatula falls freely and the cube on it feels
almost no friction: off the table the cube may slide off the blade during the lift, after success
has latched. Success is unaffected: RLBench also ends at the first step where its conditions hold.
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

BLADE_HALF = np.array([0.05, 0.035, 0.0005], np.float32)
CUBE_HALF = 0.02
GRASP = np.array([-0.1563, 0.0, 0.0355], np.float32)  # tcp in the spatula frame (on the handle)
CUBE_X = 0.12  # cube centre on the task's x axis (the blade's centre is the origin)
STOP_GAP = 0.002  # the stop's near face this far beyond the cube's far face
STOP_HALF_X = 0.01  # half the stop's thickness (tasks_mjcf: the bar's x half-size)
STOP_X = CUBE_X + CUBE_HALF + STOP_GAP + STOP_HALF_X  # the stop's centre on the task's x axis
FOOTPRINT_MIN = np.array([-0.205, -0.055], np.float32)  # the handle's end, the stop's side
FOOTPRINT_MAX = np.array([STOP_X + STOP_HALF_X, 0.055], np.float32)  # the stop's far face
PITCH = np.deg2rad(10.0)  # blade tip-down angle while scooping
DEPTH = 0.001  # leading top edge of the blade below the table surface
START_GAP = 0.02  # leading edge this far before the cube at the start of the stroke
TIP_UNDER_STOP = 0.0  # the leading edge's target at the stroke's end: this far past the stop's near face
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
    expert_durations = (40, 20, 8, 25, 25, 45, 20, 8, 40, 6, 30, 12)

    def setup(self):
        m = self.mj_model
        self.spatula_qadr = free_adr(m, "spatula")
        self.cube_qadr = free_adr(m, "cube")
        self.stop_mocap = mocap_index(m, "stop")

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, FOOTPRINT_MIN, FOOTPRINT_MAX)
        sp_pos = jnp.concatenate([xy, jnp.array([BLADE_HALF[2]])])
        cube_xy = placement.to_world(xy, yaw, jnp.array([CUBE_X, 0.0]))
        cube_pos = jnp.concatenate([cube_xy, jnp.array([CUBE_HALF])])
        stop_pos = jnp.concatenate([placement.to_world(xy, yaw, jnp.array([STOP_X, 0.0])), jnp.zeros(1)])
        q = geo.yaw_quat(yaw)
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.spatula_qadr, sp_pos, q)
        qpos = set_free_body(qpos, self.cube_qadr, cube_pos, q)
        params = {"spatula": sp_pos, "cube": cube_pos, "yaw": yaw, "fits": fits}
        return scene.replace(qpos=qpos, mocap_pos=scene.mocap_pos.at[self.stop_mocap].set(stop_pos),
                             mocap_quat=scene.mocap_quat.at[self.stop_mocap].set(q), params=params)

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
        # the blade centre's target at the stroke's end, from the cube's centre (negative: short of it)
        push_end = STOP_X - STOP_HALF_X + TIP_UNDER_STOP - lead - CUBE_X
        end = cube.at[2].set(z_scoop) + push_end * fwd
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
