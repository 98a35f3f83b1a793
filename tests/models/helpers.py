"""Tiny configs and a synthetic, FK-consistent batch for the model and diffusion tests."""

from __future__ import annotations

import dataclasses
import functools

import jax.numpy as jnp
import numpy as np

from readjax.config import DenoiserConfig, VAEConfig
from readjax import motion as mo
from readjax.sim import kinematics as kin

TINY_VAE = VAEConfig(width=16, layers=1, heads=2, ffn=32, latent_dim=16)  # latent = width, as in the paper
# two ConvNeXt blocks (one encoder, one decoder) exercise every UNet path at little compile cost
TINY_UNET = DenoiserConfig(image_size=32, conv_dims=(8, 8, 8, 8), enc_depths=(1, 0, 0, 0),
                           dec_depths=(1, 0, 0), drop_path=0.1, feature_channels=12, d_model=16, layers=1, heads=2, ffn=32)
# the denoiser tests use a block-free UNet (the UNet has its own tests)
TINY_DENOISER = dataclasses.replace(TINY_UNET, enc_depths=(0, 0, 0, 0), dec_depths=(0, 0, 0))


@functools.lru_cache(maxsize=None)
def chain_and_camera(size: int = 32):
    """The reach_target arm chain and its front camera at ``size`` x ``size``."""
    from readjax import tasks
    from readjax.sim.camera import camera_from_model

    env = tasks.make("reach_target")
    return env.chain, camera_from_model(env.mj_model, "front", size, size)


def synthetic_batch(n: int, seed: int = 0, size: int = 32) -> dict[str, jnp.ndarray]:
    """Smooth joint trajectories near the home posture, their FK motions and a grip that closes.

    Motion and joints agree exactly through FK (like the generated datasets), so both the
    task-space and the joint-space losses have a consistent target.
    """
    chain, cam = chain_and_camera(size)
    rng = np.random.default_rng(seed)
    home = np.asarray(kin.HOME_Q, np.float64)
    q0 = home + rng.normal(0, 0.15, (n, 7))
    q1 = home + rng.normal(0, 0.3, (n, 7))
    s = np.linspace(0.0, 1.0, mo.FRAMES)
    s = (3 * s**2 - 2 * s**3)[None, :, None]
    q = np.clip(q0[:, None] + (q1 - q0)[:, None] * s, chain.lower + 0.05, chain.upper - 0.05)
    q = q.astype(np.float32)
    t_close = rng.uniform(0.3, 0.8, (n, 1))
    grip = (np.linspace(0, 1, mo.FRAMES)[None] < t_close).astype(np.float32)
    motion = _fk_encode(size)(jnp.asarray(q), jnp.asarray(grip))
    return {"motion": jnp.asarray(motion, jnp.float32), "joints": jnp.asarray(q)}


@functools.lru_cache(maxsize=None)
def _fk_encode(size):
    import jax

    chain, cam = chain_and_camera(size)
    return jax.jit(lambda q, g: mo.encode(cam, *kin.fk(chain, q), g))


def jitted(model, method=None, **kw):
    """``jax.jit`` of ``model.apply`` with a fixed method (one compile, no op-by-op dispatch)."""
    import jax

    return jax.jit(functools.partial(model.apply, method=method, **kw))


def jit_init(model, *args, **kw):
    import jax

    return jax.jit(functools.partial(model.init, **kw))(*args)


def key(seed: int):
    """A typed PRNG key of the "rbg" implementation.

    Under the project's XLA flag (--xla_cpu_use_fusion_emitters=false) every threefry random op
    takes ~2 s to compile on this CPU, so a model init (one draw per parameter tensor) compiled
    for 50 s; with rbg keys it compiles in a few seconds. The modules accept either kind.
    """
    import jax

    return jax.random.key(seed, impl="rbg")


def tree_finite(tree) -> bool:
    import jax

    return all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(tree))


def tree_norm(tree) -> float:
    import jax

    return float(jnp.sqrt(sum(jnp.sum(x**2) for x in jax.tree.leaves(tree))))
