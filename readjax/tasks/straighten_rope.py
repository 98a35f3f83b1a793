"""SR — straighten rope: pull the rope's head and tail, in turn, until the rope lies straight.

RLBench (``rlbench/tasks/straighten_rope.py``): success = ``head`` detected by the proximity sensor
``success_head`` AND ``tail`` detected by ``success_tail`` (l.11-13); no failure condition, 1
variation. The rope lies in the task model in one fixed bent shape, and the whole model (rope and
both sensors) is placed by ``Scene._place_task`` anywhere in the workspace with yaw ±3.14 (no
``base_rotation_bounds`` override), rejected when the demo cannot be reached. The paper (supplement
l.103): to grasp the rope the arm must stretch to near its reach limit.

Here:
- Rope: 12 capsules (radius 11 mm, 4 cm apart, 0.48 m: a thick cotton rope) on ball joints (MJX
  has no flex), the head link carrying the free joint. Its shape is fixed, as RLBench's model is:
  an S of one full wave, heading ``axis + A cos(2 pi s / length)`` with A = 90 degrees, i.e. two
  opposite half-turns whose ends leave at right angles to the S's axis (the letter S laid on its
  side). Its ends lie on the axis 0.224 m apart; straight, they are 0.44 m apart, so each end must
  travel about 10 cm (and turn 90 degrees) to straighten it (the .ttm's shape is unreadable;
  this is the plain S the paper names, "a rope bent in an S-shape").
- Sensors: boxes (mocap bodies ``head_target`` / ``tail_target`` carrying only a group-4 site, so
  they are never rendered: RLBench's proximity sensors are invisible) 5 cm along the axis x 7 cm
  x 6 cm, centred on the axis where the end links' centres lie when the rope is straight with 5 %
  slack (0.95 x 0.44 m apart). "Detected" = the end link's geom centre inside its box.
- Placement: the task frame has its origin at the S's centre and x along its axis (the head
  towards -x). Its footprint, the bounding box of the rope and both sensors in that frame
  (``FOOTPRINT``, 0.47 x 0.21 m), goes to :func:`placement.place_task` with yaw ±π over the full
  workspace; placements the expert cannot reach (near the far edge) are rejected by
  ``expert_reachable``, as RLBench's validation rejects them.

Grasping: RLBench registers no graspable object in this task (the rope is held by friction), and
the kinematic attachment needs a free body (the tail link hangs on ball joints), so the ends are
held by friction here too: nothing is in ``graspable``; closed fingers squeeze an end link with
the finger actuators' 10 N (pads: friction 1.5, condim 4). The end links are weighted, grippy
ends (40 g, table friction 1.5 against 10 g and 0.7 for the rest): with a uniform rope, pulling
the tail dragged the released head back out of its sensor before the middle straightened.

Expert (RLBench's demo: "grasping each end of the rope in turn, leave the rope straight"): for the
head, then the tail: above the end link, down, close across the link, drag it along the table to
its sensor (turning it onto the axis' heading), open, up. The yaws are chosen (modulo pi, the
gripper is symmetric) to keep joint 7 inside its limits whatever the task's yaw.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index

N_LINKS = 12
LINK = 0.04  # m
RADIUS = 0.011
SPAN = (N_LINKS - 1) * LINK  # head-link centre to tail-link centre when straight
SLACK = 0.95  # the targets are SLACK * SPAN apart
REGION_HALF = np.array([0.025, 0.035, 0.03], np.float32)  # along the axis, across, up
AMPLITUDE = np.pi / 2  # S: heading = axis + A cos(2 pi s / length): two half-turns, ends across the axis
GRIP_Z = RADIUS + 0.001  # tcp height when holding an end link on the table
DRAG_LIFT = 0.006  # the held end is dragged slightly lifted


def rope_pose(centre, axis_yaw, amplitude=AMPLITUDE, xp=jnp):
    """Link start points (N, 2) and headings (N,) of the S (end-link centres symmetric about ``centre``)."""
    s = (xp.arange(N_LINKS) + 0.5) / N_LINKS
    heading = axis_yaw + amplitude * xp.cos(2 * np.pi * s)
    step = LINK * xp.stack([xp.cos(heading), xp.sin(heading)], -1)
    start = xp.concatenate([xp.zeros((1, 2)), xp.cumsum(step, 0)[:-1]])
    mid = start + 0.5 * step
    offset = centre - 0.5 * (mid[0] + mid[-1])
    return start + offset, heading


def _footprint() -> tuple[np.ndarray, np.ndarray]:
    """The task model's bounding box in the task frame (origin: the S's centre, x: its axis): the
    rope's capsules (radius included) and both sensor boxes."""
    start, heading = rope_pose(np.zeros(2), 0.0, xp=np)
    end = start + LINK * np.stack([np.cos(heading), np.sin(heading)], -1)
    pts = np.concatenate([start, end])
    half = 0.5 * SLACK * SPAN
    sensors = np.array([[-half - REGION_HALF[0], -REGION_HALF[1]], [half + REGION_HALF[0], REGION_HALF[1]]])
    lo = np.minimum(pts.min(0) - RADIUS, sensors[0])
    hi = np.maximum(pts.max(0) + RADIUS, sensors[1])
    return lo.astype(np.float32), hi.astype(np.float32)


