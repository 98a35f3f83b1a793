"""SR — straighten rope: pull the rope's head and tail ends, in turn, onto their target patches.

RLBench's ``straighten_rope`` detects the rope's head and tail shapes with two proximity
sensors placed where the ends of the straightened rope lie. Here the rope is a chain of 12
capsules on ball joints (MJX has no flex); the sensors are boxes (mocap bodies ``head_target``
and ``tail_target``) around where the end links' centres lie when the rope is straight along the
S's axis with 5% slack; "detected" = the end link's geom centre inside its box. The boxes move
with the rope's start pose and are drawn as flat patches (red: head, blue: tail, the colours of
the rope's end links).

Grasping: RLBench registers no graspable object in this task (the rope is held by friction),
and the kinematic attachment needs a free body (the tail link hangs on ball joints), so the
ends are held by friction here too: nothing is in ``graspable``; closed fingers squeeze an end
link with the finger actuators' 10 N (pads: friction 1.5, condim 4).

The end links are weighted, grippy ends (40 g, table friction 1.5 against 10 g and 0.7 for the
rest): with a uniform rope, pulling the tail dragged the released head back off its patch
before the middle straightened.

Expert: for the head, then the tail: above the end link, down, close across the link, drag it
along the table to its target (turning it to the axis' heading), open, up. Unlike the paper's
RLBench scene, the rope lies mid-workspace, so the arm does not have to reach its limit.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index

N_LINKS = 12
LINK = 0.04  # m
RADIUS = 0.011
SPAN = (N_LINKS - 1) * LINK  # head-link centre to tail-link centre when straight
SLACK = 0.95  # the targets are SLACK * SPAN apart
REGION_HALF = np.array([0.025, 0.035, 0.03], np.float32)  # along the axis, across, up
AMPLITUDE = (np.deg2rad(70.0), np.deg2rad(85.0))  # S: heading = axis + A cos(2 pi s / length)
CENTRE_LOW, CENTRE_HIGH = (0.45, -0.06), (0.58, 0.06)
AXIS_YAW = (np.pi / 2 - np.pi / 6, np.pi / 2 + np.pi / 6)  # the head lies towards -y
GRIP_Z = RADIUS + 0.001  # tcp height when holding an end link on the table
DRAG_LIFT = 0.006  # the held end is dragged slightly lifted


def rope_pose(centre: jax.Array, axis_yaw: jax.Array, amplitude: jax.Array):
    """Link start points (N, 2) and headings (N,) of the S (end-link centres symmetric about ``centre``)."""
    s = (jnp.arange(N_LINKS) + 0.5) / N_LINKS
    heading = axis_yaw + amplitude * jnp.cos(2 * jnp.pi * s)
    step = LINK * jnp.stack([jnp.cos(heading), jnp.sin(heading)], -1)
    start = jnp.concatenate([jnp.zeros((1, 2)), jnp.cumsum(step, 0)[:-1]])
    mid = start + 0.5 * step
    offset = centre - 0.5 * (mid[0] + mid[-1])
    return start + offset, heading


def wrap(a: jax.Array) -> jax.Array:
    return (a + jnp.pi) % (2 * jnp.pi) - jnp.pi


def wrist(yaw: jax.Array, at: jax.Array) -> jax.Array:
    """Joint 7 of a down-pointing tcp at ``at`` with ``yaw`` (an approximation, from IK samples)."""
    return 0.785 + jnp.arctan2(at[1], at[0]) - yaw


def expert_yaws(p: dict, grab_at: tuple, put_at: tuple) -> jax.Array:
    """Gripper yaws (grab head, put head, grab tail, put tail) for the expert.

    down_quat(yaw) opens the fingers along Rz(yaw) y, i.e. across a link heading ``yaw``; the
    gripper is symmetric, so any ``heading + k pi`` grasps a link. Each held link turns by its own
    turn onto the axis heading (``axis - heading``, never the other way round, which would fold
    it back over the rope). The branches k are chosen (out of 4 x 4) to keep joint 7 far from its
    limits and every change of yaw between waypoints below ~160 degrees (orientations are slerped
    the short way, so a larger change would turn the wrist the wrong way).
    """
    ks = jnp.arange(-2, 2) * jnp.pi
    turn_h = wrap(p["axis"] - p["head_heading"])
    turn_t = wrap(p["axis"] - p["tail_heading"])
    gh = p["head_heading"] + ks[:, None]  # (4, 1)
    gt = p["tail_heading"] + ks[None, :]  # (1, 4)
    ph, pt = gh + turn_h, gt + turn_t
    q7 = jnp.stack(jnp.broadcast_arrays(wrist(gh, grab_at[0]), wrist(ph, put_at[0]),
                                        wrist(gt, grab_at[1]), wrist(pt, put_at[1])))
    jumps = jnp.stack(jnp.broadcast_arrays(gh - 0.0, gt - ph))
    cost = jnp.abs(q7).max(0) + 10.0 * jnp.any(jnp.abs(jumps) > 2.8, axis=0)
    i, j = jnp.unravel_index(jnp.argmin(cost), cost.shape)
    return jnp.stack([gh[i, 0], ph[i, 0], gt[0, j], pt[0, j]])


class StraightenRope(TaskEnv):
    name = "straighten_rope"
    code = "SR"
    xml = "straighten_rope.xml"
    description = "straighten the S-shaped rope: red end onto the red patch, blue end onto the blue patch"
    # per end: above, down, close, drag, open, up
    expert_durations = (30, 12, 20, 30, 10, 8) + (40, 12, 20, 30, 10, 8)

    def setup(self):
        m = self.mj_model
        self.rope_qadr = free_adr(m, "rope0")
        self.joint_qadr = np.array([m.joint(f"rope{i}").qposadr[0] for i in range(1, N_LINKS)], np.int32)
        self.head_geom = m.geom("rope0").id
        self.tail_geom = m.geom(f"rope{N_LINKS - 1}").id
        self.head_mocap = mocap_index(m, "head_target")
        self.tail_mocap = mocap_index(m, "tail_target")

    def sample_scene(self, key):
        k_c, k_yaw, k_amp = jax.random.split(key, 3)
        centre = jax.random.uniform(k_c, (2,), minval=jnp.array(CENTRE_LOW), maxval=jnp.array(CENTRE_HIGH))
        axis = jax.random.uniform(k_yaw, (), minval=AXIS_YAW[0], maxval=AXIS_YAW[1])
        amp = jax.random.uniform(k_amp, (), minval=AMPLITUDE[0], maxval=AMPLITUDE[1])
        start, heading = rope_pose(centre, axis, amp)
        scene = self.default_scene()
        qpos = scene.qpos.at[self.rope_qadr:self.rope_qadr + 3].set(jnp.append(start[0], RADIUS))
        qpos = qpos.at[self.rope_qadr + 3:self.rope_qadr + 7].set(geo.yaw_quat(heading[0]))
        bends = geo.yaw_quat(heading[1:] - heading[:-1])  # (N-1, 4) ball joint quaternions
        qpos = qpos.at[self.joint_qadr[:, None] + np.arange(4)].set(bends)
        u = jnp.array([jnp.cos(axis), jnp.sin(axis)])
        head_t = centre - 0.5 * SLACK * SPAN * u
        tail_t = centre + 0.5 * SLACK * SPAN * u
        mocap = scene.mocap_pos.at[self.head_mocap, :2].set(head_t).at[self.tail_mocap, :2].set(tail_t)
        quat = geo.yaw_quat(axis)
        mquat = scene.mocap_quat.at[self.head_mocap].set(quat).at[self.tail_mocap].set(quat)
        mid = start + 0.5 * LINK * jnp.stack([jnp.cos(heading), jnp.sin(heading)], -1)
        params = {"head": mid[0], "tail": mid[-1], "head_heading": heading[0], "tail_heading": heading[-1],
                  "head_target": head_t, "tail_target": tail_t, "axis": axis}
        return scene.replace(qpos=qpos, mocap_pos=mocap, mocap_quat=mquat, params=params)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        p = scene.params
        at = {e: jnp.append(p[e], GRIP_Z) for e in ("head", "tail")}
        to = {e: jnp.append(p[f"{e}_target"], GRIP_Z + DRAG_LIFT) for e in ("head", "tail")}
        yaws = expert_yaws(p, (at["head"], at["tail"]), (to["head"], to["tail"]))
        up = jnp.array([0.0, 0.0, 0.1])
        pos, quat = [], []
        for k, end in enumerate(("head", "tail")):
            grab, put = down_quat(yaws[2 * k]), down_quat(yaws[2 * k + 1])
            pos += [at[end] + up, at[end], at[end], to[end], to[end], to[end] + up]
            quat += [grab, grab, grab, put, put, put]
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 1.0, 1.0] * 2)
        return WaypointPlan(pos=jnp.stack(pos), quat=jnp.stack(quat), grip=grip)

    def ends_in_regions(self, data) -> tuple[jax.Array, jax.Array]:
        def inside(geom, mocap):
            rot = geo.quat_to_mat(data.mocap_quat[mocap])
            centre = data.mocap_pos[mocap].at[2].set(RADIUS)
            return in_box(data.geom_xpos[geom], centre, rot, REGION_HALF)

        return inside(self.head_geom, self.head_mocap), inside(self.tail_geom, self.tail_mocap)

    def is_success(self, progress, data, grasp, scene):
        head, tail = self.ends_in_regions(data)
        return head & tail
