"""The public planner: ``Planner.load(run_dir)`` then ``plan(rgbd, key, N=...)``.

Loading restores the trained models, loads the task's training set as the retrieval database and
precomputes its SPE features once. ``plan`` validates the input, encodes each image once,
retrieves a motion (SPE, or the oracle for experiments), refines it with N denoising steps (one
jitted ``lax.scan``, compiled once per batch shape and N; the run's ``sde.rounds`` times in a row,
each round from the previous plan), converts the result to world poses with
the dataset's camera, and solves a joint trajectory by IK.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from readjax import retrieval, tasks
from readjax.config import DEFAULT_N
from readjax import motion as motion_lib
from readjax.data import store
from readjax.methods import load_model
from readjax.methods.common import check_n_steps
from readjax.sim.execute import ExecConfig, solve_waypoints


@dataclass
class Plan:
    """A batch of plans (numpy). World poses are in the simulator's frame."""

    motion: np.ndarray  # (B, 101, 10) camera-frame motion (the model's output)
    retrieved: np.ndarray  # (B, 101, 10) the retrieved motion it was refined from
    retrieved_index: np.ndarray  # (B,) index into the training set
    positions: np.ndarray  # (B, 101, 3) end-effector positions, world
    rotations: np.ndarray  # (B, 101, 3, 3) end-effector rotations, world
    grip: np.ndarray  # (B, 101) gripper opening in [0, 1]
    joints: np.ndarray  # (B, 101, 7) IK solution (unreachable frames hold the previous one)
    reachable: np.ndarray  # (B, 101) whether IK reached each frame's pose


