"""PU — put umbrella: grab the handle of the umbrella lying on a crate and put it into the stand.

RLBench (``put_umbrella_in_umbrella_stand.py``): success = the umbrella detected by the stand's
``success`` sensor AND nothing grasped; no failure condition; one variation. There is no spawn
boundary: umbrella, crate and stand are one rigid model, and the whole task is placed by
``Scene._place_task`` at a random workspace position with yaw in ``base_rotation_bounds()`` (the
default ±π), a placement being kept only when it fits and the demo is reachable.

Here the same: crate, umbrella and stand sit at fixed offsets in one task frame (``tasks_mjcf/
put_umbrella.xml``), placed by :func:`readjax.sim.placement.place_task` with yaw ±π; the footprint
is the model's bounding box in its frame (tip to handle end along x, crate side to the stand's
far wall along y: FOOTPRINT). Unreachable placements are rejected by ``TaskEnv.sample_scene``.
Sizes (RLBench's .ttm is unreadable): a child's stick umbrella 0.51 m long (a folded stick
umbrella is 0.5-0.9 m; the Panda must lift the tip over a stand about half the umbrella's height,
with the tcp 0.72 m above the table, which it reaches only near the short end of that range), a
0.22 m high stand with an inner 0.13 m square, and a 0.30 x 0.16 x 0.10 m crate. The sensor is
the lower half of the stand's inside (so a tip passing the rim does not count); "detected" =
any of 12 points along the umbrella's axis, tip to canopy top, inside it.

Expert: the handle is grasped with the hand pitched 45 degrees (pointing down towards the tip,
fingers across the handle). Spinning the wrist by 180 degrees about the hand's own axis turns
the umbrella from lying to hanging tip-down while the hand keeps its pitch; the hand also turns
about the vertical so that over the stand it points outward (plus an offset). Waypoints: top-down
over the handle with the grasp's finger axis (selects joint 7's branch), tilt above the handle,
down, close (the arm still), lift, half the spin and turn while carrying it towards the stand,
the rest with the tip 3.5 cm over the rim (the carry height is reached half way, so the tip
swings in over the rim), settle, lower the tip to 3 cm above the floor, settle, open, retreat up.
The grasp's finger sign, the spin's direction and the final heading (outward, ±45°) are chosen
per scene: of the 12 candidates, the reachable one (IK path within tolerance and joint margin)
with the largest joint margin, as RLBench's planner tries grasp poses until one has a path.
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

# the rigid model in the task frame (origin on the table at the crate's centre)
GRASP_X = 0.22  # umbrella origin (handle centre, grasp point) on the task's x axis
LIE_Z = 0.10 + 0.025  # umbrella axis height lying on the crate (crate top + canopy radius)
DROP = 0.0005
STAND_XY = np.array([0.0, 0.22], np.float32)
FOOTPRINT_MIN = np.array([-0.24, -0.08], np.float32)  # tip end .. crate's near side
FOOTPRINT_MAX = np.array([0.275, 0.295], np.float32)  # handle end .. stand's far wall
# the umbrella: tip and canopy top on its axis (umbrella frame, x from the tip to the handle)
TIP_X, CANOPY_TOP_X = -0.46, -0.08
AXIS_POINTS = np.stack([np.linspace(TIP_X, CANOPY_TOP_X, 12), np.zeros(12), np.zeros(12)], 1)
AXIS_POINTS = AXIS_POINTS.astype(np.float32)
# the sensor: lower half of the stand's inside (stand frame)
RIM = 0.22
REGION_CENTRE = np.array([0.0, 0.0, 0.055], np.float32)
REGION_HALF = np.array([0.065, 0.065, 0.055], np.float32)
# the expert
TIP_ABOVE = RIM + 0.035  # tip height carried over the stand
TIP_LOW = 0.03  # tip height when letting go
PITCH = np.pi / 4  # hand axis below horizontal when holding the handle
# candidates: (finger sign, spin direction, final heading offset from pointing outward)
CANDIDATES = np.array(list(itertools.product((1.0, -1.0), (1.0, -1.0), (0.0, np.pi / 4, -np.pi / 4))),
                      np.float32)


def hand_in_umbrella(ysign) -> jax.Array:
    """Rotation of the tcp frame in the umbrella frame while holding the handle."""
    s, c = np.sin(PITCH), np.cos(PITCH)
    z = jnp.array([-s, 0.0, -c])  # the hand axis: down and towards the tip
    y = jnp.array([0.0, -1.0, 0.0]) * ysign  # fingers across the handle
    return jnp.stack([jnp.cross(y, z), y, z], axis=1)


def axis_rotation(axis, angle):
    k = jnp.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return jnp.eye(3) + jnp.sin(angle) * k + (1 - jnp.cos(angle)) * (k @ k)


def wrap(a):
    return (a + jnp.pi) % (2 * jnp.pi) - jnp.pi


class PutUmbrella(TaskEnv):
    name = "put_umbrella"
    code = "PU"
    xml = "put_umbrella.xml"
    description = "grab the umbrella's handle and put it into the umbrella stand"
    graspable = ("umbrella",)
    fixtures = ()
    # top-down, tilted above the handle, approach, close, lift, half spin, over the stand, settle,
    # lower, settle, open, retreat
    expert_durations = (30, 20, 20, 25, 20, 35, 35, 10, 25, 10, 20, 15)

    def setup(self):
        m = self.mj_model
        self.umbrella_qadr = free_adr(m, "umbrella")
        self.crate_mocap = mocap_index(m, "crate")
        self.stand_mocap = mocap_index(m, "stand")
        self.tip_site = m.site("umbrella_tip").id

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, FOOTPRINT_MIN, FOOTPRINT_MAX)
        crate = jnp.concatenate([xy, jnp.zeros(1)])
        stand = jnp.concatenate([placement.to_world(xy, yaw, STAND_XY), jnp.zeros(1)])
        origin = jnp.concatenate([placement.to_world(xy, yaw, jnp.array([GRASP_X, 0.0])),
                                  jnp.array([LIE_Z + DROP])])
        q = geo.yaw_quat(yaw)
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.umbrella_qadr, origin, q)
        mpos = scene.mocap_pos.at[self.crate_mocap].set(crate).at[self.stand_mocap].set(stand)
        mquat = scene.mocap_quat.at[self.crate_mocap].set(q).at[self.stand_mocap].set(q)
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"origin": origin, "yaw": yaw, "stand": stand, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    # ------------------------------------------------------------------ expert
    def candidate_plan(self, scene: Scene, cand: jax.Array) -> WaypointPlan:
        """The expert's waypoints for one (finger sign, spin direction, heading offset)."""
        origin, yaw, stand = scene.params["origin"], scene.params["yaw"], scene.params["stand"]
        ysign, spin, offset = cand[0], cand[1], cand[2]
        u0 = geo.rot_z(yaw)
        rel = hand_in_umbrella(ysign)
        axis = u0 @ rel[:, 2]  # hand axis at the grasp (world)
        heading0 = jnp.arctan2(axis[1], axis[0])
        turn = wrap(jnp.arctan2(stand[1], stand[0]) + offset - heading0)

        def hand(frac):
            """Hand orientation after ``frac`` of the spin and of the turn."""
            u = geo.rot_z(turn * frac) @ axis_rotation(axis, spin * jnp.pi * frac) @ u0
            return geo.mat_to_quat(u @ rel)

        up = jnp.array([0.0, 0.0, 1.0])
        lift = origin + 0.15 * up
        above = stand + (TIP_ABOVE - TIP_X) * up  # umbrella hanging: tip straight below the handle
        low = stand + (TIP_LOW - TIP_X) * up
        # at the carry height already half way: the tip swings in over the rim while the spin ends
        mid = (0.5 * (lift + above)).at[2].set(above[2])
        q_grasp, q_mid, q_end = hand(0.0), hand(0.5), hand(1.0)
        # first turn the wrist top-down to the grasp's finger axis (keeps the IK on joint 7's
        # branch of this candidate), then tilt to the grasp pose
        fingers = u0 @ rel[:, 1]
        q_top = down_quat(jnp.arctan2(fingers[0], -fingers[1]))
        pos = jnp.stack([origin + 0.15 * up, origin + 0.06 * up, origin, origin, lift, mid, above, above,
                         low, low, low, low + 0.08 * up])
        quat = jnp.stack([q_top] + [q_grasp] * 4 + [q_mid] + [q_end] * 6)
        grip = jnp.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        """The candidate (finger side x spin direction x heading) the arm follows most easily."""
        return self.easiest_plan(jax.vmap(lambda c: self.candidate_plan(scene, c))(jnp.asarray(CANDIDATES)))

    # ------------------------------------------------------------------ predicate
    def tip(self, data) -> jax.Array:
        return data.site_xpos[self.tip_site]

    def umbrella_detected(self, data, scene) -> jax.Array:
        """Any point on the umbrella's axis (tip to canopy top) in the lower half of the stand."""
        a = self.umbrella_qadr
        rot = geo.quat_to_mat(data.qpos[a + 3:a + 7])
        pts = data.qpos[a:a + 3] + jnp.asarray(AXIS_POINTS) @ rot.T
        stand_rot = geo.rot_z(scene.params["yaw"])
        centre = scene.params["stand"] + stand_rot @ jnp.asarray(REGION_CENTRE)
        return jnp.any(in_box(pts, centre, stand_rot, REGION_HALF))

    def is_success(self, progress, data, grasp, scene):
        return self.umbrella_detected(data, scene) & ~grasp.any
