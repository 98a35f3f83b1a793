"""CB — close box: lift the open lid by its tab and swing it shut over the hinge."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, set_free_body

OPEN = 2.8  # rad, the lid's open rest angle (its upper joint limit)
CLOSED_BY = 2.6  # rad the hinge must move (RLBench)
HINGE = np.array([0.075, 0.0, 0.08])  # in the box frame
PUSHER = np.array([-0.17, 0.0, 0.02])  # pad centre in the lid frame: under the tab
ARC = np.linspace(OPEN, 0.0, 9)[1:]  # lid angles the pusher sweeps through


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

    def sample_scene(self, key):
        k_xy, k_yaw = jax.random.split(key)
        xy = jax.random.uniform(k_xy, (2,), minval=jnp.array([0.37, -0.2]), maxval=jnp.array([0.48, 0.2]))
        yaw = jax.random.uniform(k_yaw, (), minval=-jnp.pi / 8, maxval=jnp.pi / 8)
        scene = self.default_scene()
        pos = jnp.array([xy[0], xy[1], 0.0])
        qpos = set_free_body(scene.qpos, self.box_qadr, pos, geo.yaw_quat(yaw))
        qpos = qpos.at[self.lid_qadr].set(OPEN)
        return scene.replace(qpos=qpos, params={"box": pos, "yaw": yaw})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        rot = geo.rot_z(scene.params["yaw"])
        pos = scene.params["box"] + jnp.asarray(_PATH) @ rot.T
        n = _PATH.shape[0]
        quat = jnp.tile(down_quat(scene.params["yaw"]), (n, 1))
        return WaypointPlan(pos=pos, quat=quat, grip=jnp.zeros(n))

    def is_success(self, progress, data, grasp, scene):
        return data.qpos[self.lid_qadr] < OPEN - CLOSED_BY
