"""PH — place hanger: lift the clothes hanger off its holder's peg and hang it on the rack's rail.

RLBench's ``place_hanger_on_rack`` (``rlbench/tasks/place_hanger_on_rack.py``): a static workspace
(l.33-34: the task is never placed as a whole, the rack never moves, as the paper says); the
``hanger_holder`` (with the hanger hanging on it) is sampled by ``SpawnBoundary([workspace])`` over
the whole workspace with the default yaw +-3.14 (l.20, 23-24); success = NothingGrasped AND the
hanger detected by the rack's ``success_detector0`` (l.15-18). Here:

* Holder: :func:`readjax.sim.placement.spawn_in_boundary` over the workspace rectangle with yaw +-pi;
  its bounding box is the holder with the hanger on it (x [-0.08, 0.047] x y [-0.11, 0.11] m in the
  holder frame). A draw whose turned box overlaps the rack's (x [0.37, 0.73] x y [-0.31, -0.13])
  is drawn again (RLBench's collision rejection); unreachable ones are rejected by the expert's
  validation (``TaskEnv.expert_reachable``).
* Success: RLBench's sensor becomes the rack's hook region, a box around the rail's middle
  (+-12 cm along it, +-2 cm across and in height; the sensor's size is in the unreadable .ttm);
  "detected" = the hook opening's centre (the hanger's body origin) in it; AND nothing grasped.
* Sizes (real-world, the .ttm is unreadable): a 0.22 m wide wire hanger with a 2.8 cm hook
  opening; rail (r 7 mm) 0.30 m high, 0.31 m long; holder peg 0.20 m high.

Expert: top-down grasp of the bottom bar 7 cm beside the hook (fingers across the hanger's plane),
straight up off the peg, over to 6 cm above the rail while turning the hanger's plane across the
rail, settle, down until the hook sits on the rail, open, retreat. The hanger's yaw is +-pi, so of
the symmetric choices (hand yaw mod pi at the pick; the hanger hung at yaw 0 or pi, grasped on the
bar's side that ends nearer the robot) the expert takes the one whose joint 7 stays nearest the
middle of its range at both ends of the turn (up to 180 deg over the pick and the transport).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

PEG_Z = 0.20  # holder peg axis height
RAIL = np.array([0.55, -0.22, 0.30], np.float32)  # where the expert hangs it (rail axis)
REGION_CENTRE = RAIL
REGION_HALF = np.array([0.12, 0.02, 0.02], np.float32)
GRASP_Y, GRASP_Z = 0.07, -0.115  # tcp in the hanger frame (on the bottom bar), |y| either side
DROP = 0.0005  # start gap between hook and peg
LIFT = 0.08  # straight up off the peg
ABOVE_RAIL = 0.06
HOLDER_MIN = np.array([-0.08, -0.11], np.float32)  # holder + hanger bounding box, holder frame
HOLDER_MAX = np.array([0.047, 0.11], np.float32)
RACK_MIN = np.array([0.37, -0.31], np.float32)  # the rack's footprint (posts, feet), world
RACK_MAX = np.array([0.73, -0.13], np.float32)
Q7_HOME = 0.785  # joint 7 with the hand yaw at the bearing of the tcp: q7 ~ Q7_HOME + bearing - yaw


def wrap(a):
    return (a + jnp.pi) % (2 * jnp.pi) - jnp.pi


def choose_turn(theta, pick_xy, hang_xy):
    """(pick hand yaw, hand turn delta): among the pick yaws theta +- pi/2 and hang yaws +-pi/2 (the
    turn is their wrapped difference), the pair keeping joint 7 (estimated from the bearing) nearest
    0, the middle of its range, at both ends; turns near pi (ambiguous slerp) are avoided."""
    psi_p = wrap(theta + jnp.pi / 2 + jnp.array([0.0, 0.0, jnp.pi, jnp.pi]))
    delta = wrap(jnp.array([1.0, -1.0, 1.0, -1.0]) * jnp.pi / 2 - psi_p)
    b_p = jnp.arctan2(pick_xy[1], pick_xy[0])
    b_h = jnp.arctan2(hang_xy[1], hang_xy[0])
    q7_p = Q7_HOME + b_p - psi_p
    q7_h = Q7_HOME + b_h - (psi_p + delta)
    cost = jnp.maximum(jnp.abs(q7_p), jnp.abs(q7_h)) + 10.0 * (jnp.abs(delta) > 2.8) + 10.0 * (jnp.abs(psi_p) > 2.9)
    i = jnp.argmin(cost)
    return psi_p[i], delta[i]


class PlaceHanger(TaskEnv):
    name = "place_hanger"
    code = "PH"
    xml = "place_hanger.xml"
    description = "take the hanger off its holder and hang it on the rack"
    graspable = ("hanger",)
    # above, descend, close, lift, to the rail, settle, lower, open, retreat
    expert_durations = (45, 25, 25, 20, 60, 10, 20, 20, 20)

    def setup(self):
        m = self.mj_model
        self.hanger_qadr = free_adr(m, "hanger")
        self.holder_mocap = mocap_index(m, "holder")

    def draw_scene(self, key):
        xy, yaw, fits = placement.spawn_in_boundary(key, placement.WORKSPACE_LOW, placement.WORKSPACE_HIGH,
                                                    HOLDER_MIN, HOLDER_MAX)
        lo, hi = placement.turned_extent(HOLDER_MIN, HOLDER_MAX, yaw)
        clear = jnp.any(xy + hi < RACK_MIN) | jnp.any(xy + lo > RACK_MAX)  # boxes disjoint
        holder = jnp.array([xy[0], xy[1], 0.0])
        scene = self.default_scene()
        mpos = scene.mocap_pos.at[self.holder_mocap].set(holder)
        mquat = scene.mocap_quat.at[self.holder_mocap].set(geo.yaw_quat(yaw))
        hook = holder + jnp.array([0.0, 0.0, PEG_Z + DROP])
        qpos = set_free_body(scene.qpos, self.hanger_qadr, hook, geo.yaw_quat(yaw))
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"holder": holder, "yaw": yaw, "fits": fits & clear})

    def scene_ok(self, scene):
        return scene.params["fits"]

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        theta = scene.params["yaw"]
        hook = scene.params["holder"] + jnp.array([0.0, 0.0, PEG_Z])
        hang_tcp = jnp.asarray(RAIL) + jnp.array([0.0, GRASP_Y, GRASP_Z])  # the grasped side towards +y
        psi_p, delta = choose_turn(theta, hook[:2], hang_tcp[:2])
        # the hanger hangs at yaw phi = theta + delta (0 or pi); grasp the side that ends at +y
        side = jnp.cos(theta + delta) * GRASP_Y
        grasp = hook + geo.rot_z(theta) @ jnp.stack([0.0, side, GRASP_Z])
        up = jnp.array([0.0, 0.0, 1.0])
        pos = jnp.stack([
            grasp + 0.10 * up,
            grasp,
            grasp,
            grasp + LIFT * up,
            hang_tcp + ABOVE_RAIL * up,
            hang_tcp + ABOVE_RAIL * up,
            hang_tcp + 0.002 * up,
            hang_tcp + 0.002 * up,
            hang_tcp + 0.10 * up,
        ])
        q_pick, q_hang = down_quat(psi_p), down_quat(psi_p + delta)
        quat = jnp.stack([q_pick] * 4 + [q_hang] * 5)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def hook_point(self, data) -> jax.Array:
        return data.qpos[self.hanger_qadr:self.hanger_qadr + 3]

    def is_success(self, progress, data, grasp, scene):
        inside = in_box(self.hook_point(data), jnp.asarray(REGION_CENTRE), jnp.eye(3), REGION_HALF)
        return inside & ~grasp.any
