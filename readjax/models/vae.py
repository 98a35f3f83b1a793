"""The paper's motion VAE (METHOD.md section 4) and the transformer blocks the models share.

The VAE maps a motion (B, 101, 10) to one latent vector; the posterior mean is the code that the
latent SDE (section 5) works on, and ``decode`` maps latents back to motions.

Architecture (as in the paper / released code):

* encoder: per-frame MLP 10 -> w -> 2w -> w (GELU), two learned query tokens (mu, logvar) put in
  front, sinusoidal positions on all 103 tokens, ``layers`` post-LN transformer encoder layers;
  the outputs at the two query tokens are mu and logvar;
* decoder: the latent plus a learned bias is the one-token memory; 101 queries are the sinusoidal
  positions; ``layers`` post-LN transformer decoder layers; per-key heads w -> w/2 -> dim.
* loss: MSE(rot6d) + 10 MSE(uv) + MSE(z) + MSE(grip) + w_KL KL (weights from the config).

Deviations, all small: the per-key heads use GELU (the released code's default there is PReLU);
initialisers are Flax's defaults; there is no dropout (the paper trains with 0).
"""

from __future__ import annotations

from typing import Mapping

import jax
import jax.numpy as jnp
import flax.linen as nn
import numpy as np

from readjax.config import VAEConfig
from readjax import motion as motion_lib
from readjax.motion import check_motion_shape

LN_EPS = 1e-5  # PyTorch's LayerNorm default, as in the original transformer layers


# ----------------------------------------------------------------------------- building blocks

def sinusoidal_positions(n: int, dim: int) -> np.ndarray:
    """Transformer positional encoding (n, dim): sin on even channels, cos on odd ones."""
    if dim % 2:
        raise ValueError(f"sinusoidal positions need an even dim, got {dim}")
    pos = np.arange(n, dtype=np.float64)[:, None]
    div = np.exp(np.arange(0, dim, 2, dtype=np.float64) * (-np.log(10000.0) / dim))
    pe = np.zeros((n, dim), np.float64)
    pe[:, 0::2] = np.sin(pos * div)
    pe[:, 1::2] = np.cos(pos * div)
    return pe.astype(np.float32)


class MLP(nn.Module):
    """Dense layers with GELU between them (none after the last): ``features`` = output sizes."""

    features: tuple[int, ...]

    @nn.compact
    def __call__(self, x):
        for i, f in enumerate(self.features):
            x = nn.Dense(f, name=f"dense_{i}")(x)
            if i < len(self.features) - 1:
                x = nn.gelu(x, approximate=False)
        return x


def embed_mlp(dim: int, name: str | None = None) -> MLP:
    """The paper's token embedding MLP: in -> dim -> 2 dim -> dim."""
    return MLP((dim, 2 * dim, dim), name=name)


class FeedForward(nn.Module):
    dim: int
    hidden: int

    @nn.compact
    def __call__(self, x):
        return nn.Dense(self.dim)(nn.gelu(nn.Dense(self.hidden)(x), approximate=False))


