"""The task-environment layer: pure ``reset``/``step`` over MJX, in the style of MuJoCo Playground.

A task subclasses :class:`TaskEnv` and supplies data (its MJCF file, graspable bodies,
recolourable geoms, the durations of its expert's segments) and four pure functions:
``sample_scene`` (randomisation), ``expert_plan`` (scripted waypoints), ``update_progress``
(memory the success predicate needs, e.g. "was the knife on the board before release") and
``is_success`` / ``is_failure``. Everything else — physics substeps, gripper ramp, grasp
attachment, pinned fixtures, success bookkeeping — is shared here.

Fixtures placed per episode (a button base, a box, a rack) are bodies with a free joint listed
in ``fixtures``: their pose comes from the scene's qpos and is pinned there after every
substep. (MJX applies mocap poses after its kinematic tree pass, so children of a mocap body
do not follow it; mocap bodies are used only for childless fixtures such as RT's spheres.) The ``mjx.Model`` is closed over, never
passed to jit (hashing its numpy fields costs ~5 ms a call; ../shared/STACK.md).
"""

from __future__ import annotations

from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from jax import lax

from readjax.prng import seed_pure
from readjax.sim import mjx
from readjax.sim.controller import WaypointPlan, kinematic_tracking
from readjax.sim.grasp import GraspSpec, GraspState
from readjax.sim.kinematics import FINGER_JOINTS, FINGER_MAX, HOME_Q, chain_from_model
from readjax.sim.scene import load_model
from readjax.sim import placement

GRIPPER_SPEED = 0.1  # m/s per finger: an instant close tunnels through thin walls


@struct.dataclass
class Scene:
    """Everything random about an episode, sampled from its seed."""

    qpos: jax.Array  # (nq,) initial joint positions (arm at home, objects placed)
    mocap_pos: jax.Array  # (nmocap, 3) fixtures (button base, box, ...) as mocap bodies
    mocap_quat: jax.Array  # (nmocap, 4)
    rgba: jax.Array  # (len(recolour_geoms), 4) per-episode colours (rendering only)
    params: dict[str, jax.Array]  # task-specific values (targets, choices)


@struct.dataclass
class EnvState:
    data: Any  # mjx.Data
    scene: Scene
    grasp: GraspState
    progress: dict[str, jax.Array]
    success: jax.Array  # () bool: the success condition held at some control step
    failure: jax.Array  # () bool: a terminal failure happened (e.g. the wire was touched)
    finger_target: jax.Array  # () current (ramped) finger position command
    step: jax.Array  # () int32 control steps taken


