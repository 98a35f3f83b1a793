"""RT — reach target: put the gripper tip inside the red sphere, ignoring two distractors.

RLBench (``rlbench/tasks/reach_target.py``): a static workspace (``is_static_workspace`` is True and
``base_rotation_bounds`` is zero, l.43-51), so the task model is never moved or turned. The target
and two distractor spheres are sampled one after another in the 3-D ``boundary`` with
``SpawnBoundary.sample(ob, min_distance=0.2, min_rotation=(0, 0, 0), max_rotation=(0, 0, 0))``
(l.31-34): each is drawn uniformly where its bounding box stays inside the boundary, up to 100 times,
until it is at least 0.2 m from every sphere placed before it. Success is the single
``DetectedCondition(arm tip, success)`` (l.18-20), where ``success`` is a proximity sensor around the
target. 20 colour variations; the paper's setting is a red target, distractor colours drawn per
episode (two distinct non-red colours, as RLBench's ``np.random.choice(..., replace=False)``).

readjax: the same sequential draw (:func:`spawn_points`, 100 candidates per sphere, the first one at
least 0.2 m from the spheres placed before); ``scene_ok`` keeps a candidate only if all three are
pairwise at least 0.2 m apart (RLBench raises and redraws when a sphere finds no place). Success: the
tcp site (the arm tip) inside the sensor volume, a sphere of radius 3 cm around the target's centre.

Sizes (RLBench's are in ``reach_target.ttm``, unreadable here): the spheres are 6 cm across (about a
tennis ball) and the sensor volume is the visible sphere itself, so "inside the ball" is what
succeeds. The boundary holds sphere centres in x [0.3, 0.7], y [-0.3, 0.3], z [0.12, 0.45] m (the
boundary box is this grown by the 3 cm radius): in front of the robot, above the table, below the
camera's view top. Expert: the tcp straight to the target, pointing down, then a short hold.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from readjax.sim import placement
from readjax.sim.controller import WaypointPlan
from readjax.sim.env import Scene, TaskEnv
from readjax.tasks import sampling
from readjax.tasks.common import down_quat, mocap_index

RADIUS = 0.03  # sphere radius = the success sensor's radius
LOW, HIGH = (0.3, -0.3, 0.12), (0.7, 0.3, 0.45)  # sphere centres (the boundary less the radius)
MIN_DIST = 0.2  # RLBench's min_distance
SPAWN_SAMPLES = 100  # RLBench's SpawnBoundary.MAX_SAMPLES


def spawn_points(key: jax.Array, n: int, low, high, min_dist: float, samples: int = SPAWN_SAMPLES) -> jax.Array:
    """n points (n, d) drawn one after another as RLBench's ``SpawnBoundary.sample``: each is the first
    of ``samples`` uniform candidates in [low, high] at least ``min_dist`` from the points before it
    (the first candidate if none is; ``scene_ok`` then rejects the scene)."""
    low, high = jnp.asarray(low, jnp.float32), jnp.asarray(high, jnp.float32)
    cands = jax.random.uniform(key, (n, samples, low.shape[0]), minval=low, maxval=high)
    placed = [cands[0, 0]]
    for i in range(1, n):
        d = jnp.linalg.norm(cands[i][:, None] - jnp.stack(placed)[None], axis=-1).min(1)
        placed.append(cands[i, jnp.argmax(d >= min_dist)])
    return jnp.stack(placed)


class ReachTarget(TaskEnv):
    name = "reach_target"
    code = "RT"
    xml = "reach_target.xml"
    description = "move the gripper tip into the red sphere; two other spheres are distractors"
    recolour_geoms = ("distractor0", "distractor1")
    expert_durations = (45, 10)  # reach, settle

    def setup(self):
        m = self.mj_model
        self.target_mocap = mocap_index(m, "target")
        self.distractor_mocap = [mocap_index(m, f"distractor{i}") for i in range(2)]
        self.tcp_site = m.site("tcp").id

    def draw_scene(self, key):
        k_pos, k_col = jax.random.split(key)
        pts = spawn_points(k_pos, 3, LOW, HIGH, MIN_DIST)  # target, distractor0, distractor1
        scene = self.default_scene()
        mocap = scene.mocap_pos.at[self.target_mocap].set(pts[0])
        mocap = mocap.at[jnp.array(self.distractor_mocap)].set(pts[1:])
        return scene.replace(mocap_pos=mocap, rgba=sampling.distractor_colours(k_col, 2),
                             params={"target": pts[0]})

    def scene_ok(self, scene):
        idx = jnp.array([self.target_mocap] + self.distractor_mocap)
        return placement.min_pairwise_distance(scene.mocap_pos[idx]) >= MIN_DIST

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        target = scene.params["target"]
        pos = jnp.stack([target, target])
        quat = jnp.stack([down_quat(0.0)] * 2)
        return WaypointPlan(pos=pos, quat=quat, grip=jnp.ones(2))

    def landmarks(self, scene):
        return {"target": scene.mocap_pos[self.target_mocap][None],
                "distractor": scene.mocap_pos[jnp.array(self.distractor_mocap)]}

    def goal(self, scene):
        return scene.mocap_pos[..., self.target_mocap, :]

    def move_goal(self, scene, delta):
        delta = jnp.asarray(delta, jnp.float32)
        mocap = jnp.asarray(scene.mocap_pos).at[..., self.target_mocap, :].add(delta)
        return scene.replace(mocap_pos=mocap, params={**scene.params, "target": scene.params["target"] + delta})

    def is_success(self, progress, data, grasp, scene):
        """RLBench's DetectedCondition(tip, success): the tcp inside the sensor sphere."""
        tip = data.site_xpos[self.tcp_site]
        return jnp.linalg.norm(tip - data.mocap_pos[self.target_mocap]) < RADIUS