class Attention(nn.Module):
    """Multi-head dot-product attention: ``nn.MultiHeadDotProductAttention``'s function and
    parameters (``query``/``key``/``value``/``out`` with the same shapes and initialisers, so
    checkpoints load either way), computed head-major.

    Flax's module contracts (B, T, heads, d) layouts directly; on XLA-CPU that batched dot_general
    ran 6x slower forward at B = 32, T = 203 (40 ms against 6.5 ms per layer; 14 against 2 ms in
    the autoencoder at T = 101), and the forward pass alone is what refinement, evaluation and the
    frozen autoencoder in training run (BENCHMARKS.md 4d). ``mask`` (broadcastable to
    (B, heads, queries, keys), True = attend) as in Flax."""

    heads: int
    dim: int

    @nn.compact
    def __call__(self, inputs_q, inputs_kv, mask=None):
        if self.dim % self.heads:
            raise ValueError(f"dim {self.dim} must be a multiple of heads {self.heads}")
        per_head = (self.heads, self.dim // self.heads)

        def project(name, x):  # (B, T, dim) -> (B, heads, T, dim / heads)
            return jnp.swapaxes(nn.DenseGeneral(per_head, axis=-1, name=name)(x), -3, -2)

        q = project("query", inputs_q)
        k, v = project("key", inputs_kv), project("value", inputs_kv)
        logits = jnp.einsum("...hqd,...hkd->...hqk", q / jnp.sqrt(q.shape[-1]).astype(q.dtype), k)
        if mask is not None:
            logits = jnp.where(mask, logits, jnp.finfo(logits.dtype).min)
        out = jnp.einsum("...hqk,...hkd->...hqd", jax.nn.softmax(logits, axis=-1), v)
        return nn.DenseGeneral(self.dim, axis=(-2, -1), name="out")(jnp.swapaxes(out, -3, -2))


def _attention(heads: int, dim: int, name: str) -> Attention:
    return Attention(heads, dim, name=name)


class EncoderLayer(nn.Module):
    """Post-LN transformer encoder layer: x = LN(x + SA(x)); x = LN(x + FFN(x))."""

    dim: int
    heads: int
    hidden: int

    @nn.compact
    def __call__(self, x, mask=None):
        a = _attention(self.heads, self.dim, "self_attn")(x, x, mask=mask)
        x = nn.LayerNorm(epsilon=LN_EPS, name="norm1")(x + a)
        x = nn.LayerNorm(epsilon=LN_EPS, name="norm2")(x + FeedForward(self.dim, self.hidden, name="ffn")(x))
        return x


class DecoderLayer(nn.Module):
    """Post-LN transformer decoder layer (self-attention, cross-attention to memory, FFN)."""

    dim: int
    heads: int
    hidden: int

    @nn.compact
    def __call__(self, x, memory):
        a = _attention(self.heads, self.dim, "self_attn")(x, x)
        x = nn.LayerNorm(epsilon=LN_EPS, name="norm1")(x + a)
        c = _attention(self.heads, self.dim, "cross_attn")(x, memory)
        x = nn.LayerNorm(epsilon=LN_EPS, name="norm2")(x + c)
        x = nn.LayerNorm(epsilon=LN_EPS, name="norm3")(x + FeedForward(self.dim, self.hidden, name="ffn")(x))
        return x


KEY_DIMS = {k: s.stop - s.start for k, s in motion_lib.KEYS.items()}


def motion_mse(pred: jax.Array, target: jax.Array) -> dict[str, jax.Array]:
    """Per-key mean squared errors between two motions (keys of ``readjax.motion.KEYS``)."""
    return {k: jnp.mean((pred[..., s] - target[..., s]) ** 2) for k, s in motion_lib.KEYS.items()}


def weighted_motion_loss(pred: jax.Array, target: jax.Array,
                         weights: Mapping[str, float]) -> tuple[jax.Array, dict]:
    """sum_k w_k MSE_k and the unweighted per-key MSEs (the paper's motion loss with its weights)."""
    per_key = motion_mse(pred, target)
    return sum(weights[k] * v for k, v in per_key.items()), per_key


def kl_divergence(mu: jax.Array, logvar: jax.Array) -> jax.Array:
    """KL(N(mu, exp(logvar)) || N(0, I)) summed over latent dims, averaged over the batch."""
    return jnp.mean(-0.5 * jnp.sum(1 + logvar - mu**2 - jnp.exp(logvar), axis=-1))


def _batch_motion(batch, name="batch") -> jax.Array:
    if not isinstance(batch, Mapping) or "motion" not in batch:
        raise ValueError(f"{name} must be a mapping with a 'motion' array (B, 101, 10)")
    m = batch["motion"]
    check_motion_shape(m, f"{name}['motion']")
    return m


# ----------------------------------------------------------------------------- the model

class MotionEncoder(nn.Module):
    """Motion (B, 101, 10) -> (mu, logvar), each (B, latent_dim)."""

    cfg: VAEConfig

    @nn.compact
    def __call__(self, motion):
        check_motion_shape(motion)
        c = self.cfg
        b = motion.shape[0]
        tokens = embed_mlp(c.width, name="frame_embed")(motion)
        queries = jnp.stack([
            self.param("mu_query", nn.initializers.normal(1.0), (c.width,)),
            self.param("logvar_query", nn.initializers.normal(1.0), (c.width,)),
        ])
        x = jnp.concatenate([jnp.broadcast_to(queries, (b, 2, c.width)), tokens], axis=1)
        x = x + sinusoidal_positions(x.shape[1], c.width)
        for i in range(c.layers):
            x = EncoderLayer(c.width, c.heads, c.ffn, name=f"layer_{i}")(x)
        mu, logvar = x[:, 0], x[:, 1]
        if c.latent_dim != c.width:
            mu = nn.Dense(c.latent_dim, name="mu_proj")(mu)
            logvar = nn.Dense(c.latent_dim, name="logvar_proj")(logvar)
        return mu, logvar


class LatentDecoderBody(nn.Module):
    """Latent (B, latent_dim) -> per-frame features (B, 101, width) through transformer decoder layers."""

    cfg: VAEConfig

    @nn.compact
    def __call__(self, z):
        c = self.cfg
        if z.ndim != 2 or z.shape[1] != c.latent_dim:
            raise ValueError(f"latent must have shape (B, {c.latent_dim}), got {z.shape}")
        if c.latent_dim != c.width:
            z = nn.Dense(c.width, name="latent_proj")(z)
        memory = (z + self.param("latent_bias", nn.initializers.normal(1.0), (c.width,)))[:, None, :]
        x = jnp.broadcast_to(sinusoidal_positions(motion_lib.FRAMES, c.width),
                             (z.shape[0], motion_lib.FRAMES, c.width))
        for i in range(c.layers):
            x = DecoderLayer(c.width, c.heads, c.ffn, name=f"layer_{i}")(x, memory)
        return x


class MotionVAE(nn.Module):
    """The paper's task-space transformer VAE (METHOD.md section 4).

    Methods (call through ``apply(params, ..., method=...)``; ``__call__`` is used by ``init``):

    * ``encode(motion) -> (mu, logvar)``; the code is ``mu`` (see :meth:`code`);
    * ``decode(z) -> motion (B, 101, 10)``;
    * ``loss(batch, key=None) -> (scalar, metrics)``: with a key, z is the reparameterised sample
      (the VAE objective); without, z = mu (deterministic evaluation).
    """

    cfg: VAEConfig

    def setup(self):
        self.encoder = MotionEncoder(self.cfg)
        self.body = LatentDecoderBody(self.cfg)
        half = max(self.cfg.width // 2, 1)
        self.heads = {k: MLP((half, d)) for k, d in KEY_DIMS.items()}

    def __call__(self, motion):
        """Reconstruction through the posterior mean."""
        mu, _ = self.encode(motion)
        return self.decode(mu)

    def encode(self, motion):
        return self.encoder(motion)

    def code(self, motion):
        """The latent code used by the diffusion model: the posterior mean (B, latent_dim)."""
        return self.encoder(motion)[0]

    def decode(self, z):
        h = self.body(z)
        return motion_lib.join_keys({k: self.heads[k](h) for k in motion_lib.KEYS})

    def loss(self, batch, key=None):
        motion = _batch_motion(batch)
        mu, logvar = self.encode(motion)
        z = mu if key is None else mu + jnp.exp(0.5 * logvar) * jax.random.normal(key, mu.shape, mu.dtype)
        rec = self.decode(z)
        task, per_key = weighted_motion_loss(rec, motion, self.cfg.loss_weights)
        kl = kl_divergence(mu, logvar)
        total = task + self.cfg.kl_weight * kl
        return total, {"loss": total, "kl": kl, **per_key}