class TaskEnv:
    """Base class of the 16 tasks. Subclasses set the class attributes and the hooks."""

    name: ClassVar[str] = ""
    code: ClassVar[str] = ""
    xml: ClassVar[str] = ""
    description: ClassVar[str] = ""
    graspable: ClassVar[tuple[str, ...]] = ()
    fixtures: ClassVar[tuple[str, ...]] = ()
    recolour_geoms: ClassVar[tuple[str, ...]] = ()
    expert_durations: ClassVar[tuple[int, ...]] = ()
    # every task's control step; its physics substeps follow from the timestep in its XML (5 ms: 4)
    control_dt: ClassVar[float] = 0.02
    # RLBench's rejection of a placement (readjax.sim.placement): candidates drawn until one fits
    # (SpawnBoundary.MAX_SAMPLES), placements validated until the expert's path is reachable
    # (TaskEnvironment's 40 reset attempts), and how closely the expert's IK must follow its path
    max_placement_tries: ClassVar[int] = 100
    max_validation_tries: ClassVar[int] = 40
    reach_tolerance: ClassVar[tuple[float, float]] = (0.01, 0.1)  # m, rad
    joint_limit_margin: ClassVar[float] = 0.02  # rad kept from every joint limit along the path

    def __init_subclass__(cls, **kwargs):
        """A task draws candidates (``draw_scene``); only the base class samples scenes, so every
        scene goes through the same per-seed rejection loop."""
        super().__init_subclass__(**kwargs)
        if "sample_scene" in cls.__dict__:
            raise TypeError(f"{cls.__name__} overrides sample_scene: implement draw_scene (one candidate) "
                            f"and scene_ok (its geometric checks) instead; TaskEnv.sample_scene rejects")

    def __init__(self):
        self.mj_model = load_model(self.xml)
        timestep = float(self.mj_model.opt.timestep)
        self.substeps = int(round(self.control_dt / timestep))
        if abs(self.substeps * timestep - self.control_dt) > 1e-9:
            raise ValueError(f"{self.xml}: the physics timestep {timestep} s does not divide the control step "
                             f"{self.control_dt} s")
        # this process's own first device: in a multi-process run jax.devices()[0] belongs to process 0
        device = jax.local_devices()[0]
        self.mx = mjx.put_model(self.mj_model, device=device)
        self.chain = chain_from_model(self.mj_model)
        self.grasp_spec = GraspSpec(self.mj_model, self.graspable)
        m = self.mj_model
        self.finger_qpos_adr = np.array([m.joint(j).qposadr[0] for j in FINGER_JOINTS], np.int32)
        self.recolour_ids = np.array([m.geom(g).id for g in self.recolour_geoms], np.int32)
        pin_q, pin_v = [], []
        for body in self.fixtures:
            b = m.body(body).id
            jnt = m.body_jntadr[b]
            if m.body_jntnum[b] < 1 or m.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
                raise ValueError(f"fixture {body!r} needs a free joint as its first joint")
            pin_q.extend(range(m.jnt_qposadr[jnt], m.jnt_qposadr[jnt] + 7))
            pin_v.extend(range(m.jnt_dofadr[jnt], m.jnt_dofadr[jnt] + 6))
        self.pinned_qpos_adr = np.array(pin_q, np.int32)
        self.pinned_qvel_adr = np.array(pin_v, np.int32)
        self._data0 = mjx.make_data(self.mx, device=device)
        self.setup()

    # ------------------------------------------------------------------ task hooks
    def setup(self) -> None:
        """Read ids of the task's bodies/geoms/joints from ``self.mj_model``."""

    def draw_scene(self, key: jax.Array) -> Scene:
        """One candidate scene from a threefry ``key``: RLBench's boundary sampling and task placement
        (:mod:`readjax.sim.placement`), before validation."""
        raise NotImplementedError

    def scene_ok(self, scene: Scene) -> jax.Array:
        """() bool: a candidate's geometric checks (it fits, nothing overlaps, distances kept)."""
        return jnp.ones((), bool)

    def sample_scene(self, key: jax.Array) -> Scene:
        """The episode's scene, RLBench's ``Scene.init_episode`` as a per-seed rejection loop: candidates
        (``draw_scene``) are drawn until one passes ``scene_ok`` (it fits; at most
        ``max_placement_tries``), and such placements until the expert can follow its whole path
        (:meth:`expert_reachable`; at most ``max_validation_tries``). Every draw comes from the seed's
        own key stream (``key`` of any implementation becomes a threefry key first), so a scene is a
        function of its seed alone under any batching. ``params["feasible"]`` is False when no
        placement passed (generation drops such a seed, as it drops one whose expert fails);
        ``params["placement_tries"]`` counts the validated placements."""
        key = seed_pure(key)
        (scene, _), ok, tries = placement.first_accepted(key, self._fitting_candidate, self._validate,
                                                         self.max_validation_tries)
        return scene.replace(params={**scene.params, "feasible": ok, "placement_tries": tries})

    def _fitting_candidate(self, key):
        scene, fits, _ = placement.first_accepted(key, self.draw_scene, self.scene_ok, self.max_placement_tries)
        return scene, fits

    def _validate(self, candidate) -> jax.Array:
        scene, fits = candidate
        return fits & self.expert_reachable(scene)

    def expert_reachable(self, scene: Scene) -> jax.Array:
        """() bool: the expert's IK follows its whole path (every control step) within
        ``reach_tolerance`` and keeps ``joint_limit_margin`` from every limit, starting at home."""
        return self._followable(self.expert_plan(scene))[0]

    def _followable(self, plan: WaypointPlan) -> tuple[jax.Array, jax.Array]:
        """(whether the arm can follow ``plan`` from home, its smallest joint-limit margin on the way)."""
        pe, re, margin = kinematic_tracking(self.chain, jnp.asarray(HOME_Q), plan, self.expert_durations)
        tol_p, tol_r = self.reach_tolerance
        return (pe < tol_p) & (re < tol_r) & (margin > self.joint_limit_margin), margin

    def easiest_plan(self, plans: WaypointPlan) -> WaypointPlan:
        """Of candidate expert plans (leaves stacked on a leading axis: the symmetric grasps, approach
        sides or wrist turns a task can choose from), the one the arm can follow with the widest margin
        from its joint limits; the first candidate where none can (the scene is then rejected). An
        expert chooses among its options as RLBench's path planner tries candidate grasps."""
        ok, margin = jax.vmap(self._followable)(plans)
        best = jnp.argmax(jnp.where(ok, margin, -10.0 - jnp.arange(margin.shape[0])))
        return jax.tree.map(lambda x: x[best], plans)

    def expert_plan(self, scene: Scene) -> WaypointPlan:
        raise NotImplementedError

    def init_progress(self) -> dict[str, jax.Array]:
        return {}

    def update_progress(self, progress, data, grasp: GraspState, scene: Scene) -> dict[str, jax.Array]:
        return progress

    def is_success(self, progress, data, grasp: GraspState, scene: Scene) -> jax.Array:
        raise NotImplementedError

    def is_failure(self, progress, data, grasp: GraspState, scene: Scene) -> jax.Array:
        return jnp.zeros((), bool)

    def landmarks(self, scene: Scene) -> dict[str, jax.Array]:
        """Named groups of world points (k, 3) where a plan may end and what that would mean, e.g.
        {"target": ..., "distractor": ...}: evaluation records which group each plan's end point
        is nearest (:mod:`readjax.failure_modes`). Empty for tasks that define none."""
        return {}

    def goal(self, scene: Scene) -> jax.Array | None:
        """The world point (..., 3) a plan must reach, for tasks with one goal object that a scene
        places freely (RT's sphere, PB's button); None elsewhere. With :meth:`move_goal`, what
        :mod:`readjax.lab.goal_shift` moves to ask whether a planner reads the goal from the image."""
        return None

    def move_goal(self, scene: Scene, delta) -> Scene:
        """The same scene (leaves (..., ...), one or a batch) with the goal object moved by ``delta``
        (3,) or (B, 3) metres in the world; everything else where it was."""
        raise ValueError(f"{self.name} defines no single goal object to move (tasks that do: those whose "
                         f"env implements goal / move_goal, e.g. reach_target, push_button)")

    # ------------------------------------------------------------------ helpers for tasks
    @property
    def episode_steps(self) -> int:
        return int(sum(self.expert_durations))

    def default_scene(self) -> Scene:
        """The model's own initial configuration with the arm at home."""
        m = self.mj_model
        qpos = np.array(m.qpos0, np.float32)
        qpos[self.chain.qpos_adr] = HOME_Q
        qpos[self.finger_qpos_adr] = FINGER_MAX
        mocap_body = np.flatnonzero(m.body_mocapid >= 0)
        order = np.argsort(m.body_mocapid[mocap_body])
        return Scene(
            qpos=jnp.asarray(qpos),
            mocap_pos=jnp.asarray(m.body_pos[mocap_body[order]], jnp.float32).reshape(m.nmocap, 3),
            mocap_quat=jnp.asarray(m.body_quat[mocap_body[order]], jnp.float32).reshape(m.nmocap, 4),
            rgba=jnp.asarray(m.geom_rgba[self.recolour_ids], jnp.float32).reshape(-1, 4),
            params={},
        )

    def body_pos(self, data, body_id) -> jax.Array:
        return data.xpos[body_id]

    # ------------------------------------------------------------------ environment API
    def reset(self, key: jax.Array) -> EnvState:
        return self.reset_to(self.sample_scene(key))

    def reset_to(self, scene: Scene) -> EnvState:
        home_ctrl = jnp.concatenate([jnp.asarray(HOME_Q), jnp.full((2,), FINGER_MAX)])
        d = self._data0.replace(
            qpos=scene.qpos,
            mocap_pos=scene.mocap_pos,
            mocap_quat=scene.mocap_quat,
            ctrl=home_ctrl,
        )
        d = mjx.forward(self.mx, d)
        grasp = self.grasp_spec.init()
        progress = self.init_progress()
        state = EnvState(
            data=d,
            scene=scene,
            grasp=grasp,
            progress=progress,
            success=jnp.zeros((), bool),
            failure=jnp.zeros((), bool),
            finger_target=jnp.asarray(FINGER_MAX, jnp.float32),
            step=jnp.zeros((), jnp.int32),
        )
        return self._judge(state)

    def step(self, state: EnvState, q_target: jax.Array, grip: jax.Array) -> EnvState:
        """One control step: arm joint targets (7,) and gripper command (1 open, 0 closed)."""
        g = state.grasp
        close_cmd = grip < 0.5
        goal = jnp.where(close_cmd, 0.0, FINGER_MAX)
        goal = jnp.where(g.any & close_cmd, g.finger_hold, goal)
        max_move = GRIPPER_SPEED * self.control_dt
        finger = state.finger_target + jnp.clip(goal - state.finger_target, -max_move, max_move)
        ctrl = jnp.concatenate([q_target, jnp.stack([finger, finger])])
        d = state.data.replace(ctrl=ctrl)
        spec, chain, mx = self.grasp_spec, self.chain, self.mx

        pin_q, pin_v = self.pinned_qpos_adr, self.pinned_qvel_adr
        pinned = state.scene.qpos[pin_q]

        def substep(_, d):
            d = mjx.step(mx, d)
            qpos, qvel = spec.apply(g, chain, d.qpos, d.qvel)
            if len(pin_q):
                qpos, qvel = qpos.at[pin_q].set(pinned), qvel.at[pin_v].set(0.0)
            return d.replace(qpos=qpos, qvel=qvel)

        d = lax.fori_loop(0, self.substeps, substep, d)
        contact = d._impl.contact
        finger_open = jnp.mean(d.qpos[self.finger_qpos_adr])
        grasp = spec.update(g, chain, d.qpos, contact.geom, contact.dist, close_cmd, finger_open)
        state = state.replace(data=d, grasp=grasp, finger_target=finger, step=state.step + 1)
        return self._judge(state)

    def _judge(self, state: EnvState) -> EnvState:
        progress = self.update_progress(state.progress, state.data, state.grasp, state.scene)
        state = state.replace(progress=progress)
        failure = state.failure | self.is_failure(progress, state.data, state.grasp, state.scene)
        ok = self.is_success(progress, state.data, state.grasp, state.scene) & ~failure
        return state.replace(success=state.success | ok, failure=failure)
