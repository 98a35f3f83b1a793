"""How precise must a plan be on a task? The ground truth replayed with a known error.

A planner's failures on a task mean little without the task's own tolerance: pouring from a
watering can onto a pot may fail at a 2 cm error where picking up a cup succeeds at 4 cm. Here each
test episode's recorded expert motion is moved by a known amount and executed through exactly the
evaluation path (``sim.execute.execute_motions`` in the episode's stored scene, the task's
predicate):

- a **shift**: every waypoint moved by ``d`` metres in one direction (uniform on the sphere), as a
  plan that is right in shape but off in place;
- a **turn**: every waypoint's orientation turned by ``a`` degrees about one axis through the tool
  (uniform on the sphere, the rotation applied in the world frame), as a plan off in orientation.

Direction and axis are a function of the episode's seed alone (NumPy generators seeded by it), so an
episode's perturbation does not depend on its batch or on which other episodes are replayed. The
success rate against ``d`` and against ``a`` is the task's tolerance curve; set beside a planner's
key-frame errors (``failure_modes``) it says whether the planner's precision or something else
limits the task.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from readjax import geometry as geo
from readjax.camera import CameraParams
from readjax import motion as motion_lib

_SHIFT, _TURN = 0, 1  # the episode generator's stream for each kind of error


def unit_vector(seed: int, stream: int) -> np.ndarray:
    """A direction uniform on the unit sphere, a function of (episode seed, stream) alone."""
    v = np.random.default_rng([int(seed), stream]).normal(size=3)
    return v / np.linalg.norm(v)


def perturb(cam: CameraParams, motions: np.ndarray, seeds: np.ndarray, shift_m: float = 0.0,
            turn_deg: float = 0.0) -> np.ndarray:
    """The motions (B, T, 10) with every waypoint shifted by ``shift_m`` along the episode's shift
    direction and turned by ``turn_deg`` about its turn axis (world frame, about the tool point)."""
    pos, rot, grip = motion_lib.decode(cam, jnp.asarray(motions, jnp.float32))
    shift = np.stack([unit_vector(s, _SHIFT) for s in seeds]) * shift_m  # (B, 3)
    axes = np.stack([unit_vector(s, _TURN) for s in seeds])
    turn = geo.quat_to_mat(geo.axis_angle_to_quat(jnp.asarray(axes), jnp.full(len(seeds), np.deg2rad(turn_deg))))
    pos = pos + jnp.asarray(shift, jnp.float32)[:, None, :]
    rot = turn[:, None] @ rot
    return np.asarray(motion_lib.encode(cam, pos, rot, grip), np.float32)


def replay(env, ds, shift_m: float = 0.0, turn_deg: float = 0.0, batch_size: int = 32) -> np.ndarray:
    """Per-episode success (bool array) of the split's ground truth replayed with that error, in each
    episode's stored scene (the caller runs the scene guard once)."""
    from readjax.sim.execute import execute_motions

    motions = perturb(ds.camera, ds.motion, ds.seeds, shift_m, turn_deg)
    return execute_motions(env, ds.camera, ds.scenes, motions, batch_size=batch_size)["success"].astype(bool)


def curve_lines(result: dict) -> list[str]:
    """The tolerance result as a small markdown table: success % at each shift and each turn."""
    out = [f"{result['task']} ({result['code']}), {result['episodes']} {result['split']} episodes: success % of the "
           "ground truth replayed with a known error", "", "| shift (cm) | " +
           " | ".join(result["shift_cm"]) + " |",
           "|---" * (len(result["shift_cm"]) + 1) + "|",
           "| success | " + " | ".join(f"{100 * v['success_rate']:.0f}" for v in result["shift_cm"].values()) + " |",
           "", "| turn (deg) | " + " | ".join(result["turn_deg"]) + " |",
           "|---" * (len(result["turn_deg"]) + 1) + "|",
           "| success | " + " | ".join(f"{100 * v['success_rate']:.0f}" for v in result["turn_deg"].values()) + " |"]
    return out


def plot(result: dict, path) -> None:
    """Success against shift and against turn, side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2), sharey=True)
    for ax, key, label in ((axes[0], "shift_cm", "shift of every waypoint (cm)"),
                           (axes[1], "turn_deg", "turn of every waypoint (deg)")):
        xs = [float(k) for k in result[key]]
        ys = [100 * v["success_rate"] for v in result[key].values()]
        ax.plot(xs, ys, "o-")
        ax.set_xlabel(label)
        ax.set_ylim(-5, 105)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success %")
    fig.suptitle(f"{result['task']}: the ground truth replayed with a known error ({result['episodes']} episodes)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