class Planner:
    """The planner of one trained run, whatever its method (see the module docstring).

    ``model`` offers ``encode``, ``generate`` and, for retrieval-based methods, ``database_tokens``
    and ``spe_distances`` (see :class:`readjax.methods.read.ReadModel`).
    """

    def __init__(self, model, database: store.Dataset, n_steps: int | None = None):
        self.model = model
        self.run_dir, self.spec, self.camera = model.run_dir, model.spec, model.camera
        self.task = self.spec["task"]
        self.image_size = model.image_size
        self.database = database
        self.n_steps = DEFAULT_N if n_steps is None else int(n_steps)
        self.env = tasks.make(self.task)
        # the retrieval database lives on the device: no copy per plan
        self.db_motion = jnp.asarray(database.motion)
        self.db_uv = motion_lib.uv(self.db_motion)
        self.db_tokens = (jnp.asarray(model.database_tokens(database.rgbd, database.motion))
                          if model.uses_retrieval else None)
        self._ik = jax.jit(jax.vmap(functools.partial(solve_waypoints, self.env, cfg=ExecConfig())))

    @property
    def default_rounds(self) -> int:
        """Refinement rounds when ``plan`` is given none: the run's ``sde.rounds`` (the cpu preset: 2),
        1 for a method that neither retrieves nor refines."""
        if not (self.model.uses_retrieval and self.model.iterative):
            return 1
        return int(getattr(self.model, "refine_rounds", 1))

    @classmethod
    def load(cls, run_dir: str | Path, data_root: str | Path | None = None, n_steps: int | None = None) -> "Planner":
        model = load_model(run_dir)
        spec = model.spec
        root = data_root or spec["data_root"]
        ds = store.load_dataset(store.split_dir(root, spec["task"], "train"),
                                limit=spec.get("episodes") or None)
        if not ds.fingerprint_matches(spec["dataset_fingerprint"], spec["image_size"]):
            raise store.DatasetError(f"the training set at {root} is not the one {run_dir} was trained on")
        return cls(model, ds.resized(spec["image_size"]), n_steps)

    # ---------------------------------------------------------------- input checks
    def check_rgbd(self, rgbd) -> np.ndarray:
        """Clear errors for a wrong shape, dtype, range or NaN (nothing reaches JAX unchecked)."""
        x = np.asarray(rgbd)
        s = self.image_size
        if x.ndim == 3:
            raise ValueError(f"rgbd must be batched: shape (B, {s}, {s}, 4), got {x.shape} (use rgbd[None])")
        if x.ndim != 4 or x.shape[1:] != (s, s, 4):
            raise ValueError(f"rgbd must have shape (B, {s}, {s}, 4) (RGB + normalised depth), got {x.shape}")
        if x.shape[0] == 0:
            raise ValueError(f"rgbd holds no images (shape {x.shape}): plan needs at least one first frame")
        if not np.issubdtype(x.dtype, np.floating):
            raise ValueError(f"rgbd must be float in [0, 1], got dtype {x.dtype} (divide uint8 RGB by 255)")
        if not np.all(np.isfinite(x)):
            raise ValueError("rgbd contains NaN or infinite values")
        if x.min() < -1e-3 or x.max() > 1 + 1e-3:
            raise ValueError(f"rgbd values must lie in [0, 1], got [{x.min():.3g}, {x.max():.3g}]")
        return x.astype(np.float32)

    # ---------------------------------------------------------------- planning
    def encode(self, rgbd) -> jax.Array:
        return self.model.encode(jnp.asarray(self.check_rgbd(rgbd)))

    def retrieve(self, features, method: str = "spe", gt_motion=None, rank: int = 1) -> np.ndarray:
        """Database indices: SPE (section 7) or the oracle's ``rank``-th neighbour of ``gt_motion``."""
        if method == "spe":
            if not self.model.uses_retrieval:
                raise ValueError(f"{self.spec['method']} has no retrieval features; use retrieval 'cheat' or none")
            return np.asarray(jnp.argmin(self.model.spe_distances(features, self.db_uv, self.db_tokens), axis=1))
        if method == "cheat":
            if gt_motion is None:
                raise ValueError("oracle ('cheat') retrieval needs the ground-truth motions (gt_motion=)")
            motion_lib.check_motion(gt_motion, "gt_motion")
            return retrieval.oracle_retrieve(self.camera, gt_motion, self.database.motion, rank)
        raise ValueError(f"unknown retrieval {method!r}; use 'spe' or 'cheat'")

    def plan(self, rgbd, key: jax.Array, N: int | None = None, retrieval_method: str = "spe",
             gt_motion=None, rank: int = 1, candidates: int = 1, rounds: int | None = None) -> Plan:
        """Plans for a batch of first frames (B, S, S, 4). N = 0 executes the retrieved motion.

        ``candidates`` > 1 (SPE retrieval, N > 0; beyond the paper, see README): refine each of
        SPE's top-``candidates`` retrievals and keep, per image, the refined plan that one more
        refinement step started from it moves least at its end point (:func:`fixed_point_residual`).
        1 is the paper's top-1.

        ``rounds`` > 1 (a retrieval-based iterative method, N > 0; beyond the paper, see README):
        refine, then refine again with the refined plan as the retrieved motion, ``rounds`` times in
        all (:meth:`refine`). 1 is the paper's single refinement; None the run's default
        (:attr:`default_rounds`)."""
        n = check_n_steps(self.n_steps if N is None else N, name="N")
        check_key(key)
        if rounds is None:
            rounds = self.default_rounds if n > 0 else 1
        for name, v in (("candidates", candidates), ("rounds", rounds)):
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if rounds > 1 and (not self.model.uses_retrieval or not self.model.iterative or n == 0):
            raise ValueError("rounds > 1 needs a retrieval-based iterative method and N > 0 (got method "
                             f"{self.spec.get('method')!r}, N = {n})")
        feats = self.encode(rgbd)
        if candidates > 1:
            if retrieval_method != "spe" or not self.model.uses_retrieval or not self.model.iterative or n == 0:
                raise ValueError("candidates > 1 needs SPE retrieval, a retrieval-based iterative method "
                                 f"and N > 0 (got retrieval {retrieval_method!r}, method "
                                 f"{self.spec.get('method')!r}, N = {n})")
            return self._plan_candidates(feats, key, n, candidates, rounds)
        if self.model.uses_retrieval or retrieval_method == "cheat":
            idx = self.retrieve(feats, retrieval_method, gt_motion, rank)
        else:  # methods without retrieval start from noise; report the first database entry
            idx = np.zeros(feats.shape[0], np.int64)
        m_r = self.db_motion[jnp.asarray(idx)]
        m = self.refine(feats, m_r, key, n, rounds)
        return self._finish(np.asarray(m), np.asarray(m_r), idx)

    def refine(self, features, m_r, key: jax.Array, n: int, rounds: int = 1) -> jax.Array:
        """``rounds`` refinements of N steps, each started from the previous one's plan as its
        retrieved motion (round r draws its noise from ``fold_in(key, r)``; round 0 from ``key``, so
        one round is exactly ``model.generate``). Why more than one: a refinement is anchored at its
        start (the SDE's mean reverts to M_R), and the denoiser corrects a near start better than a
        far one; the second round starts where the first ended (RT: BENCHMARKS.md 8l)."""
        m = self.model.generate(features, m_r, key, n)
        for r in range(1, rounds):
            m = self.model.generate(features, m, jax.random.fold_in(key, r), n)
        return m

    def _plan_candidates(self, feats, key, n: int, candidates: int, rounds: int = 1) -> Plan:
        dist = self.model.spe_distances(feats, self.db_uv, self.db_tokens)
        if candidates > dist.shape[1]:
            raise ValueError(f"candidates = {candidates} exceeds the retrieval database ({dist.shape[1]} demos)")
        order = np.asarray(jnp.argsort(dist, axis=1)[:, :candidates])  # (B, C), nearest first
        plans, residuals = [], []
        for c in range(candidates):
            m = self.refine(feats, self.db_motion[jnp.asarray(order[:, c])], key, n, rounds)
            plans.append(np.asarray(m))
            residuals.append(np.asarray(fixed_point_residual(self.model, self.camera, feats, m, key)))
        pick = select_candidates(np.stack(residuals, axis=1))
        rows = np.arange(len(pick))
        idx = order[rows, pick]
        return self._finish(np.stack(plans, axis=1)[rows, pick], np.asarray(self.db_motion[jnp.asarray(idx)]), idx)

    def _finish(self, m, m_r, idx) -> Plan:
        pos, rot, grip = (np.asarray(x) for x in motion_lib.decode(self.camera, jnp.asarray(m)))
        q, skipped = self._ik(jnp.asarray(pos), jnp.asarray(rot))
        return Plan(motion=m, retrieved=m_r, retrieved_index=np.asarray(idx), positions=pos, rotations=rot,
                    grip=grip, joints=np.asarray(q), reachable=~np.asarray(skipped))


