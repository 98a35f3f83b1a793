"""READ-L's denoiser (METHOD.md section 10): the reverse process in the autoencoder's latent space.

Inputs: the image, the noisy latent z_t (B, D), the diffusion time t and the uv track (B, 101, 2)
of the decoded motion Dec(z_t) (computed by the caller with the frozen autoencoder). Output: the
clean-latent estimate ẑ0 (B, D).

* image features: READ's ConvNeXt UNet (:class:`readjax.models.convnext_unet.ConvNeXtUNet`, the
  ``denoiser`` config section), bilinearly sampled along Dec(z_t)'s uv -> 101 image tokens
  (projected to d when C != d) + sinusoidal positions 0..100;
* one latent token (MLP D -> d -> 2d -> d of z_t) and one time token (READ's sinusoidal time
  features of raw t, then MLP), with positions 0, 1;
* ``layers`` post-LN transformer encoder layers (d_model, heads, ffn of the ``denoiser`` section)
  over the 103 tokens;
* head: MLP d -> d -> D on the latent token's output; ẑ0 = z_t + head (a delta, like READ's).

So the image is still "read" along the motion the current latent decodes to (READ's
feature-sampling idea), but the state, the prediction and the loss live in latent space. The
per-image cache is the UNet trunk (``encode_image``) and ``image_tokens`` has READ's signature, so
SPE retrieval (METHOD.md section 7) works with this module unchanged.
"""

from __future__ import annotations

import flax.linen as nn
import jax.numpy as jnp

from readjax.config import DenoiserConfig
from readjax import motion as motion_lib
from readjax.models.convnext_unet import ConvNeXtUNet
from readjax.models.denoiser import time_features
from readjax.models.vae import MLP, EncoderLayer, embed_mlp, sinusoidal_positions


class LatentDenoiser(nn.Module):
    """ẑ0 = z_t + f(image features along Dec(z_t), z_t, t) (see the module docstring).

    Methods: ``encode_image(image, train=False)``, ``image_tokens(features, uv)``,
    ``denoise(features, z_t, uv, t) -> (B, D)``, ``__call__(image, z_t, uv, t, train=False)``.
    """

    cfg: DenoiserConfig
    latent_dim: int

    def setup(self):
        c = self.cfg
        d = c.d_model
        self.unet = ConvNeXtUNet(c)
        self.latent_embed = embed_mlp(d)
        self.time_embed = embed_mlp(d)
        self.image_proj = nn.Dense(d) if c.feature_channels != d else None
        self.layers = [EncoderLayer(d, c.heads, c.ffn) for _ in range(c.layers)]
        self.head = MLP((d, d, self.latent_dim))

    def __call__(self, image, z_t, uv, t, train: bool = False):
        return self.denoise(self.encode_image(image, train), z_t, uv, t)

    def encode_image(self, image, train: bool = False):
        return self.unet.trunk(image, train)

    def image_tokens(self, features, uv):
        return self.unet.head_at(features, uv)

    def full_features(self, features):
        """The full-resolution feature map that ``image_tokens`` samples."""
        return self.unet.head(features)

    def retrieval_tokens(self, features, uv):
        """What SPE retrieval compares along a track: the UNet's features (as READ's denoiser)."""
        return self.image_tokens(features, uv)

    def retrieval_map(self, features):
        """The full map whose samples are ``retrieval_tokens`` (one image, many tracks)."""
        return self.full_features(features)

    def retrieval_embed(self, samples):
        return samples

    def denoise(self, features, z_t, uv, t):
        c = self.cfg
        d = c.d_model
        if z_t.ndim != 2 or z_t.shape[1] != self.latent_dim:
            raise ValueError(f"z_t must have shape (B, {self.latent_dim}), got {z_t.shape}")
        b = z_t.shape[0]
        if uv.shape != (b, motion_lib.FRAMES, 2):
            raise ValueError(f"uv must have shape ({b}, {motion_lib.FRAMES}, 2), got {uv.shape}")
        if features.ndim != 4 or features.shape[0] != b or features.shape[-1] != c.conv_dims[0]:
            raise ValueError(f"features (from encode_image) must have shape (B={b}, H/4, W/4, "
                             f"{c.conv_dims[0]}), got {features.shape}")
        t = jnp.broadcast_to(jnp.asarray(t, jnp.float32), (b,))
        lat = self.latent_embed(z_t)[:, None, :]
        tim = self.time_embed(time_features(t, d))[:, None, :]
        seq = jnp.concatenate([lat, tim], axis=1) + sinusoidal_positions(2, d)
        img = self.image_tokens(features, uv)
        if self.image_proj is not None:
            img = self.image_proj(img)
        x = jnp.concatenate([seq, img + sinusoidal_positions(motion_lib.FRAMES, d)], axis=1)
        for layer in self.layers:
            x = layer(x)
        return z_t + self.head(x[:, 0])
