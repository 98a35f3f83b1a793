"""PH — place hanger: lift the clothes hanger off its holder's peg and hang it on the rack's rail.

As in RLBench's ``place_hanger_on_rack`` the rack never moves and the hanger starts hanging on a
small holder placed (and turned) at random. RLBench's success sensor becomes the rack's hook
region, a box around the middle of the rail; the hanger's reference point is the centre of its
hook's opening (the body origin), so success = that point inside the region AND nothing grasped
(the hanger hangs by its hook on the rail once released).

Expert: top-down grasp of the bottom bar 7 cm beside the hook (fingers closing across the
hanger's plane), straight up off the peg, over to 6 cm above the rail with the hanger turned
perpendicular to it, settle, straight down until the hook sits on the rail, open, retreat.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

PEG_Z = 0.20  # holder peg axis height
RAIL = np.array([0.55, -0.22, 0.30], np.float32)  # where the expert hangs it (rail axis)
REGION_CENTRE = RAIL
REGION_HALF = np.array([0.12, 0.02, 0.02], np.float32)
GRASP = np.array([0.0, 0.07, -0.115], np.float32)  # tcp in the hanger frame (on the bottom bar)
DROP = 0.0005  # start gap between hook and peg
LIFT = 0.08  # straight up off the peg
ABOVE_RAIL = 0.06
LOW, HIGH = np.array([0.42, 0.08]), np.array([0.60, 0.22])
YAW_RANGE = np.pi / 6


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

    def sample_scene(self, key):
        k_xy, k_yaw = jax.random.split(key)
        xy = jax.random.uniform(k_xy, (2,), minval=jnp.asarray(LOW), maxval=jnp.asarray(HIGH))
        yaw = jax.random.uniform(k_yaw, (), minval=-YAW_RANGE, maxval=YAW_RANGE)
        holder = jnp.array([xy[0], xy[1], 0.0])
        scene = self.default_scene()
        mpos = scene.mocap_pos.at[self.holder_mocap].set(holder)
        mquat = scene.mocap_quat.at[self.holder_mocap].set(geo.yaw_quat(yaw))
        hook = holder + jnp.array([0.0, 0.0, PEG_Z + DROP])
        qpos = set_free_body(scene.qpos, self.hanger_qadr, hook, geo.yaw_quat(yaw))
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"holder": holder, "yaw": yaw})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        yaw = scene.params["yaw"]
        hook = scene.params["holder"] + jnp.array([0.0, 0.0, PEG_Z])
        grasp = hook + geo.rot_z(yaw) @ jnp.asarray(GRASP)
        hang = jnp.asarray(RAIL + GRASP)  # the hanger turned to yaw 0 (plane across the rail)
        up = jnp.array([0.0, 0.0, 1.0])
        pos = jnp.stack([
            grasp + 0.10 * up,
            grasp,
            grasp,
            grasp + LIFT * up,
            hang + ABOVE_RAIL * up,
            hang + ABOVE_RAIL * up,
            hang + 0.002 * up,
            hang + 0.002 * up,
            hang + 0.10 * up,
        ])
        q_pick, q_hang = down_quat(yaw + jnp.pi / 2), down_quat(jnp.pi / 2)
        quat = jnp.stack([q_pick] * 4 + [q_hang] * 5)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def hook_point(self, data) -> jax.Array:
        return data.qpos[self.hanger_qadr:self.hanger_qadr + 3]

    def is_success(self, progress, data, grasp, scene):
        inside = in_box(self.hook_point(data), jnp.asarray(REGION_CENTRE), jnp.eye(3), REGION_HALF)
        return inside & ~grasp.any
