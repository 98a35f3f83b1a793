"""[beyond] The kinematics-aware motion autoencoder (METHOD.md section 4) and the shared factory.

Same encoder as the paper's VAE (:class:`readjax.models.vae.MotionEncoder`). The decoder's
transformer body is the paper's too, but its heads emit a joint trajectory q(t) (101 x 7) and the
gripper channel instead of task-space keys:

    q = lower + m + (upper - lower - 2 m) * sigmoid(raw + offset)

so every decoded angle lies strictly inside the Panda joint limits (margin m = ``joint_margin``;
``offset`` starts the decoder near the home posture). End-effector poses come from differentiable
forward kinematics (:func:`readjax.arm.fk`, the chain of the simulator's MJCF) and are
converted to the front-camera motion format (uv, z, rot6d) — decoded motions are reachable by
construction. Loss: the paper's task-space losses on the FK motion + ``w_joint`` x joint-space MSE
against the recorded joints + ``kl_weight`` x KL.

The chain and camera are constructor data (static numpy constants wrapped in the hashable
:class:`KinematicConstants`), never learned. :func:`make_autoencoder` builds either model from a
:class:`readjax.config.VAEConfig`; both share ``encode`` / ``code`` / ``decode`` / ``loss``.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import flax.linen as nn
import numpy as np

from readjax import arm as kin
from readjax import camera as cam_lib
from readjax import geometry as geo
from readjax.arm import ArmChain
from readjax.camera import CameraParams
from readjax.config import VAEConfig
from readjax import motion as motion_lib
from readjax.models.vae import (MLP, LatentDecoderBody, MotionEncoder, MotionVAE, _batch_motion,
                                kl_divergence, weighted_motion_loss)

MIN_DEPTH = 0.02  # metres; FK points closer to (or behind) the camera are projected at this depth


def _fingerprint(chain: ArmChain, camera: CameraParams) -> str:
    h = hashlib.sha256()
    for name, v in chain._asdict().items():
        h.update(name.encode())
        h.update(np.ascontiguousarray(np.asarray(v, np.float64)).tobytes())
    for v in (camera.intrinsics, camera.cam_to_world, camera.width, camera.height):
        h.update(np.ascontiguousarray(np.asarray(v, np.float64)).tobytes())
    return h.hexdigest()


@dataclass(frozen=True, eq=False)
class KinematicConstants:
    """The arm chain and the camera of a kinematic decoder, hashable by content.

    Hashability lets a module that holds them be a static argument of ``jax.jit``.
    """

    chain: ArmChain
    camera: CameraParams
    fingerprint: str = field(init=False)

    def __post_init__(self):
        if not isinstance(self.chain, ArmChain):
            raise ValueError(f"chain must be an ArmChain, got {type(self.chain).__name__}")
        if not isinstance(self.camera, CameraParams):
            raise ValueError(f"camera must be a CameraParams, got {type(self.camera).__name__}")
        if np.shape(self.chain.lower) != (motion_lib.JOINTS,):
            raise ValueError(f"chain must have {motion_lib.JOINTS} joints, got limits "
                             f"{np.shape(self.chain.lower)}")
        object.__setattr__(self, "fingerprint", _fingerprint(self.chain, self.camera))

    def __hash__(self):
        return hash(self.fingerprint)

    def __eq__(self, other):
        return isinstance(other, KinematicConstants) and other.fingerprint == self.fingerprint


def fk_motion(chain: ArmChain, camera: CameraParams, q: jax.Array, grip: jax.Array) -> jax.Array:
    """Joint trajectory (..., 7) and grip (..., 1) -> camera-frame motion (..., 10) via FK.

    Equal to ``readjax.motion.encode(camera, *fk(chain, q), grip)`` wherever the end effector
    is at least ``MIN_DEPTH`` in front of the camera; closer points are projected at that depth so
    that gradients stay finite for any q.
    """
    pos, rot = kin.fk(chain, q)
    pc = cam_lib.world_to_camera(camera, pos)
    depth = pc[..., 2]
    safe = jnp.maximum(depth, MIN_DEPTH)
    k = camera.intrinsics
    u = 2 * (k[0, 0] * pc[..., 0] / safe + k[0, 2]) / camera.width - 1
    v = 2 * (k[1, 1] * pc[..., 1] / safe + k[1, 2]) / camera.height - 1
    r_cam = cam_lib.rotation_to_camera(camera, rot)
    uvz = jnp.stack([u, v, depth], axis=-1)
    return jnp.concatenate([uvz, geo.rot6d_from_mat(r_cam), grip], axis=-1)


def _home_logit(chain: ArmChain, margin: float) -> np.ndarray:
    """Pre-sigmoid offset that puts a zero head output at the Panda home posture (clipped inside)."""
    lo, hi = np.asarray(chain.lower, np.float64), np.asarray(chain.upper, np.float64)
    frac = (np.asarray(kin.HOME_Q, np.float64) - lo - margin) / np.maximum(hi - lo - 2 * margin, 1e-6)
    frac = np.clip(frac, 0.05, 0.95)
    return np.log(frac / (1 - frac)).astype(np.float32)


def _batch_joints(batch) -> jax.Array:
    if "joints" not in batch:
        raise ValueError("the kinematic autoencoder's loss needs batch['joints'] (B, 101, 7)")
    q = batch["joints"]
    shape = getattr(q, "shape", None)
    if shape is None or len(shape) != 3 or tuple(shape[1:]) != (motion_lib.FRAMES, motion_lib.JOINTS):
        raise ValueError(f"batch['joints'] must have shape (B, {motion_lib.FRAMES}, {motion_lib.JOINTS}), "
                         f"got {shape}")
    return q


class KinematicAE(nn.Module):
    """[beyond] Kinematics-aware autoencoder: latent -> joint trajectory -> FK -> motion.

    Methods: ``encode(motion) -> (mu, logvar)``, ``code(motion) -> mu``, ``decode(z) -> motion``,
    ``decode_with_joints(z) -> (motion, joints)``, ``loss(batch, key=None) -> (scalar, metrics)``
    with ``batch = {"motion": (B,101,10), "joints": (B,101,7)}``.
    """

    cfg: VAEConfig
    consts: KinematicConstants

    def setup(self):
        half = max(self.cfg.width // 2, 1)
        self.encoder = MotionEncoder(self.cfg)
        self.body = LatentDecoderBody(self.cfg)
        self.joint_head = MLP((half, motion_lib.JOINTS))
        self.grip_head = MLP((half, 1))

    def __call__(self, motion):
        mu, _ = self.encode(motion)
        return self.decode(mu)

    def encode(self, motion):
        return self.encoder(motion)

    def code(self, motion):
        return self.encoder(motion)[0]

    def joints(self, h):
        """Per-frame features (B, 101, width) -> joint angles strictly inside the limits."""
        chain, m = self.consts.chain, self.cfg.joint_margin
        lo = jnp.asarray(chain.lower, jnp.float32) + m
        span = jnp.asarray(chain.upper - chain.lower, jnp.float32) - 2 * m
        return lo + span * jax.nn.sigmoid(self.joint_head(h) + _home_logit(chain, m))

    def decode_with_joints(self, z):
        h = self.body(z)
        q = self.joints(h)
        motion = fk_motion(self.consts.chain, self.consts.camera, q, self.grip_head(h))
        return motion, q

    def decode(self, z):
        return self.decode_with_joints(z)[0]

    def loss(self, batch, key=None):
        motion = _batch_motion(batch)
        joints = _batch_joints(batch)
        mu, logvar = self.encode(motion)
        z = mu if key is None else mu + jnp.exp(0.5 * logvar) * jax.random.normal(key, mu.shape, mu.dtype)
        rec, q = self.decode_with_joints(z)
        task, per_key = weighted_motion_loss(rec, motion, self.cfg.loss_weights)
        joint_mse = jnp.mean((q - joints) ** 2)
        kl = kl_divergence(mu, logvar)
        total = task + self.cfg.w_joint * joint_mse + self.cfg.kl_weight * kl
        return total, {"loss": total, "kl": kl, "joints": joint_mse, **per_key}


def make_autoencoder(cfg: VAEConfig, chain: ArmChain | None = None, camera: CameraParams | None = None):
    """The paper's :class:`MotionVAE`, or :class:`KinematicAE` when ``cfg.kinematic``.

    The kinematic one needs the task's arm chain (``env.chain``) and the dataset's front camera.
    """
    if not isinstance(cfg, VAEConfig):
        raise ValueError(f"cfg must be a VAEConfig, got {type(cfg).__name__}")
    if not cfg.kinematic:
        return MotionVAE(cfg)
    if chain is None or camera is None:
        raise ValueError("a kinematic autoencoder needs chain= (ArmChain) and camera= (CameraParams)")
    return KinematicAE(cfg, KinematicConstants(chain, camera))
