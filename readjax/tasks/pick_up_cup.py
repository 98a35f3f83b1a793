"""PC — pick up cup: grasp the red cup by its rim and lift it; the other cup is a distractor.

RLBench (``rlbench/tasks/pick_up_cup.py``): success is ``DetectedCondition(cup1, success,
negated=True)`` AND ``GraspedCondition(gripper, cup1)`` (l.21-24): the red cup grasped and out of the
``success`` proximity sensor. Each episode ``cup2`` and then the ``success`` sensor are sampled in
``boundary`` with ``min_distance=0.1`` and the default yaw +-3.14 (l.38-40); ``cup1`` is not sampled
itself, so it rides with the sensor (inferred: it is its child in ``pick_up_cup.ttm``), i.e. the
sensor is a volume around the red cup's start. The task overrides neither ``is_static_workspace``
nor ``base_rotation_bounds``: the whole model (boundary, cups, sensor) is placed at a random
workspace pose with yaw +-pi (``backend/scene.py:529-537``). 20 colour variations; the paper's
setting is a red target with the distractor's colour drawn per episode.

readjax: the boundary is the task model's bounding box, placed by
:func:`readjax.sim.placement.place_task` (yaw +-pi); in its frame the distractor and then the
sensor (carrying the red cup) are drawn by :func:`readjax.sim.placement.spawn_in_boundary` (yaw
+-pi, the turned bounding box inside the boundary), the sensor redrawn up to 100 times (RLBench's
``SpawnBoundary.MAX_SAMPLES``) until it is at least 0.1 m from the distractor; ``scene_ok`` rejects a
scene where it never was. Success: the red cup attached (RLBench's grasp is also a kinematic
attachment) AND no point of it in the sensor box (every corner of its wall and bottom boxes outside:
lifted above it, or carried out sideways), latched. Failure (sticky), added from the paper: grasping
the distractor (Paper l.11 calls picking the wrong cup a failure; RLBench does not register it).

Sizes (RLBench's are in ``pick_up_cup.ttm``, unreadable here): cups 7.5 cm across and 9 cm tall (a
coffee mug, tasks_mjcf/pick_up_cup.xml); a 30 x 40 cm boundary (a placemat); the sensor a 10 x 10 cm
box from the table up to 10 cm, just enclosing the cup at rest (1 cm above its rim), so the cup's
bottom must be lifted more than 10 cm.

Expert: a rim grasp on the wall facing away from the distractor (the outer finger then never
meets it), the fingers opening radially, at the hand yaw (modulo pi: the gripper is symmetric)
nearest joint 7's centre; above, down, close, lift 20 cm, hold.
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
from readjax.tasks.common import down_quat, free_adr, in_box, set_free_body

WALL_CENTRE = 0.0345  # radius of the wall boxes' centres
WALLS = 8  # wall k faces the cup-frame angle k * 45 degrees
RIM = 0.09
BOUNDARY = np.array([0.15, 0.20], np.float32)  # half size of the boundary: the task's bounding box
CUP_HALF = np.array([0.0375, 0.0375], np.float32)  # a cup's bounding square (half size)
SENSOR_HALF = np.array([0.05, 0.05, 0.05], np.float32)  # the success sensor box, its centre 5 cm up
MIN_DIST = 0.1  # RLBench's min_distance
SPAWN_SAMPLES = 100  # RLBench's SpawnBoundary.MAX_SAMPLES
GRASP_DEPTH = 0.02  # tcp below the rim at the grasp
LIFT = 0.2  # m the expert lifts


def corner_points(model, body: str) -> np.ndarray:
    """(n, 3) corners of every box geom of a body, in the body frame."""
    pts = []
    b = model.body(body).id
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float32)
    for g in np.flatnonzero(model.geom_bodyid == b):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        rot = np.asarray(geo.quat_to_mat(jnp.asarray(model.geom_quat[g], jnp.float32)))
        pts.append(model.geom_pos[g] + (signs * model.geom_size[g]) @ rot.T)
    return np.concatenate(pts).astype(np.float32)


def frame_point(origin, yaw, local):
    """A task-frame point (2,) -> world (3,) on the table (:func:`readjax.sim.placement.to_world`)."""
    return placement.to_world(origin, yaw, jnp.stack([local[0], local[1], jnp.zeros_like(yaw)]))


def rim_grasp(cup: jax.Array, cup_yaw: jax.Array, away: jax.Array) -> tuple[jax.Array, jax.Array]:
    """tcp position (3,) and hand yaw () of a rim grasp on the wall whose outward direction is nearest
    the world angle ``away``; the hand yaw (mod pi) nearest joint 7's centre (about atan2(y, x) + pi/4
    for a down-pointing tcp)."""
    k = jnp.round((away - cup_yaw) / (2 * jnp.pi / WALLS))
    wall = cup_yaw + k * 2 * jnp.pi / WALLS
    pos = cup + jnp.stack([WALL_CENTRE * jnp.cos(wall), WALL_CENTRE * jnp.sin(wall), RIM - GRASP_DEPTH])
    centre = jnp.arctan2(pos[1], pos[0]) + jnp.pi / 4
    yaw = wall - jnp.pi / 2  # the fingers open along the wall's normal
    yaw = centre + (yaw - centre + jnp.pi / 2) % jnp.pi - jnp.pi / 2
    return pos, yaw


class PickUpCup(TaskEnv):
    name = "pick_up_cup"
    code = "PC"
    xml = "pick_up_cup.xml"
    description = "grasp and lift the red cup; the other cup is a distractor"
    graspable = ("cup", "distractor")
    recolour_geoms = ("distractor_bottom",) + tuple(f"distractor_wall{k}" for k in range(8))
    expert_durations = (45, 25, 25, 35, 10)  # above, descend, close, lift, hold

    def setup(self):
        m = self.mj_model
        self.cup_qadr = free_adr(m, "cup")
        self.distractor_qadr = free_adr(m, "distractor")
        self.cup_points = corner_points(m, "cup")

    def draw_scene(self, key):
        k_task, k_cup2, k_sensor, k_col = jax.random.split(key, 4)
        origin, task_yaw, fits_task = placement.place_task(k_task, -BOUNDARY, BOUNDARY)
        xy2, yaw2, fits2 = placement.spawn_in_boundary(k_cup2, -BOUNDARY, BOUNDARY, -CUP_HALF, CUP_HALF)
        spawn = jax.vmap(lambda k: placement.spawn_in_boundary(k, -BOUNDARY, BOUNDARY, -SENSOR_HALF[:2],
                                                               SENSOR_HALF[:2]))
        xys, yaws, fitss = spawn(jax.random.split(k_sensor, SPAWN_SAMPLES))
        good = fitss & (jnp.linalg.norm(xys - xy2, axis=-1) >= MIN_DIST)
        i = jnp.argmax(good)
        cup = frame_point(origin, task_yaw, xys[i])
        distractor = frame_point(origin, task_yaw, xy2)
        cup_yaw, distractor_yaw = task_yaw + yaws[i], task_yaw + yaw2
        scene = self.default_scene()
        qpos = set_free_body(scene.qpos, self.cup_qadr, cup, geo.yaw_quat(cup_yaw))
        qpos = set_free_body(qpos, self.distractor_qadr, distractor, geo.yaw_quat(distractor_yaw))
        colour = sampling.distractor_colours(k_col, 1)
        rgba = jnp.tile(colour, (len(self.recolour_geoms), 1))
        return scene.replace(qpos=qpos, rgba=rgba, params={
            "cup": cup, "cup_yaw": cup_yaw, "distractor": distractor, "task_yaw": task_yaw,
            "fits": fits_task & fits2 & good[i]})

    def scene_ok(self, scene):
        p = scene.params
        return p["fits"] & (jnp.linalg.norm(p["cup"][:2] - p["distractor"][:2]) >= MIN_DIST)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        cup, other = scene.params["cup"], scene.params["distractor"]
        away = jnp.arctan2(cup[1] - other[1], cup[0] - other[0])
        grasp, yaw = rim_grasp(cup, scene.params["cup_yaw"], away)
        above = grasp + jnp.array([0.0, 0.0, 0.12])
        lift = grasp + jnp.array([0.0, 0.0, LIFT])
        pos = jnp.stack([above, grasp, grasp, lift, lift])
        quat = jnp.stack([down_quat(yaw)] * 5)
        grip = jnp.array([1.0, 1.0, 0.0, 0.0, 0.0])
        return WaypointPlan(pos=pos, quat=quat, grip=grip)

    def cup_detected(self, data, scene) -> jax.Array:
        """RLBench's DetectedCondition(cup1, success): some point of the red cup inside the sensor box
        (centred SENSOR_HALF[2] above the cup's start, turned with it)."""
        q = data.qpos[self.cup_qadr:self.cup_qadr + 7]
        points = q[:3] + jnp.asarray(self.cup_points) @ geo.quat_to_mat(q[3:]).T
        centre = scene.params["cup"] + jnp.array([0.0, 0.0, SENSOR_HALF[2]])
        rot = geo.rot_z(scene.params["cup_yaw"])
        return jnp.any(in_box(points, centre, rot, SENSOR_HALF))

    def is_success(self, progress, data, grasp, scene):
        return grasp.attached[0] & ~self.cup_detected(data, scene)

    def is_failure(self, progress, data, grasp, scene):
        """The paper's rule: grasping the distractor cup is a failure."""
        return grasp.attached[1]
