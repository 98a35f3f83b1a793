"""SB — stack blocks: stack two of the four red cubes on the marked spot; other colours distract.

RLBench's ``stack_blocks`` (variation "stack 2 red blocks"): 4 target-coloured blocks and 4
distractors spawned in a boundary; success = DetectedSeveralCondition(target blocks, the sensor
over the target plane, 2) AND nothing grasped. Here the sensor is a column over the spot (0.03 m
half-width, tested on the cube centres); since two cubes side by side could both have their
centres in it, one of the counted red cubes must also be on the second level (centre higher than
one cube size), i.e. really stacked. Distractors never count and grasping one is not a failure
(RLBench has no failure condition either).

Expert: the two red cubes nearest to the spot, nearest first; for each a top-down grasp aligned
with the cube's yaw, lift, carry over the spot, lower onto the spot (or onto the first cube),
open, back up. Two pick-and-place cycles: 392 control steps, long on purpose (the paper's SB
demos are ~350-400 frames).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import down_quat, free_adr, in_box, set_free_body

SIZE = 0.045  # cube edge
LOW, HIGH = (0.32, -0.3), (0.72, 0.3)
MIN_DIST = 0.085  # between cube centres
SPOT_CLEAR = 0.11  # cube centres from the spot
TRIES = 1024
CARRY_Z = 0.15  # tcp height while carrying
# distractor colours: the shared palette without the reds' look-alikes
_DISTRACTOR_PALETTE = jnp.array([c for n, c in sampling.PALETTE.items() if n not in ("orange", "magenta")],
                                jnp.float32)
# one pick-and-place: above, descend, settle, close, lift, carry, lower, settle, open, up
_CYCLE = (35, 20, 5, 25, 20, 35, 20, 6, 12, 18)


def place_cubes(key, n, low, high, min_dist, spot, spot_clear, tries=TRIES):
    """n points in [low, high] pairwise >= min_dist apart and >= spot_clear from ``spot``.

    Like :func:`sampling.separated_points` (first valid of ``tries`` candidate sets, the best
    separated one if none is valid), with the spot as an extra keep-out point.
    """
    low, high = jnp.asarray(low, jnp.float32), jnp.asarray(high, jnp.float32)
    pts = jax.random.uniform(key, (tries, n, 2), minval=low, maxval=high)
    diff = pts[:, :, None, :] - pts[:, None, :, :]
    pair = (jnp.linalg.norm(diff, axis=-1) + jnp.eye(n) * 1e3).min(axis=(1, 2))
    clear = jnp.linalg.norm(pts - jnp.asarray(spot), axis=-1).min(axis=1)
    margin = jnp.minimum(pair - min_dist, clear - spot_clear)
    ok = margin >= 0
    pick = jnp.where(jnp.any(ok), jnp.argmax(ok), jnp.argmax(margin))
    return pts[pick]


class StackBlocks(TaskEnv):
    name = "stack_blocks"
    code = "SB"
    xml = "stack_blocks.xml"
    description = "stack two of the four red cubes on the marked spot; other colours are distractors"
    graspable = tuple(f"red{i}" for i in range(4)) + tuple(f"distractor{i}" for i in range(4))
    recolour_geoms = tuple(f"distractor{i}" for i in range(4))
    expert_durations = _CYCLE + _CYCLE

    def setup(self):
        m = self.mj_model
        self.red_qadr = np.array([free_adr(m, f"red{i}") for i in range(4)], np.int32)
        self.distractor_qadr = np.array([free_adr(m, f"distractor{i}") for i in range(4)], np.int32)
        self.cube_qadr = np.concatenate([self.red_qadr, self.distractor_qadr])
        site = m.site("target_region")
        self.region_pos = np.array(site.pos, np.float32)
        self.region_half = np.array(site.size, np.float32)
        self.spot = np.array(m.geom("spot").pos[:2], np.float32)

    def sample_scene(self, key):
        k_pos, k_yaw, k_col = jax.random.split(key, 3)
        xy = place_cubes(k_pos, 8, LOW, HIGH, MIN_DIST, self.spot, SPOT_CLEAR)
        yaw = jax.random.uniform(k_yaw, (8,), minval=-jnp.pi / 4, maxval=jnp.pi / 4)
        scene = self.default_scene()
        qpos = scene.qpos
        for i, adr in enumerate(self.cube_qadr):
            pos = jnp.array([xy[i, 0], xy[i, 1], SIZE / 2])
            qpos = set_free_body(qpos, int(adr), pos, geo.yaw_quat(yaw[i]))
        idx = jax.random.choice(k_col, _DISTRACTOR_PALETTE.shape[0], (4,), replace=False)
        rgba = jnp.concatenate([_DISTRACTOR_PALETTE[idx], jnp.ones((4, 1))], axis=1)
        return scene.replace(qpos=qpos, rgba=rgba, params={"xy": xy, "yaw": yaw})

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        xy, yaw = scene.params["xy"][:4], scene.params["yaw"][:4]  # the red cubes
        order = jnp.argsort(jnp.linalg.norm(xy - jnp.asarray(self.spot), axis=-1))
        spot = jnp.asarray(self.spot)
        place_q = down_quat(0.0)
        pos, quat = [], []
        for level in range(2):
            c = order[level]
            cube = jnp.array([xy[c, 0], xy[c, 1], SIZE / 2])
            q = down_quat(yaw[c])
            carry = jnp.array([spot[0], spot[1], CARRY_Z + level * SIZE])
            place = jnp.array([spot[0], spot[1], SIZE / 2 + level * SIZE + 0.004])
            lift = cube.at[2].set(CARRY_Z)
            pos += [cube.at[2].set(0.13), cube, cube, cube, lift, carry, place, place, place, carry]
            quat += [q, q, q, q, q, place_q, place_q, place_q, place_q, place_q]
        grip = jnp.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0] * 2)
        return WaypointPlan(pos=jnp.stack(pos), quat=jnp.stack(quat), grip=grip)

    # ------------------------------------------------------------------ predicates
    def red_positions(self, data) -> jax.Array:
        return data.qpos[self.red_qadr[:, None] + np.arange(3)]

    def is_success(self, progress, data, grasp, scene):
        p = self.red_positions(data)
        inside = in_box(p, jnp.asarray(self.region_pos), jnp.eye(3), self.region_half)
        stacked = jnp.any(inside & (p[:, 2] > SIZE))
        return (jnp.sum(inside) >= 2) & stacked & ~grasp.any
