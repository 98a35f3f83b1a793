"""SB — stack blocks: stack two of the four red cubes on the marked spot; a distractor colour distracts.

RLBench (``rlbench/tasks/stack_blocks.py``), variation 0 ("stack 2 red blocks"):
- 4 target blocks and 4 distractors are sampled, one after another, in ``SpawnBoundary`` of the 4
  shapes ``stack_blocks_boundary0..3`` (l.26-27, 59-61): each draw picks a boundary with probability
  proportional to its area, a yaw in ±3.14 (the default) and a position where the turned block
  fits; ``min_distance=0.1`` is checked against the blocks already in *that* boundary
  (``spawn_boundary.py:101-125``; a failed draw is redrawn, at most 100 times).
- All 4 distractors share ONE colour: ``colors[color_choices[int(i / 4)]]`` is index 0 for i < 4
  (l.52-58), a colour other than the target's.
- Success: ``DetectedSeveralCondition(targets, stack_blocks_success, 2)`` AND ``NothingGrasped``
  (l.44-49). No failure condition.
- The boundaries, the target plane and its sensor are parts of the task model, which
  ``Scene._place_task`` turns by a yaw in ±3.14 (``Task.base_rotation_bounds``, not overridden).

Here:
- The task frame's origin is the marked spot, kept at the table centre (0.5, 0): the paper says
  "a marked spot in the center of the table" (supplement l.43), and where the paper is explicit we
  follow it. The frame's yaw is uniform in ±π (RLBench's placement), so the boundaries, the spot's
  square and its sensor turn with it. The footprint (the 4 boundaries' outer square, half size
  ``OUTER``) fits the workspace at every yaw (OUTER * sqrt 2 <= 0.25 m, the spot's distance to the
  workspace's near edge), so the yaw stays uniform; ``scene_ok`` still checks the fit.
- Boundaries (the .ttm is unreadable; our choice): 4 congruent rectangles in a pinwheel round the
  spot, together the square |x|, |y| <= OUTER = 0.175 m minus the square |x|, |y| <= INNER = 0.08 m
  around the spot: each 0.095 x 0.255 m. A block lies wholly inside its boundary, so no block comes
  within 8 cm of the spot's centre (the open fingers reach 4.9 cm from the tcp) and blocks in
  different boundaries cannot overlap. Sampling follows ``SpawnBoundary`` draw by draw (equal areas:
  a uniform boundary; yaw ±π; min distance 0.1 m within the boundary; 100 draws per block).
- Cubes 0.045 m (a toy block), 50 g. The distractor colour: one per episode, drawn from the palette
  without red and its look-alikes (orange, magenta).
- Success (RLBench's terms): at least 2 red cube centres in the sensor, a column over the spot
  (±3 cm in the spot's own frame, 0-20 cm high: a stand-in for the unreadable sensor volume), one of
  them on the second level (centre above one cube size: two cubes side by side on the spot would
  otherwise count), AND nothing grasped. Distractors never count; grasping one is not a failure.

Expert (RLBench's waypoints: above the block, down, close, lift, over the spot, down, open, up;
twice): the two red cubes nearest the spot, nearest first. Grasp yaw: the cube's yaw modulo pi/2
gives two finger axes; the one whose open pads keep clear of the other cubes (blocks of different
boundaries may lie closer than 0.1 m), then the one keeping joint 7 nearest 0, never a change of
yaw of pi or more between waypoints (slerp would turn the wrist the other way round). At the spot
each cube turns by the least angle that aligns it with the spot's square, so the two stack flush. Timing as RLBench records a demo: the arm holds still only while the gripper
actuates, for as long as our gripper (0.1 m/s per finger) needs: 10 control steps to close from
open onto the 4.5 cm cube (the pads touch after 8-9) and 4 to open clear before the arm rises. No
other pause, so in the 101-frame resampling of the 384-step demo (the paper's SB demos are 350-400
frames) a grasp spans about 2.5 frames and a release about one.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

SIZE = 0.045  # cube edge
HALF = np.full(2, SIZE / 2, np.float32)
INNER, OUTER = 0.08, 0.175  # the boundaries' pinwheel: inner and outer half size round the spot
# boundary k (in the task frame): the pinwheel's rectangles, each 0.095 x 0.255 m
BOUNDARY_LOW = np.array([[INNER, -INNER], [-OUTER, INNER], [-OUTER, -OUTER], [-INNER, -OUTER]], np.float32)
BOUNDARY_HIGH = np.array([[OUTER, OUTER], [INNER, OUTER], [-INNER, INNER], [OUTER, -INNER]], np.float32)
MIN_DIST = 0.1  # RLBench's min_distance between blocks of one boundary
DRAWS = 100  # SpawnBoundary.MAX_SAMPLES
N_BLOCKS = 8  # 4 red targets, then 4 distractors (RLBench's sampling order)
CARRY_Z = 0.15  # tcp height while carrying
ABOVE_Z = 0.13  # tcp height above a cube before the descent
PLACE_GAP = 0.004  # a carried cube is let go this far above its resting height
PAD_REACH = 0.049  # the open pads' outer faces from the tcp (m)
CLEAR_ENOUGH = 0.06  # cube centre to open pad: a neighbour this far is clear
# distractor colours: the shared palette without the reds' look-alikes
_DISTRACTOR_PALETTE = jnp.array([c for n, c in sampling.PALETTE.items() if n not in ("orange", "magenta")],
                                jnp.float32)
# one pick-and-place: above, descend, close (the gripper's own time), lift, carry, lower, open, up
CYCLE = (45, 22, 10, 22, 45, 22, 4, 22)
CLOSE_STEPS, OPEN_STEPS = CYCLE[2], CYCLE[6]


def wrap(a, period=2 * np.pi):
    """``a`` into [-period / 2, period / 2)."""
    return (a + period / 2) % period - period / 2


def sample_blocks(key: jax.Array):
    """RLBench's SpawnBoundary for the 8 blocks, in the task frame: per block, the first of ``DRAWS``
    draws (boundary by area, yaw ±π, position where the turned cube fits) that keeps MIN_DIST from
    the blocks already in its boundary. Returns local xy (8, 2), yaw (8,), boundary (8,), ok ()."""
    lows, highs = jnp.asarray(BOUNDARY_LOW), jnp.asarray(BOUNDARY_HIGH)
    area = jnp.prod(highs - lows, axis=1)

    def draw(k):
        k_b, k_s = jax.random.split(k)
        b = jax.random.choice(k_b, 4, p=area / area.sum())
        p, a, fits = placement.spawn_in_boundary(k_s, lows[b], highs[b], -HALF, HALF)
        return p, a, b, fits

    # every draw of every block at once (one batched sampler); then RLBench's order, block by block
    pts, yaws, bnds, fits = jax.vmap(draw)(jax.random.split(key, N_BLOCKS * DRAWS))
    pts, yaws = pts.reshape(N_BLOCKS, DRAWS, 2), yaws.reshape(N_BLOCKS, DRAWS)
    bnds, fits = bnds.reshape(N_BLOCKS, DRAWS), fits.reshape(N_BLOCKS, DRAWS)
    xy, yaw, bnd, ok = [], [], [], jnp.ones((), bool)
    for i in range(N_BLOCKS):
        valid = fits[i]
        for j in range(i):
            valid &= (bnds[i] != bnd[j]) | (jnp.linalg.norm(pts[i] - xy[j], axis=-1) >= MIN_DIST)
        pick = jnp.argmax(valid)
        xy.append(pts[i, pick]), yaw.append(yaws[i, pick]), bnd.append(bnds[i, pick])
        ok &= valid[pick]
    return jnp.stack(xy), jnp.stack(yaw), jnp.stack(bnd), ok


class StackBlocks(TaskEnv):
    name = "stack_blocks"
    code = "SB"
    xml = "stack_blocks.xml"
    description = "stack two of the four red cubes on the marked spot; the other cubes are distractors"
    graspable = tuple(f"red{i}" for i in range(4)) + tuple(f"distractor{i}" for i in range(4))
    recolour_geoms = tuple(f"distractor{i}" for i in range(4))
    expert_durations = CYCLE + CYCLE

    def setup(self):
        m = self.mj_model
        self.red_qadr = np.array([free_adr(m, f"red{i}") for i in range(4)], np.int32)
        self.distractor_qadr = np.array([free_adr(m, f"distractor{i}") for i in range(4)], np.int32)
        self.cube_qadr = np.concatenate([self.red_qadr, self.distractor_qadr])
        self.plane_mocap = mocap_index(m, "target_plane")
        self.spot = np.array(m.body("target_plane").pos[:2], np.float32)
        site = m.site("target_region")
        self.region_z = float(site.pos[2])
        self.region_half = np.array(site.size, np.float32)

    def draw_scene(self, key):
        k_yaw, k_blocks, k_col = jax.random.split(key, 3)
        task_yaw = jax.random.uniform(k_yaw, (), minval=placement.FULL_TURN[0], maxval=placement.FULL_TURN[1])
        lo, hi = placement.turned_extent(-np.full(2, OUTER), np.full(2, OUTER), task_yaw)
        spot = jnp.asarray(self.spot)
        fits = jnp.all(spot + lo >= placement.WORKSPACE_LOW) & jnp.all(spot + hi <= placement.WORKSPACE_HIGH)
        local, local_yaw, bnd, placed = sample_blocks(k_blocks)
        c, s = jnp.cos(task_yaw), jnp.sin(task_yaw)  # element-wise (a batched matmul rounds differently)
        xy = spot + jnp.stack([c * local[:, 0] - s * local[:, 1], s * local[:, 0] + c * local[:, 1]], -1)
        yaw = wrap(local_yaw + task_yaw)
        scene = self.default_scene()
        qpos = scene.qpos
        for i, adr in enumerate(self.cube_qadr):
            qpos = set_free_body(qpos, int(adr), jnp.append(xy[i], SIZE / 2), geo.yaw_quat(yaw[i]))
        mquat = scene.mocap_quat.at[self.plane_mocap].set(geo.yaw_quat(task_yaw))
        colour = _DISTRACTOR_PALETTE[jax.random.randint(k_col, (), 0, _DISTRACTOR_PALETTE.shape[0])]
        rgba = jnp.tile(jnp.append(colour, 1.0), (4, 1))  # RLBench: one colour for all 4 distractors
        params = {"xy": xy, "yaw": yaw, "task_yaw": task_yaw, "boundary": bnd, "fits": fits & placed}
        return scene.replace(qpos=qpos, mocap_quat=mquat, rgba=rgba, params=params)

    def scene_ok(self, scene):
        return scene.params["fits"]

    def grasp_yaw(self, xy: jax.Array, yaw: jax.Array, c: jax.Array, prev: jax.Array, task_yaw: jax.Array):
        """(grasp yaw, put yaw) for cube ``c`` after the gripper yaw ``prev``. The candidates are the
        cube's yaw + k pi/2 (its two finger axes, each twice). Preferred: the axis whose open pads
        keep clear of the other cubes, then joint 7 nearest 0. Excluded (unless nothing else): a
        change of yaw from ``prev`` of pi or more (orientations are slerped the short way, which
        would turn the wrist the other way round) and joint 7 beyond 2.5 rad at grasp or put.
        Joint 7 of a down-pointing hand is about 0.785 + bearing - yaw (the home pose: 0.785)."""
        cands = yaw[c] + jnp.arange(-4, 4) * (np.pi / 2)
        axis = jnp.stack([-jnp.sin(cands), jnp.cos(cands)], -1)  # the fingers open along Rz(yaw) y
        pads = xy[c][None, None] + PAD_REACH * jnp.array([-1.0, 1.0])[None, :, None] * axis[:, None]
        d = jnp.linalg.norm(pads[:, :, None] - xy[None, None], axis=-1)  # (8 candidates, 2 pads, 8 cubes)
        d = jnp.where(jnp.arange(N_BLOCKS) == c, jnp.inf, d)
        clear = jnp.minimum(d.min(axis=(1, 2)), CLEAR_ENOUGH)
        puts = cands + wrap(task_yaw - yaw[c], np.pi / 2)  # the least turn aligning it with the spot
        bearing = jnp.arctan2(xy[c, 1], xy[c, 0])
        q7_grasp = 0.785 + bearing - cands
        q7_put = 0.785 + jnp.arctan2(self.spot[1], self.spot[0]) - puts
        bad = (jnp.abs(cands - prev) >= np.pi - 0.2) | (jnp.maximum(jnp.abs(q7_grasp), jnp.abs(q7_put)) > 2.5)
        cost = -clear + 1e-3 * jnp.abs(q7_grasp) + 10.0 * bad
        best = jnp.argmin(cost)
        return cands[best], puts[best]

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        p = scene.params
        xy, yaw = p["xy"], p["yaw"]
        spot = jnp.asarray(self.spot)
        order = jnp.argsort(jnp.linalg.norm(xy[:4] - spot, axis=-1))  # the red cubes, nearest first
        pos, quat = [], []
        prev = jnp.zeros(())  # the home pose's yaw
        for level in range(2):
            c = order[level]
            cube = jnp.append(xy[c], SIZE / 2)
            g, put = self.grasp_yaw(xy, yaw, c, prev, p["task_yaw"])
            prev = put
            carry = jnp.append(spot, CARRY_Z + level * SIZE)
            place = jnp.append(spot, SIZE / 2 + level * SIZE + PLACE_GAP)
            pos += [cube.at[2].set(ABOVE_Z), cube, cube, cube.at[2].set(CARRY_Z), carry, place, place, carry]
            quat += [down_quat(g)] * 4 + [down_quat(put)] * 4
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0] * 2)
        return WaypointPlan(pos=jnp.stack(pos), quat=jnp.stack(quat), grip=grip)

    # ------------------------------------------------------------------ predicates
    def red_positions(self, data) -> jax.Array:
        return data.qpos[self.red_qadr[:, None] + np.arange(3)]

    def detected(self, data, scene) -> jax.Array:
        """(4,) bool: each red cube's centre inside the spot's sensor column (turned with the task)."""
        centre = jnp.append(jnp.asarray(self.spot), self.region_z)
        rot = geo.rot_z(scene.params["task_yaw"])
        return in_box(self.red_positions(data), centre, rot, self.region_half)

    def is_success(self, progress, data, grasp, scene):
        inside = self.detected(data, scene)
        stacked = jnp.any(inside & (self.red_positions(data)[:, 2] > SIZE))
        return (jnp.sum(inside) >= 2) & stacked & ~grasp.any
