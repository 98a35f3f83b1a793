"""PU — put umbrella: grab the handle of the umbrella lying on a crate and put it into the stand.

RLBench's ``put_umbrella_in_umbrella_stand`` succeeds when the umbrella is detected by the
stand's sensor and nothing is grasped; here the sensor is the stand's inner volume and the
umbrella's reference point is its tip (site ``umbrella_tip``): success = tip inside the stand
AND nothing grasped. The umbrella starts lying on a crate (the paper: "placed on top of a
container"), tip towards the robot, handle away from it.

Expert: the handle is grasped with the hand pitched 45 degrees (pointing down and back towards
the robot, fingers across the handle). Spinning the wrist by 180 degrees about the hand's own
axis then turns the umbrella from lying to hanging tip-down while the hand keeps the same
comfortable pitch (a top-down grasp would need a horizontal hand over the stand, which the Panda
cannot reach near its base; pointing the hand outward instead drives joints 4-6 to their limits).
Waypoints: top-down over the handle with the grasp's finger axis (puts joint 7 on the branch
that leaves room for the spin), tilt above the handle, down, close, lift, half the spin while
carrying it towards the stand, the rest of the spin with the tip over the stand, settle, lower
the tip to 2.5 cm above the floor inside the stand, open, retreat straight up. Checked
kinematically on 64 seeds: every joint stays >= 0.5 rad from its limits.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

TIP = np.array([-0.267, 0.0, 0.0], np.float32)  # tip (end of the canopy capsule) in the umbrella frame
CANOPY_CENTRE = 0.135  # crate centre under the umbrella, behind the handle
LIE_Z = 0.10 + 0.022  # umbrella axis height when lying on the crate
DROP = 0.0005
STAND_HALF = np.array([0.05, 0.05, 0.075], np.float32)  # inner volume of the stand
STAND_CENTRE_Z = 0.075
TIP_ABOVE = 0.185  # tip height above the stand before lowering (rim at 0.15)
TIP_LOW = 0.025  # tip height when letting go
PITCH = np.pi / 4  # hand axis below horizontal when holding the handle
SPIN = -1.0  # direction of the 180 degree wrist spin about the hand axis
CRATE_R, CRATE_BEARING = (0.36, 0.42), (0.25, 0.55)
STAND_R, STAND_BEARING = (0.40, 0.52), (0.18, 0.50)
YAW_NOISE = np.pi / 12


def _hand_in_umbrella() -> np.ndarray:
    """Rotation of the tcp frame in the umbrella frame while holding the handle."""
    s, c = np.sin(PITCH), np.cos(PITCH)
    z = np.array([-s, 0.0, -c])  # the hand axis: down and towards the tip
    # fingers across the handle; of the two finger orientations this one (with SPIN) takes joint 7
    # from ~0.8 to ~-2.3 rad
    y = np.array([0.0, -1.0, 0.0])
    return np.stack([np.cross(y, z), y, z], axis=1).astype(np.float32)


REL = _hand_in_umbrella()


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
    # top-down, tilted above the handle, approach, close, lift, half spin, over the stand, settle,
    # lower, open, retreat
    expert_durations = (30, 20, 20, 25, 15, 35, 35, 10, 25, 20, 15)

    def setup(self):
        m = self.mj_model
        self.umbrella_qadr = free_adr(m, "umbrella")
        self.crate_mocap = mocap_index(m, "crate")
        self.stand_mocap = mocap_index(m, "stand")
        self.tip_site = m.site("umbrella_tip").id

    def sample_scene(self, key):
        k_side, k_c, k_s, k_yaw = jax.random.split(key, 4)  # crate on a random side, stand opposite
        side = jnp.where(jax.random.bernoulli(k_side), 1.0, -1.0)
        rc = jax.random.uniform(k_c, (2,), minval=jnp.array([CRATE_R[0], CRATE_BEARING[0]]),
                                maxval=jnp.array([CRATE_R[1], CRATE_BEARING[1]]))
        rs = jax.random.uniform(k_s, (2,), minval=jnp.array([STAND_R[0], STAND_BEARING[0]]),
                                maxval=jnp.array([STAND_R[1], STAND_BEARING[1]]))
        bc, bs = side * rc[1], -side * rs[1]
        crate = jnp.array([rc[0] * jnp.cos(bc), rc[0] * jnp.sin(bc), 0.0])
        stand = jnp.array([rs[0] * jnp.cos(bs), rs[0] * jnp.sin(bs), 0.0])
        # the umbrella's x axis (tip -> handle) points away from the robot
        yaw = bc + jax.random.uniform(k_yaw, (), minval=-YAW_NOISE, maxval=YAW_NOISE)
        x_axis = jnp.array([jnp.cos(yaw), jnp.sin(yaw), 0.0])
        origin = crate + CANOPY_CENTRE * x_axis + jnp.array([0.0, 0.0, LIE_Z + DROP])
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.umbrella_qadr, origin, geo.yaw_quat(yaw))
        mpos = scene.mocap_pos.at[self.crate_mocap].set(crate).at[self.stand_mocap].set(stand)
        mquat = scene.mocap_quat.at[self.crate_mocap].set(geo.yaw_quat(yaw))
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"origin": origin, "yaw": yaw, "stand": stand})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        origin, yaw, stand = scene.params["origin"], scene.params["yaw"], scene.params["stand"]
        u0 = geo.rot_z(yaw)
        rel = jnp.asarray(REL)
        axis = u0 @ rel[:, 2]  # hand axis at the grasp (world)
        turn = wrap(jnp.arctan2(stand[1], stand[0]) - yaw)  # keep the hand pointing inward

        def hand(spin, frac):
            """Hand orientation after ``spin`` of the 180 degree spin and ``frac`` of the turn."""
            u = geo.rot_z(turn * frac) @ axis_rotation(axis, SPIN * spin) @ u0
            return geo.mat_to_quat(u @ rel)

        up = jnp.array([0.0, 0.0, 1.0])
        lift = origin + 0.12 * up
        above = stand + (TIP_ABOVE - TIP[0]) * up  # umbrella hanging: tip straight below the handle
        low = stand + (TIP_LOW - TIP[0]) * up
        mid = 0.5 * (lift + above) + 0.05 * up
        q_grasp, q_mid, q_end = hand(0.0, 0.0), hand(jnp.pi / 2, 0.5), hand(jnp.pi, 1.0)
        # first turn the wrist top-down to the grasp's finger axis (keeps the IK on joint 7's
        # branch that leaves room for the spin), then tilt to the grasp pose
        fingers = u0 @ rel[:, 1]
        q_top = down_quat(jnp.arctan2(fingers[0], -fingers[1]))
        pos = jnp.stack([origin + 0.15 * up, origin + 0.06 * up, origin, origin, lift, mid, above, above,
                         low, low, low + 0.08 * up])
        quat = jnp.stack([q_top] + [q_grasp] * 4 + [q_mid] + [q_end] * 5)
        grip = jnp.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def tip(self, data) -> jax.Array:
        return data.site_xpos[self.tip_site]

    def is_success(self, progress, data, grasp, scene):
        centre = scene.params["stand"] + jnp.array([0.0, 0.0, STAND_CENTRE_Z])
        return in_box(self.tip(data), centre, jnp.eye(3), STAND_HALF) & ~grasp.any
