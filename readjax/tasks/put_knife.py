"""PK — put knife: pull the knife straight up out of its block and lay it on the chopping board.

RLBench's ``put_knife_on_chopping_board`` (``rlbench/tasks/put_knife_on_chopping_board.py``): the
knife block is sampled in the task's ``boundary`` with SpawnBoundary's default yaw +-3.14 (l.15,
23-24); the board is part of the task model; the whole task is placed by ``Scene._place_task`` with
the default ``base_rotation_bounds`` +-3.14; success is the ordered
``ConditionSet([DetectedCondition(knife, success), NothingGrasped], order_matters=True)`` (l.17-20):
the knife detected by the board's sensor at some step, then nothing grasped at that step or later
(``backend/conditions.py:146-173``; the knife may be released anywhere once it was detected). Here:

* Task frame (:func:`readjax.sim.placement.place_task`, yaw +-pi): the board centred at (0, -0.11)
  with its long side along x, the block's boundary x [-0.15, 0.15] x y [0.02, 0.20] beside it; the
  footprint (board + boundary) is x [-0.15, 0.15] x y [-0.21, 0.20].
* Block: :func:`readjax.sim.placement.spawn_in_boundary` in that boundary, yaw +-pi, its box
  0.10 x 0.08 m (RLBench's min_distance concerns other objects in the boundary: there are none).
* Success: progress ``detected`` latches the knife's midpoint (its body origin) inside the sensor
  (the board's footprint, from its top to 6 cm above); success = ``detected`` AND nothing grasped.
* Sizes (real-world; RLBench's are in the unreadable .ttm): a 0.23 m kitchen knife (blade
  0.13 x 0.026 m, handle 0.10 x 0.028 x 0.016 m), a 0.10 x 0.08 x 0.13 m block, a 0.30 x 0.20 x
  0.02 m chopping board; the sensor's 6 cm height is ours.

Expert: the fingers close across the handle's 28 mm side with the hand tilted 45 deg between
horizontal and straight down, approaching the blade's face (``GRASP_TILT``); pull straight up until
the tip clears the block; carry over the board while turning so the knife lies flat along the
board (the hand then leans 45 deg from vertical); lower to ~1 cm above the board, open, back off.
Of the symmetric choices (which face the hand approaches, which way the tip points on the board,
which finger is which) the expert takes the one its IK follows best (:meth:`PutKnife.choose`).
The 45 deg tilt: with 30, 60 or 90 deg (90 = the former top-down pick and horizontal hand on the
board) 5-9 % of first placements had no choice the IK could follow; with 45 deg 4 % (128 seeds).
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import free_adr, in_box, mocap_index, set_free_body

BOARD_LOCAL = np.array([0.0, -0.11], np.float32)  # board centre in the task frame (long side along x)
BOUNDARY_LOW, BOUNDARY_HIGH = np.array([-0.15, 0.02], np.float32), np.array([0.15, 0.20], np.float32)
FOOTPRINT_MIN, FOOTPRINT_MAX = np.array([-0.15, -0.21], np.float32), np.array([0.15, 0.20], np.float32)
BLOCK_HALF = np.array([0.05, 0.04], np.float32)
KNIFE_Z = 0.115  # knife midpoint above the table while standing in the block (tip on the table)
GRASP = 0.065  # tcp on the knife axis (handle middle), from the knife midpoint
GRASP_TILT = np.pi / 4  # the approach's tilt below horizontal at the pick
PULL = 0.17  # straight pull: the tip ends 4 cm above the block's top
PLACE_Z = 0.04  # knife midpoint height at release: ~1 cm above the board
# the symmetric choices: approached face s, tip direction tau along the board, finger sign sigma
COMBOS = np.array(list(itertools.product((1.0, -1.0), repeat=3)), np.float32)


def grasp_in_knife(s, sigma):
    """The tcp's rotation in the knife frame (x blade width, y blade normal, z towards the handle):
    fingers along sigma*x, approach into face s*y, tilted GRASP_TILT towards the tip."""
    y = jnp.array([sigma, 0.0, 0.0])
    z = jnp.array([0.0, s * np.cos(GRASP_TILT), -np.sin(GRASP_TILT)])
    return jnp.stack([jnp.cross(y, z), y, z], -1)


def task_to_world(origin, yaw, local):
    """A task-frame point (2,) -> world (3,) on the table (:func:`readjax.sim.placement.to_world`)."""
    return placement.to_world(origin, yaw, jnp.stack([local[0], local[1], jnp.zeros_like(yaw)]))


class PutKnife(TaskEnv):
    name = "put_knife"
    code = "PK"
    xml = "put_knife.xml"
    description = "pull the knife straight up out of its block and put it on the chopping board"
    graspable = ("knife",)
    # above, descend, close, pull up, carry+turn, lower, settle, open, back off
    expert_durations = (40, 20, 25, 35, 60, 25, 8, 12, 20)

    def setup(self):
        m = self.mj_model
        self.knife_qadr = free_adr(m, "knife")
        self.block_mocap = mocap_index(m, "knife_block")
        self.board_mocap = mocap_index(m, "board")
        site = m.site("board_region")
        self.region_pos = np.array(site.pos, np.float32)  # in the board's frame
        self.region_half = np.array(site.size, np.float32)
        self.board_top = float(m.geom("board").pos[2] + m.geom("board").size[2])

    def draw_scene(self, key):
        k_task, k_block = jax.random.split(key)
        origin, yaw, fits = placement.place_task(k_task, FOOTPRINT_MIN, FOOTPRINT_MAX)
        local, block_yaw, fits_b = placement.spawn_in_boundary(k_block, BOUNDARY_LOW, BOUNDARY_HIGH,
                                                                -BLOCK_HALF, BLOCK_HALF)
        block = task_to_world(origin, yaw, local)
        board = task_to_world(origin, yaw, BOARD_LOCAL)
        omega = yaw + block_yaw
        scene = self.default_scene()
        mpos = scene.mocap_pos.at[self.block_mocap].set(block).at[self.board_mocap].set(board)
        mquat = scene.mocap_quat.at[self.block_mocap].set(geo.yaw_quat(omega)).at[self.board_mocap].set(
            geo.yaw_quat(yaw))
        qpos = set_free_body(scene.qpos, self.knife_qadr, block + jnp.array([0.0, 0.0, KNIFE_Z]), geo.yaw_quat(omega))
        return scene.replace(qpos=qpos, mocap_pos=mpos, mocap_quat=mquat,
                             params={"block": block, "block_yaw": omega, "board": board, "yaw": yaw,
                                     "fits": fits & fits_b})

    def scene_ok(self, scene):
        return scene.params["fits"]

    # ------------------------------------------------------------------ expert
    def plan_with(self, scene: Scene, combo) -> WaypointPlan:
        s, tau, sigma = combo[0], combo[1], combo[2]
        g = grasp_in_knife(s, sigma)
        k_pick = geo.rot_z(scene.params["block_yaw"])
        a = geo.rot_z(scene.params["yaw"]) @ jnp.array([1.0, 0.0, 0.0])  # the board's long axis
        zb = tau * a
        yb = jnp.array([0.0, 0.0, -s])
        k_place = jnp.stack([jnp.cross(yb, zb), yb, zb], -1)
        mid_pick = scene.params["block"] + jnp.array([0.0, 0.0, KNIFE_Z])
        mid_place = scene.params["board"] + jnp.array([0.0, 0.0, PLACE_Z])
        r_pick, r_place = k_pick @ g, k_place @ g
        grasp = mid_pick + k_pick @ jnp.array([0.0, 0.0, GRASP])
        place = mid_place + k_place @ jnp.array([0.0, 0.0, GRASP])
        up = jnp.array([0.0, 0.0, 1.0])
        pulled = grasp + PULL * up
        pos = jnp.stack([grasp - 0.10 * r_pick[:, 2], grasp, grasp, pulled, place + 0.10 * up, place, place, place,
                         place - 0.08 * r_place[:, 2] + 0.03 * up])
        q_pick, q_place = geo.mat_to_quat(r_pick), geo.mat_to_quat(r_place)
        quat = jnp.stack([q_pick] * 4 + [q_place] * 5)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        """Of the symmetric options (``COMBOS``), the one the arm follows most easily."""
        return self.easiest_plan(jax.vmap(lambda c: self.plan_with(scene, c))(jnp.asarray(COMBOS)))

    # ------------------------------------------------------------------ predicates
    def knife_on_board(self, data) -> jax.Array:
        p = data.qpos[self.knife_qadr:self.knife_qadr + 3]
        rot = geo.quat_to_mat(data.mocap_quat[self.board_mocap])
        centre = data.mocap_pos[self.board_mocap] + rot @ jnp.asarray(self.region_pos)
        return in_box(p, centre, rot, self.region_half)

    def init_progress(self):
        return {"detected": jnp.zeros((), bool)}

    def update_progress(self, progress, data, grasp, scene):
        return {"detected": progress["detected"] | self.knife_on_board(data)}

    def is_success(self, progress, data, grasp, scene):
        return progress["detected"] & ~grasp.any