def check_key(key) -> None:
    """A clear error for anything but one JAX PRNG key (a typed ``jax.random.key(seed)`` or a legacy
    ``jax.random.PRNGKey(seed)``): the refinement draws its noise from it."""
    typed = hasattr(key, "dtype") and jnp.issubdtype(key.dtype, jax.dtypes.prng_key)
    legacy = (isinstance(key, (jax.Array, np.ndarray)) and not typed and key.dtype == np.uint32
              and key.shape in ((2,), (4,)))  # threefry or rbg key data
    if typed and key.shape != ():
        raise ValueError(f"key must be one PRNG key for the whole batch, got a batch of keys of shape {key.shape}")
    if not (typed or legacy):
        raise ValueError(f"key must be a JAX PRNG key, e.g. key=jax.random.key(0) (the refinement draws its "
                         f"noise from it), got {type(key).__name__}"
                         + (f" with dtype {key.dtype}" if hasattr(key, "dtype") else ""))


def fixed_point_residual(model, camera, features, motion, key) -> jax.Array:
    """How far one more refinement step, started from ``motion`` (B, 101, 10) as if it were the
    retrieved motion, moves its end point (B,), in metres. A refined plan the denoiser would keep
    has a small residual; one refined from a wrong start (a distractor, a far demo) a large one:
    on RT, 0.5 against 2.4 cm median for plans within / beyond 3 cm of the target (BENCHMARKS 8k)."""
    again = model.generate(features, motion, key, 1)
    end = lambda m: motion_lib.decode(camera, jnp.asarray(m))[0][:, -1]
    return jnp.linalg.norm(end(again) - end(motion), axis=-1)


def select_candidates(residuals: np.ndarray) -> np.ndarray:
    """Per row of (B, C) residuals, the candidate kept: the smallest residual, ties to the nearer
    retrieval (lower column)."""
    return np.argmin(np.asarray(residuals), axis=1)
