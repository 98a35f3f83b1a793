"""BB — beat the buzz: carry the wand's ring along the wire to the far end without touching it.

RLBench (``rlbench/tasks/beat_the_buzz.py``): fail condition (terminates) = the wand detected by
``middle_sensor`` (around the pole); success = the wand detected by ``right_sensor`` AND
NothingGrasped; no ``base_rotation_bounds`` override, so the whole task model is placed by
``Scene._place_task`` at a random workspace position with yaw +-pi.

Here: the base (board, wire, rests, both sensors) is the task frame placed by
:func:`readjax.sim.placement.place_task` with yaw +-pi; its footprint is the board, 0.40 x 0.10 m
(the wand's ring, 8 cm across, stays inside it). The wand starts standing on the start rest (x =
-0.12 in the base frame; RLBench: at one end of the pole). The middle sensor becomes an exact
geometric test: the wand touches the wire when the distance between the wire's axis and any wand
part's axis (ring bars and stick as capsules of their half thickness) is below the sum of their
radii plus 1 mm; a sticky failure. The right sensor becomes the finish region, a box +-3 x +-1.5
x +-1.5 cm around where the ring stands on the finish rest; success = the ring centre in it AND
nothing grasped. Sizes (the .ttm is unreadable): a brass wire of 5 mm radius and a square ring of
6 cm inner width, i.e. 2.5 cm clearance all round, the size of a table-top buzz-wire game whose
loop a hand can pass along the wire; the 1 mm touch distance stands for the sensor's detection
range.

Expert: top-down grasp of the handle stick with the fingers closing along the wire (the hand's yaw
folded modulo pi, the gripper being symmetric, to where joint 7 is mid-range over the traverse),
lift 1 cm off the rest, slide along the wire to above the finish rest, settle, set it down, open,
retreat.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim import placement
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

WIRE_Z = 0.12  # wire axis height above the table (base frame)
WIRE_HALF = 0.185  # wire from -WIRE_HALF to +WIRE_HALF along the base x axis
WIRE_R = 0.005
START_X, FINISH_X = -0.12, 0.12  # rest positions along the wire
DROP = 0.0005  # the wand starts this far above its rest
FINISH_HALF = np.array([0.03, 0.015, 0.015], np.float32)
TOUCH = 0.001  # m: closer than this counts as touching
GRASP_Z = 0.125  # tcp above the ring centre when holding the stick
LIFT = 0.01  # ring centre above the wire while carried
# Wand parts as capsules in the wand frame: (from, to, radius)
_PARTS = (
    ((0.0, -0.035, 0.035), (0.0, 0.035, 0.035), 0.005),  # ring top
    ((0.0, -0.035, -0.035), (0.0, -0.035, 0.035), 0.005),  # ring sides
    ((0.0, 0.035, -0.035), (0.0, 0.035, 0.035), 0.005),
    ((0.0, -0.035, -0.035), (0.0, 0.035, -0.035), 0.005),  # ring bottom (a flat box)
    ((0.0, 0.0, 0.04), (0.0, 0.0, 0.14), 0.008),  # stick
)
PART_A = np.array([p[0] for p in _PARTS], np.float32)
PART_B = np.array([p[1] for p in _PARTS], np.float32)
PART_R = np.array([p[2] for p in _PARTS], np.float32)
FOOTPRINT = np.array([0.2, 0.05], np.float32)  # the board's half size: the task's bounding box


def segment_distance(p0, p1, q0, q1):
    """Distance between segments [p0, p1] and [q0, q1] (non-degenerate; batched over leading dims)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = jnp.sum(d1 * d1, -1)
    e = jnp.sum(d2 * d2, -1)
    b = jnp.sum(d1 * d2, -1)
    c = jnp.sum(d1 * r, -1)
    f = jnp.sum(d2 * r, -1)
    denom = a * e - b * b
    ok = denom > 1e-12  # not parallel
    s = jnp.where(ok, jnp.clip((b * f - c * e) / jnp.where(ok, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = jnp.where(t < 0, jnp.clip(-c / a, 0.0, 1.0), jnp.where(t > 1, jnp.clip((b - c) / a, 0.0, 1.0), s))
    t = jnp.clip(t, 0.0, 1.0)
    return jnp.linalg.norm(p0 + d1 * s[..., None] - (q0 + d2 * t[..., None]), axis=-1)


class BeatTheBuzz(TaskEnv):
    name = "beat_the_buzz"
    code = "BB"
    xml = "beat_the_buzz.xml"
    description = "slide the ring along the wire from one end to the other without touching it"
    graspable = ("wand",)
    # above, descend, close, lift, traverse, settle, lower, open, retreat
    expert_durations = (45, 25, 25, 12, 70, 10, 12, 20, 20)

    def setup(self):
        m = self.mj_model
        self.wand_qadr = free_adr(m, "wand")
        self.base_mocap = mocap_index(m, "buzz_base")

    def base_frame(self, scene: Scene):
        return scene.params["base"], geo.rot_z(scene.params["yaw"])

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, -FOOTPRINT, FOOTPRINT)
        base = jnp.array([xy[0], xy[1], 0.0])
        rot = geo.rot_z(yaw)
        scene = self.default_scene()
        mpos = scene.mocap_pos.at[self.base_mocap].set(base)
        mquat = scene.mocap_quat.at[self.base_mocap].set(geo.yaw_quat(yaw))
        wand = base + rot @ jnp.array([START_X, 0.0, WIRE_Z + DROP])
        qpos = set_free_body(scene.qpos, self.wand_qadr, wand, geo.yaw_quat(yaw))
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"base": base, "yaw": yaw, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    @staticmethod
    def hand_yaw(base, yaw):
        """The hand's yaw: fingers closing along the wire (yaw - pi/2), folded modulo pi to within pi/2
        of where joint 7 is mid-range at the base (q7 ~ 0.785 + atan2(y, x) - hand yaw)."""
        mid = jnp.arctan2(base[1], base[0]) + 0.785
        return mid + (yaw - jnp.pi / 2 - mid + jnp.pi / 2) % jnp.pi - jnp.pi / 2

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        base, rot = self.base_frame(scene)
        g = WIRE_Z + GRASP_Z
        local = jnp.array([
            [START_X, 0.0, g + 0.10],  # above the stick
            [START_X, 0.0, g + DROP],  # fingers around the stick
            [START_X, 0.0, g + DROP],  # close
            [START_X, 0.0, g + LIFT],  # lift off the rest
            [FINISH_X, 0.0, g + LIFT],  # along the wire
            [FINISH_X, 0.0, g + LIFT],  # settle
            [FINISH_X, 0.0, g + DROP],  # set it down
            [FINISH_X, 0.0, g + DROP],  # open
            [FINISH_X, 0.0, g + 0.10],  # retreat
        ])
        pos = base + local @ rot.T
        quat = jnp.tile(down_quat(self.hand_yaw(base, scene.params["yaw"])), (local.shape[0], 1))
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    # ------------------------------------------------------------------ predicates
    def wand_pose(self, data):
        a = self.wand_qadr
        return data.qpos[a:a + 3], geo.quat_to_mat(data.qpos[a + 3:a + 7])

    def wire_clearance(self, data, scene: Scene) -> jax.Array:
        """Smallest surface distance (m) between the wire and the wand (negative: overlap)."""
        base, rot = self.base_frame(scene)
        w0 = base + rot @ jnp.array([-WIRE_HALF, 0.0, WIRE_Z])
        w1 = base + rot @ jnp.array([WIRE_HALF, 0.0, WIRE_Z])
        p, r = self.wand_pose(data)
        a = p + jnp.asarray(PART_A) @ r.T
        b = p + jnp.asarray(PART_B) @ r.T
        d = segment_distance(a, b, w0[None], w1[None]) - jnp.asarray(PART_R) - WIRE_R
        return jnp.min(d)

    def is_failure(self, progress, data, grasp, scene):
        return self.wire_clearance(data, scene) < TOUCH

    def is_success(self, progress, data, grasp, scene):
        base, rot = self.base_frame(scene)
        p, _ = self.wand_pose(data)
        centre = base + rot @ jnp.array([FINISH_X, 0.0, WIRE_Z])
        return in_box(p, centre, rot, FINISH_HALF) & ~grasp.any