FOOTPRINT = _footprint()
# the fixed S in the task frame: link start points, middles and headings (relative to the axis), and
# the ball joints' bends (constants: a scene only turns and moves them, element-wise, so a scene is
# bit-for-bit the same alone or in a batch)
_S_START, _S_HEADING = (np.asarray(v, np.float32) for v in rope_pose(np.zeros(2), 0.0, xp=np))
_S_MID = (_S_START + 0.5 * LINK * np.stack([np.cos(_S_HEADING), np.sin(_S_HEADING)], -1)).astype(np.float32)
_BEND_ANGLE = np.diff(_S_HEADING)
BENDS = np.stack([np.cos(_BEND_ANGLE / 2), 0 * _BEND_ANGLE, 0 * _BEND_ANGLE, np.sin(_BEND_ANGLE / 2)],
                 -1).astype(np.float32)


def turn(yaw: jax.Array, pts) -> jax.Array:
    """Points (..., 2) turned by ``yaw`` about the origin (element-wise, no matmul)."""
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    return jnp.stack([c * pts[..., 0] - s * pts[..., 1], s * pts[..., 0] + c * pts[..., 1]], -1)


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
    it back over the rope). The branches k are chosen (out of 6 x 6: the heading spans axis ± pi/2
    and the axis ±pi) to keep joint 7 far from its
    limits and every change of yaw between waypoints below ~160 degrees (orientations are slerped
    the short way, so a larger change would turn the wrist the wrong way).
    """
    ks = jnp.arange(-3, 3) * jnp.pi
    turn_h = wrap(p["axis"] - p["head_heading"])
    turn_t = wrap(p["axis"] - p["tail_heading"])
    gh = p["head_heading"] + ks[:, None]  # (6, 1)
    gt = p["tail_heading"] + ks[None, :]  # (1, 6)
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
    description = ("straighten the S-shaped rope: pull its red end, then its blue end, out along the S until "
                   "it lies straight")
    # per end: above, down, close (15 steps to touch the link, 5 to squeeze), drag, open, up
    expert_durations = (30, 12, 20, 45, 10, 8) + (50, 12, 20, 45, 10, 8)

    def setup(self):
        m = self.mj_model
        self.rope_qadr = free_adr(m, "rope0")
        self.joint_qadr = np.array([m.joint(f"rope{i}").qposadr[0] for i in range(1, N_LINKS)], np.int32)
        self.head_geom = m.geom("rope0").id
        self.tail_geom = m.geom(f"rope{N_LINKS - 1}").id
        self.head_mocap = mocap_index(m, "head_target")
        self.tail_mocap = mocap_index(m, "tail_target")

    def draw_scene(self, key):
        centre, axis, fits = placement.place_task(key, *FOOTPRINT)
        start = centre + turn(axis, _S_START)
        mid = centre + turn(axis, _S_MID)
        scene = self.default_scene()
        qpos = scene.qpos.at[self.rope_qadr:self.rope_qadr + 3].set(jnp.append(start[0], RADIUS))
        qpos = qpos.at[self.rope_qadr + 3:self.rope_qadr + 7].set(geo.yaw_quat(axis + _S_HEADING[0]))
        qpos = qpos.at[self.joint_qadr[:, None] + np.arange(4)].set(jnp.asarray(BENDS))
        u = jnp.stack([jnp.cos(axis), jnp.sin(axis)])
        head_t = centre - 0.5 * SLACK * SPAN * u
        tail_t = centre + 0.5 * SLACK * SPAN * u
        mocap = scene.mocap_pos.at[self.head_mocap, :2].set(head_t).at[self.tail_mocap, :2].set(tail_t)
        quat = geo.yaw_quat(axis)
        mquat = scene.mocap_quat.at[self.head_mocap].set(quat).at[self.tail_mocap].set(quat)
        params = {"head": mid[0], "tail": mid[-1], "head_heading": axis + _S_HEADING[0],
                  "tail_heading": axis + _S_HEADING[-1], "head_target": head_t, "tail_target": tail_t,
                  "axis": axis, "fits": fits}
        return scene.replace(qpos=qpos, mocap_pos=mocap, mocap_quat=mquat, params=params)

    def scene_ok(self, scene):
        return scene.params["fits"]

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
