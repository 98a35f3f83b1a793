"""PK — put knife: pull the knife straight up out of its block and lay it on the cutting board.

RLBench's ``put_knife_on_chopping_board``: the knife starts standing in a knife block (spawned
in a boundary), the chopping board is fixed; success is the ordered ConditionSet
[knife detected by the board's proximity sensor, nothing grasped].

Here the "sensor" is the board region (board footprint, up to 6 cm above its top) tested on the
knife's midpoint (its body origin). The order is kept with a progress flag: ``on_board_held`` is
set once the knife is in the region while grasped; success is that flag AND nothing grasped AND
the knife still in the region (slightly stricter than RLBench, which would also accept carrying
the knife over the board and dropping it elsewhere).

Expert: top-down grasp on the handle (the fingers close across the handle's 28 mm side), pull
straight up until the tip clears the block, carry it over the board while turning the hand to
point sideways (tcp along -y, fingers horizontal) so the knife lies flat, lower it to ~3 cm above
the board, open, back off. (A flat knife with the fingers closing on its 16 mm side would need the
hand 12 cm above the board; pointing forward at that height is outside the Panda's reach.)
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks.common import down_quat, free_adr, in_box, mocap_index, set_free_body

BLOCK_LOW, BLOCK_HIGH = (0.36, 0.06), (0.62, 0.28)
KNIFE_Z = 0.115  # knife midpoint above the table while standing in the block (tip on the table)
GRASP = 0.065  # tcp position on the knife axis (handle middle), from the knife midpoint
PULL = 0.17  # straight pull: the tip ends 4 cm above the block's top
PLACE_TCP_Z = 0.06  # tcp height at release: the knife ~3 cm above the board
# Tcp orientation for laying the knife flat: z along -y (the blade points -y), fingers along +x.
_FLAT = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]], np.float32)  # columns x, y, z


class PutKnife(TaskEnv):
    name = "put_knife"
    code = "PK"
    xml = "put_knife.xml"
    description = "pull the knife straight up out of its block and put it on the cutting board"
    graspable = ("knife",)
    # above, descend, close, pull up, carry+turn, lower, settle, open, back off
    expert_durations = (40, 20, 25, 35, 50, 25, 8, 12, 20)

    def setup(self):
        m = self.mj_model
        self.knife_qadr = free_adr(m, "knife")
        self.block_mocap = mocap_index(m, "knife_block")
        site = m.site("board_region")
        self.region_pos = np.array(site.pos, np.float32)
        self.region_half = np.array(site.size, np.float32)
        board = m.geom("board")
        self.board_centre = np.array(board.pos, np.float32)
        self.board_top = float(board.pos[2] + board.size[2])

    def sample_scene(self, key):
        xy = jax.random.uniform(key, (2,), minval=jnp.array(BLOCK_LOW), maxval=jnp.array(BLOCK_HIGH))
        scene = self.default_scene()
        block = jnp.array([xy[0], xy[1], 0.0])
        mocap = scene.mocap_pos.at[self.block_mocap].set(block)
        qpos = set_free_body(scene.qpos, self.knife_qadr, block + jnp.array([0.0, 0.0, KNIFE_Z]),
                             jnp.array([1.0, 0, 0, 0]))
        return scene.replace(qpos=qpos, mocap_pos=mocap, params={"block": block})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        b = scene.params["block"]
        grasp = b + jnp.array([0.0, 0.0, KNIFE_Z + GRASP])
        pulled = grasp + jnp.array([0.0, 0.0, PULL])
        # knife midpoint over the board centre: the tcp sits GRASP further along +y (the handle side)
        place = jnp.array([self.board_centre[0], self.board_centre[1] + GRASP, PLACE_TCP_Z])
        over = place + jnp.array([0.0, 0.0, 0.1])
        back = place + jnp.array([0.0, 0.08, 0.06])
        down = down_quat(-jnp.pi / 2)  # fingers along +x: across the handle's wide side
        flat = geo.mat_to_quat(jnp.asarray(_FLAT))
        above = grasp + jnp.array([0.0, 0.0, 0.1])
        pos = jnp.stack([above, grasp, grasp, pulled, over, place, place, place, back])
        quat = jnp.stack([down, down, down, down, flat, flat, flat, flat, flat])
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    # ------------------------------------------------------------------ predicates
    def knife_on_board(self, data) -> jax.Array:
        p = data.qpos[self.knife_qadr:self.knife_qadr + 3]
        return in_box(p, jnp.asarray(self.region_pos), jnp.eye(3), self.region_half)

    def init_progress(self):
        return {"on_board_held": jnp.zeros((), bool)}

    def update_progress(self, progress, data, grasp, scene):
        held = grasp.attached[0] & self.knife_on_board(data)
        return {"on_board_held": progress["on_board_held"] | held}

    def is_success(self, progress, data, grasp, scene):
        return progress["on_board_held"] & ~grasp.any & self.knife_on_board(data)
