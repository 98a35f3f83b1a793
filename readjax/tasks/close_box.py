"""CB — close box: lift the open lid by its tab and swing it shut over the hinge.

RLBench (``rlbench/tasks/close_box.py``): the single success condition is ``JointCondition(box_joint,
2.6)`` (l.11-12), i.e. the lid's hinge moved more than 2.6 rad from its start (``backend/
conditions.py:30-40``); no failure condition. ``base_rotation_bounds`` is overridden to yaw +-pi/8
(l.23-24): the whole box is placed at a random workspace pose, turned at most 22.5 degrees from
facing the robot (``backend/scene.py:529-537``). One variation.

readjax: the box with its open lid is the task model; its bounding box in the box frame (FOOTPRINT:
the 15 x 18 cm box, and behind it the lid lying open at 2.8 rad, reaching 0.25 m behind the box's
centre) is placed by :func:`readjax.sim.placement.place_task` with yaw +-pi/8. Success: the hinge
more than 2.6 rad from its start (latched). Sizes (RLBench's are in ``close_box.ttm``, unreadable
here): a 15 x 18 x 8 cm box (a shoe-box-sized storage box) with a 3 cm tab on the lid's free edge
(tasks_mjcf/close_box.xml).

Expert: from above and behind the tab, down, slide the closed fingers under the tab, then sweep
the tab along the lid's arc over the hinge until the lid is shut, then up; the hand's yaw follows
the box's.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, set_free_body

OPEN = 2.8  # rad, the lid's open rest angle (its upper joint limit)
CLOSED_BY = 2.6  # rad the hinge must move (RLBench)
HINGE = np.array([0.075, 0.0, 0.08])  # in the box frame
PUSHER = np.array([-0.17, 0.0, 0.02])  # pad centre in the lid frame: under the tab
ARC = np.linspace(OPEN, 0.0, 9)[1:]  # lid angles the pusher sweeps through
YAW_BOUNDS = (-np.pi / 8, np.pi / 8)  # RLBench's base_rotation_bounds
# the task's bounding box in the box frame: the box (x +-0.075, y +-0.092 with the lid) and the open
# lid behind the hinge (its tab's end at 0.075 + 0.18 * |cos 2.8| = 0.245 m, plus its thickness)
FOOTPRINT_MIN, FOOTPRINT_MAX = np.array([-0.075, -0.092], np.float32), np.array([0.25, 0.092], np.float32)


def _lid_point(angle, p_lid=PUSHER) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return HINGE + np.array([p_lid[0] * c + p_lid[2] * s, p_lid[1], -p_lid[0] * s + p_lid[2] * c])


# Expert path in the box frame: behind and above the tab, down, slide under it, then the arc.
_START = _lid_point(OPEN)
_PATH = np.stack(
    [_START + [0.035, 0, 0.12], _START + [0.035, 0, 0.0], _START]
    + [_lid_point(a) for a in ARC]
    + [_lid_point(0.0) + [0, 0, 0.1]]
).astype(np.float32)


class CloseBox(TaskEnv):
    name = "close_box"
    code = "CB"
    xml = "close_box.xml"
    description = "close the open lid of the box"
    fixtures = ("box",)
    expert_durations = (45, 20, 15) + (10,) * len(ARC) + (20,)

    def setup(self):
        m = self.mj_model
        self.box_qadr = free_adr(m, "box")
        self.lid_qadr = int(m.joint("lid").qposadr[0])

    def draw_scene(self, key):
        xy, yaw, fits = placement.place_task(key, FOOTPRINT_MIN, FOOTPRINT_MAX, YAW_BOUNDS)
        scene = self.default_scene()
        pos = jnp.array([xy[0], xy[1], 0.0])
        qpos = set_free_body(scene.qpos, self.box_qadr, pos, geo.yaw_quat(yaw))
        qpos = qpos.at[self.lid_qadr].set(OPEN)
        return scene.replace(qpos=qpos, params={"box": pos, "yaw": yaw, "fits": fits})

    def scene_ok(self, scene):
        return scene.params["fits"]

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        rot = geo.rot_z(scene.params["yaw"])
        pos = scene.params["box"] + jnp.asarray(_PATH) @ rot.T
        n = _PATH.shape[0]
        quat = jnp.tile(down_quat(scene.params["yaw"]), (n, 1))
        return WaypointPlan(pos=pos, quat=quat, grip=jnp.zeros(n))

    def is_success(self, progress, data, grasp, scene):
        """RLBench's JointCondition(box_joint, 2.6): the hinge more than 2.6 rad from its start."""
        return jnp.abs(data.qpos[self.lid_qadr] - scene.qpos[self.lid_qadr]) > CLOSED_BY
