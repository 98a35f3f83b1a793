"""OW — open wine: grasp the bottle's screw cap, turn it > 150 degrees, lift it off the mouth.

RLBench (``rlbench/tasks/open_wine_bottle.py``): the cap is parented to a force sensor on the bottle
and freed (re-parented to the joint) once ``JointCondition(joint, 150 deg)`` holds (l.21-22, 34-38).
The only success condition is ``DetectedCondition(cap, cap_detector, negated=True)`` (l.19-20): the
cap is no longer in the detector volume at the bottle's mouth. No failure condition; no
``NothingGrasped`` (imported at l.8, never registered), so the cap may still be held at the end. The
task overrides neither ``is_static_workspace`` nor ``base_rotation_bounds``: the whole model is placed
at a random workspace pose with yaw +-pi (``backend/scene.py:529-537``). One variation.

readjax: the bottle (the task model; its bounding box is the glass's 7.4 cm square) is placed by
:func:`readjax.sim.placement.place_task` with yaw +-pi; the cap rests on it, turned with it. Grasping
is a kinematic attachment (a carried cap goes wherever the hand goes, through any "thread"), so the
thread is in the predicate instead: the cap's turn about the bottle axis is accumulated (unwrapped,
either direction) at every control step while its centre is in the mouth region (``cap_detector``);
progress "unscrewed" = turned > 150 degrees while on the mouth, and success = unscrewed AND the
cap's centre outside the region (RLBench's negated DetectedCondition once the cap is free). The cap
leaving the region before the twist is a (sticky) failure: RLBench's cap cannot come free untwisted
(it is parented to the bottle), so that state does not exist there; here it stands for it.

Sizes (RLBench's are in ``open_wine_bottle.ttm``, unreadable here): a 75 cl bottle (glass radius
3.7 cm, mouth at 0.285 m), a 3.2 cm screw cap 4 cm tall, the detector a 6 x 6 x 8 cm box around the
cap's resting pose (tasks_mjcf/open_wine.xml).

Expert: top-down grasp of the cap at the yaw (modulo the square cap's 90 degrees) that leaves
joint 7 room for the turn, a 165 degree counter-clockwise turn (unscrewing) in three segments,
a short settle, then a straight lift.
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

UNSCREW = np.deg2rad(150.0)  # RLBench's JointCondition threshold
TWIST = np.deg2rad(165.0)  # what the expert turns
TWIST_SEGMENTS = 3  # slerp takes the short way: keep each segment well below 180 degrees
CAP_Z = 0.305  # cap centre at rest (mouth at 0.285, cap half height 0.02)
REGION_CENTRE = np.array([0.0, 0.0, 0.305], np.float32)  # in the bottle frame (site mouth_region)
REGION_HALF = np.array([0.03, 0.03, 0.04], np.float32)
GRASP_Z = 0.308  # tcp height on the cap
LIFT_Z = 0.42
FOOTPRINT = np.array([0.037, 0.037], np.float32)  # the bottle's half size: the task's bounding box


def wrap(a: jax.Array) -> jax.Array:
    return (a + jnp.pi) % (2 * jnp.pi) - jnp.pi


def grasp_yaw(cap_yaw: jax.Array, bottle_xy: jax.Array) -> jax.Array:
    """The cap's face-aligned yaw (mod 90 deg) in the window where joint 7 can turn it by TWIST.

    At a down-pointing tcp, joint 7 ~ 0.785 + atan2(y, x) - yaw, within +-2.9 rad; the window
    [phi - 1.45, phi + 0.12) (phi = atan2(y, x)) leaves joint 7 within about [-2.2, 2.3].
    """
    lo = jnp.arctan2(bottle_xy[1], bottle_xy[0]) - 0.66 - jnp.pi / 4
    return lo + (cap_yaw - lo) % (jnp.pi / 2)


class OpenWine(TaskEnv):
    name = "open_wine"
    code = "OW"
    xml = "open_wine.xml"
    description = "unscrew the red cap of the wine bottle and take it off"
    graspable = ("cap",)
    # above, descend, close, turn x3, settle, lift, hold
    expert_durations = (40, 20, 25) + (20,) * TWIST_SEGMENTS + (10, 25, 10)

    def setup(self):
        m = self.mj_model
        self.cap_qadr = free_adr(m, "cap")
        self.bottle_mocap = mocap_index(m, "bottle")

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, -FOOTPRINT, FOOTPRINT)
        scene = self.default_scene()
        pos = jnp.array([xy[0], xy[1], 0.0])
        quat = geo.yaw_quat(yaw)
        qpos = set_free_body(scene.qpos, self.cap_qadr, pos + jnp.array([0.0, 0.0, CAP_Z]), quat)
        mocap_pos = scene.mocap_pos.at[self.bottle_mocap].set(pos)
        mocap_quat = scene.mocap_quat.at[self.bottle_mocap].set(quat)
        return scene.replace(qpos=qpos, mocap_pos=mocap_pos, mocap_quat=mocap_quat,
                             params={"bottle": pos, "yaw": yaw, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        b = scene.params["bottle"]
        yaw0 = grasp_yaw(scene.params["yaw"], b)
        grasp = b + jnp.array([0.0, 0.0, GRASP_Z])
        above = grasp + jnp.array([0.0, 0.0, 0.1])
        lift = b + jnp.array([0.0, 0.0, LIFT_Z])
        turns = [yaw0 + TWIST * (k + 1) / TWIST_SEGMENTS for k in range(TWIST_SEGMENTS)]
        yaws = [yaw0, yaw0, yaw0] + turns + [turns[-1]] * 3
        pos = jnp.stack([above, grasp, grasp] + [grasp] * TWIST_SEGMENTS + [grasp, lift, lift])
        quat = jnp.stack([down_quat(y) for y in yaws])
        grip = jnp.array([1.0, 1.0] + [0.0] * (len(yaws) - 2))
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    # ------------------------------------------------------------------ predicates
    def cap_on_mouth(self, data) -> jax.Array:
        rot = geo.quat_to_mat(data.mocap_quat[self.bottle_mocap])
        centre = data.mocap_pos[self.bottle_mocap] + rot @ jnp.asarray(REGION_CENTRE)
        return in_box(data.qpos[self.cap_qadr:self.cap_qadr + 3], centre, rot, REGION_HALF)

    def cap_yaw(self, data) -> jax.Array:
        r = geo.quat_to_mat(data.qpos[self.cap_qadr + 3:self.cap_qadr + 7])
        return jnp.arctan2(r[1, 0], r[0, 0])

    def init_progress(self):
        return {"twist": jnp.zeros(()), "unscrewed": jnp.zeros((), bool), "on": jnp.ones((), bool)}

    def update_progress(self, progress, data, grasp, scene):
        rel = wrap(self.cap_yaw(data) - scene.params["yaw"])
        twist = progress["twist"] + wrap(rel - wrap(progress["twist"]))
        on = self.cap_on_mouth(data)
        unscrewed = progress["unscrewed"] | (on & (jnp.abs(twist) > UNSCREW))
        return {"twist": twist, "unscrewed": unscrewed, "on": on}

    def is_success(self, progress, data, grasp, scene):
        return progress["unscrewed"] & ~progress["on"]

    def is_failure(self, progress, data, grasp, scene):
        return ~progress["on"] & ~progress["unscrewed"]
