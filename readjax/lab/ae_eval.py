"""How good is a trained motion autoencoder as READ's motion space?

Two questions, for the plain task-space VAE (METHOD.md section 4) and the kinematics-aware one:

* **reconstruction** — encode (z = mu) and decode held-out demos; errors per key in the world
  frame: end-effector position (mm), orientation (rad), image-plane uv (pixels at the run's image
  size), gripper;
* **reachability** — can the arm actually execute the decoded motion? Every decoded pose goes
  through damped-least-squares IK (:mod:`readjax.sim.ik`, joint limits enforced), warm-started
  along the motion as the controller does; a pose is reachable when the residual is within
  ``pos_tol`` (5 mm) and ``rot_tol`` (0.05 rad), a motion when all its 101 poses are.

The recorded demos themselves go through the same check (``data`` row): the expert executed
them, so any shortfall there is the IK's, not the autoencoder's.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from readjax import config, tasks
from readjax import geometry as geo
from readjax import motion as motion_lib
from readjax.methods import base
from readjax.methods import read as read_lib
from readjax.models.kinematic_vae import make_autoencoder
from readjax.sim.camera import CameraParams
from readjax.sim.ik import IKParams, pose_error, solve_ik
from readjax.sim.kinematics import HOME_Q, ArmChain

POS_TOL = 0.005
ROT_TOL = 0.05


def track_ik(chain: ArmChain, pos: jax.Array, rot: jax.Array, first_iters: int = 200, iters: int = 50):
    """IK along one motion (T poses), each frame warm-started from the previous solution (jit it
    with the chain closed over: its parent indices must stay static).

    Returns (q (T, 7), position error (T,) m, orientation error (T,) rad)."""
    params = IKParams()
    q0 = solve_ik(chain, jnp.asarray(HOME_Q), pos[0], rot[0], first_iters, params)

    def step(q, target):
        p, r = target
        q = solve_ik(chain, q, p, r, iters, params)
        return q, q

    _, qs = jax.lax.scan(step, q0, (pos, rot))
    pe, re = jax.vmap(lambda q, p, r: pose_error(chain, q, p, r))(qs, pos, rot)
    return qs, pe, re


def reachability(chain: ArmChain, camera, motions: np.ndarray, pos_tol: float = POS_TOL,
                 rot_tol: float = ROT_TOL) -> dict:
    """Fraction of poses and of whole motions (B, 101, 10) that IK reaches within tolerance."""
    pos, rot, _ = jax.jit(jax.vmap(lambda m: motion_lib.decode(camera, m)))(jnp.asarray(motions))
    _, pe, re = jax.jit(jax.vmap(lambda p, r: track_ik(chain, p, r)))(pos, rot)
    pe, re = np.asarray(pe), np.asarray(re)
    ok = (pe <= pos_tol) & (re <= rot_tol)
    return {"poses_reachable": float(ok.mean()), "motions_reachable": float(ok.all(axis=1).mean()),
            "ik_pos_err_mm_median": float(np.median(pe) * 1e3), "ik_pos_err_mm_max": float(pe.max() * 1e3),
            "ik_rot_err_rad_median": float(np.median(re)), "ik_rot_err_rad_max": float(re.max()),
            "pos_tol_m": pos_tol, "rot_tol_rad": rot_tol}


def reconstruction_errors(camera, recon: np.ndarray, target: np.ndarray, image_size: int) -> dict:
    """World-frame errors of reconstructed motions against the originals (both (B, 101, 10))."""
    dec = jax.jit(jax.vmap(lambda m: motion_lib.decode(camera, m)))
    p1, r1, g1 = dec(jnp.asarray(recon))
    p0, r0, g0 = dec(jnp.asarray(target))
    pos_err = np.linalg.norm(np.asarray(p1 - p0), axis=-1)
    rot_err = np.asarray(geo.rotation_angle(r1, r0))
    uv_px = np.linalg.norm(np.asarray(motion_lib.uv(recon) - motion_lib.uv(target)), axis=-1) * image_size / 2
    end = pos_err[:, -1]  # where the motion ends is what most success predicates test
    return {"pos_err_mm_mean": float(pos_err.mean() * 1e3), "pos_err_mm_p95": float(np.percentile(pos_err, 95) * 1e3),
            "end_pos_err_mm_median": float(np.median(end) * 1e3), "end_pos_err_mm_p95": float(np.percentile(end, 95) * 1e3),
            "rot_err_rad_mean": float(rot_err.mean()), "rot_err_rad_p95": float(np.percentile(rot_err, 95)),
            "uv_err_px_mean": float(uv_px.mean()), "grip_abs_err_mean": float(np.abs(np.asarray(g1 - g0)).mean()),
            "motion_mse": float(np.mean((recon - target) ** 2))}


def load_autoencoder(run_dir: str | Path):
    """(autoencoder module, its trained params, run spec) of a run's ``vae/`` stage."""
    run_dir = Path(run_dir)
    spec = base.read_run(run_dir)
    if "vae" not in spec["configs"]:
        raise ValueError(f"run {run_dir} (method {spec['method']!r}) has no autoencoder")
    configs = config.configs_from_dict(spec["configs"])
    camera = CameraParams.from_dict(spec["camera"])
    ae = make_autoencoder(configs["vae"], chain=tasks.make(spec["task"]).chain, camera=camera)
    k_ae, _ = jax.random.split(jax.random.key(configs["train"].seed))
    params = read_lib.autoencoder_params(run_dir, ae, k_ae, configs["train"], spec["configs"],
                                         spec["dataset_fingerprint"])
    return ae, params, spec


def round_trip(run_dir: str | Path, motions: np.ndarray, chunk: int = 64) -> tuple[np.ndarray, dict]:
    """(Dec(Enc(M)) of every motion (B, 101, 10), with the code's mean (deterministic), run spec): a
    motion as the run's motion space keeps it. A latent normalisation (``sde.latent_norm``) cancels in
    the round trip, so the raw code gives the same motion."""
    ae, params, spec = load_autoencoder(run_dir)
    recon_fn = jax.jit(lambda p, m: ae.apply(p, ae.apply(p, m, method="code"), method="decode"))
    recon = np.concatenate([np.asarray(recon_fn(params, jnp.asarray(motions[s:s + chunk])))
                            for s in range(0, len(motions), chunk)])
    return recon, spec


def evaluate_autoencoder(run_dir: str | Path, motions: np.ndarray, chunk: int = 64, execute=None) -> dict:
    """Reconstruction errors and reachability of a run's autoencoder on ``motions`` (B, 101, 10).

    ``execute``: a function of motions (B, 101, 10) returning each one's task success (0 / 1), e.g. the
    evaluation path on the motions' own scenes. With it, the round trip is also executed: how much of
    the task the motion space keeps, which bounds any plan that is the decoder's output (READ-L's)."""
    recon, spec = round_trip(run_dir, motions, chunk)
    camera = CameraParams.from_dict(spec["camera"])
    chain = tasks.make(spec["task"]).chain
    out = {"run": str(run_dir), "kinematic": bool(spec["configs"]["vae"].get("kinematic", False)),
           "episodes": len(motions),
           "reconstruction": reconstruction_errors(camera, recon, motions, int(spec["image_size"])),
           "reachability": reachability(chain, camera, recon)}
    if execute is not None:
        out["task_success"] = task_success(execute(recon))
    return out


def task_success(success) -> dict:
    """A per-motion success vector as a record: rate, count and the vector (for pairing by episode)."""
    s = np.asarray(success).astype(int)
    return {"rate": float(s.mean()), "successes": int(s.sum()), "success": s.tolist()}
