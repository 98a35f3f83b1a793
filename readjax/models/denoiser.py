"""The READ denoiser (METHOD.md section 6): image features sampled along the motion + transformer.

Given the image's feature map F (from :class:`~readjax.models.convnext_unet.ConvNeXtUNet`), the
current motion M_t (B, 101, 10) and the diffusion time t in [0, 1], it predicts the clean motion:

* 101 motion tokens: MLP 10 -> d -> 2d -> d of each frame;
* 1 time token: sinusoidal features of the raw t (frequencies exp(-k log(5000)/(d/2 - 1))), then
  an MLP d -> d -> 2d -> d;
* 101 image tokens: F bilinearly sampled at each frame's uv (:func:`sample_features`), projected
  to d when C != d;
* sinusoidal positions on [motion, time] (0..101) and, separately, on the image tokens (0..100);
* optional extra conditioning tokens (the retrieved motion, for the VPSDE+CG baseline): embedded
  by their own MLP, their own positions 0..100, and a per-sample keep flag that masks them out of
  attention (classifier-free dropout; masked keys = the unconditional branch);
* ``layers`` post-LN transformer encoder layers over all tokens; per-key heads d -> d/2 -> d/2 ->
  dim on the motion tokens' outputs.

``output="delta"``: returns M_t + heads (READ's M̂0). ``output="eps"``: returns the heads' output
as is (noise-predicting baselines). The image is encoded ONCE by :meth:`Denoiser.encode_image`
(the UNet trunk, from which the full-resolution map's samples are computed exactly, see
:mod:`readjax.models.convnext_unet`); :meth:`Denoiser.denoise` reuses it at every step.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import flax.linen as nn

from readjax.camera import DEPTH_FAR, DEPTH_NEAR
from readjax.config import DenoiserConfig
from readjax import motion as motion_lib
from readjax.motion import check_motion_shape
from readjax.models.convnext_unet import HEAD_STRIDE, ConvNeXtUNet, bilinear_axis
from readjax.models.vae import KEY_DIMS, MLP, EncoderLayer, embed_mlp, sinusoidal_positions

OUTPUTS = ("delta", "eps")
TIME_MAX_PERIOD = 5000.0


def sample_features(features: jax.Array, uv: jax.Array) -> jax.Array:
    """Bilinear samples of a feature map (B, H, W, C) at normalised points uv (B, T, 2) -> (B, T, C).

    uv in [-1, 1] follows :mod:`readjax.camera`: u = 2 u_px / W - 1 with pixel i covering
    [i, i + 1), so pixel centres sit at u_px = i + 0.5 and the map (one vector per pixel) is sampled
    at x = (u + 1) W / 2 - 0.5. Points beyond the outermost pixel centres are clamped to the
    border. Differentiable in both the features and uv."""
    if features.ndim != 4:
        raise ValueError(f"features must have shape (B, H, W, C), got {features.shape}")
    if uv.ndim != 3 or uv.shape[-1] != 2 or uv.shape[0] != features.shape[0]:
        raise ValueError(f"uv must have shape (B={features.shape[0]}, T, 2), got {uv.shape}")
    b, h, w, c = features.shape
    return bilinear_gather(features.reshape(b, h * w, c), uv, h, w, lambda y, x: y * w + x)


def bilinear_gather(flat: jax.Array, uv: jax.Array, h: int, w: int, index) -> jax.Array:
    """Bilinear samples (B, T, C) at uv (B, T, 2) of an h x w map stored as rows of ``flat``
    (B, N, C), pixel (y, x) at row ``index(y, x)`` (the convention of :func:`sample_features`)."""
    y0, y1, wy = bilinear_axis(uv[..., 1], h)
    x0, x1, wx = bilinear_axis(uv[..., 0], w)

    def at(yi, xi):
        return jnp.take_along_axis(flat, index(yi, xi)[..., None], axis=1)

    wx, wy = wx[..., None], wy[..., None]
    return ((1 - wx) * (1 - wy) * at(y0, x0) + wx * (1 - wy) * at(y0, x1)
            + (1 - wx) * wy * at(y1, x0) + wx * wy * at(y1, x1))


def time_features(t: jax.Array, dim: int) -> jax.Array:
    """Sinusoidal features (B, dim) of raw diffusion times t (B,) in [0, 1] (the released code's)."""
    half = dim // 2
    if half < 2:
        raise ValueError(f"time features need dim >= 4, got {dim}")
    freqs = jnp.exp(jnp.arange(half, dtype=jnp.float32) * (-math.log(TIME_MAX_PERIOD) / (half - 1)))
    arg = t[:, None] * freqs[None, :]
    return jnp.concatenate([jnp.sin(arg), jnp.cos(arg)], axis=-1)


class Denoiser(nn.Module):
    """READ's image-conditioned motion denoiser (see the module docstring).

    Methods (through ``apply(..., method=...)``):

    * ``encode_image(image, train=False) -> features``: the per-image cache, the UNet trunk's
      output (B, H/4, W/4, conv_dims[0]) (see :mod:`readjax.models.convnext_unet`);
    * ``image_tokens(features, uv) -> (B, T, C)``: the full-resolution C-channel feature map
      bilinearly sampled at uv (B, T, 2) (T is arbitrary);
    * ``full_features(features) -> (B, H, W, C)``: the full map from a cache;
    * ``track_tokens(features, uv) -> (B, T, d)``: the image tokens the transformer reads;
    * ``retrieval_tokens(features, uv)``: what SPE compares (``image_tokens``; ``track_tokens``
      with ``input_skip``), and ``retrieval_map(features)`` / ``retrieval_embed(samples)``, its
      form for one image sampled along many tracks;
    * ``feature_map(image, train=False) -> (B, H, W, C)``: the full map itself (inspection, tests);
    * ``denoise(features, motion_t, t, cond=None, cond_keep=None, track=None) -> (B, 101, 10)``;
    * ``__call__(image, motion_t, t, cond=None, cond_keep=None, train=False, track=None)`` = encode + denoise
      (for init and training). Training with drop-path needs ``train=True`` and
      ``rngs={"dropout": key}``.

    ``t`` is a scalar or (B,). ``cond`` (B, 101, 10) is only accepted when ``use_cond``; with
    ``use_cond`` and ``cond=None`` the conditioning tokens are all masked (unconditional).
    ``cond_keep`` (B,) bool masks them per sample. ``track`` (B, 101, 10), when given, is the motion in
    real units that places the image tokens (its uv) and, with ``surface_depth``, the frames' depth
    (its z) instead of ``motion_t`` itself (the baselines that diffuse normalised motions feed the
    normalised motion and its real track); None keeps READ's behaviour.
    """

    cfg: DenoiserConfig
    use_cond: bool = False
    output: str = "delta"

    def setup(self):
        c = self.cfg
        if self.output not in OUTPUTS:
            raise ValueError(f"output must be one of {OUTPUTS}, got {self.output!r}")
        d = c.d_model
        self.unet = ConvNeXtUNet(c)
        self.motion_embed = embed_mlp(d)
        self.time_embed = embed_mlp(d)
        self.image_proj = nn.Dense(d) if c.feature_channels != d else None
        self.input_embed = embed_mlp(d) if c.input_skip else None
        self.cond_embed = embed_mlp(d) if self.use_cond else None
        self.layers = [EncoderLayer(d, c.heads, c.ffn) for _ in range(c.layers)]
        self.heads = {k: MLP((d // 2, d // 2, dim)) for k, dim in KEY_DIMS.items()}

    def __call__(self, image, motion_t, t, cond=None, cond_keep=None, train: bool = False, track=None):
        return self.denoise(self.encode_image(image, train), motion_t, t, cond, cond_keep, track)

    def encode_image(self, image, train: bool = False):
        """The per-image feature cache (computed once per image, reused at every step): the UNet
        trunk's output, followed by the input pixels (space-to-depth) with ``input_skip``."""
        trunk = self.unet.trunk(image, train)
        if not self.cfg.input_skip:
            return trunk
        b, h, w, k = image.shape
        s = HEAD_STRIDE
        pixels = image.reshape(b, h // s, s, w // s, s, k).transpose(0, 1, 3, 2, 4, 5)
        return jnp.concatenate([trunk, pixels.reshape(b, h // s, w // s, s * s * k).astype(trunk.dtype)], -1)

    def image_tokens(self, features, uv):
        """Samples (B, T, C) of the full-resolution feature map at uv (B, T, 2)."""
        return self.unet.head_at(features[..., : self.cfg.conv_dims[0]], uv)

    def full_features(self, features):
        """The full-resolution C-channel feature map (B, H, W, C) from a cache: what ``image_tokens``
        samples."""
        return self.unet.head(features[..., : self.cfg.conv_dims[0]])

    def track_tokens(self, features, uv):
        """The image tokens the transformer reads along a track (B, T, d), before positions: the
        sampled features (projected to d when C != d), plus the embedded input pixels with
        ``input_skip``."""
        pixels = self.input_at(features, uv) if self.cfg.input_skip else None
        return self._tokens(self.image_tokens(features, uv), pixels)

    def _tokens(self, img, pixels):
        """Image tokens from sampled features (projected to d when C != d) and, with
        ``input_skip``, sampled input pixels (embedded and added)."""
        if self.image_proj is not None:
            img = self.image_proj(img)
        return img if pixels is None else img + self.input_embed(pixels)

    def retrieval_tokens(self, features, uv):
        """What SPE retrieval (METHOD.md section 7) compares along a track: the UNet's features
        (``image_tokens``, the paper); with ``input_skip`` the transformer's own image tokens
        (``track_tokens``), which add the embedded input pixels, so retrieval sees the depth under
        the track that the denoiser reads (beyond the paper, see README)."""
        if self.cfg.input_skip:
            return self.track_tokens(features, uv)
        return self.image_tokens(features, uv)

    def retrieval_map(self, features):
        """A full-resolution map (B, H, W, C') whose bilinear samples, passed through
        ``retrieval_embed``, equal ``retrieval_tokens``: worth materialising when one image is
        sampled along many tracks (SPE over a database). The UNet's full map, followed by the
        input pixels (normalised as ``input_at`` returns them) with ``input_skip``."""
        full = self.full_features(features)
        if not self.cfg.input_skip:
            return full
        return jnp.concatenate([full, self._input_pixels(features)], axis=-1)

    def retrieval_embed(self, samples):
        """Samples (..., C') of ``retrieval_map`` -> ``retrieval_tokens``' values (the features are
        linear in the map, the input embedding is applied after sampling, as in ``track_tokens``)."""
        if not self.cfg.input_skip:
            return samples
        c = self.cfg.feature_channels
        return self._tokens(samples[..., :c], samples[..., c:])

    def _input_pixels(self, features):
        """The cache's input pixels back at full resolution (B, H, W, in_channels) (undoing
        ``encode_image``'s space-to-depth), each normalised as ``input_at`` returns it."""
        c = self.cfg
        b, hs, ws, _ = features.shape
        s, k = HEAD_STRIDE, c.in_channels
        x = features[..., c.conv_dims[0]:].reshape(b, hs, ws, s, s, k).transpose(0, 1, 3, 2, 4, 5)
        return self._normalise_pixels(x.reshape(b, hs * s, ws * s, k))

    def _normalise_pixels(self, x):
        """Input RGB-D values (..., in_channels) as the transformer reads them: RGB centred, depth in
        metres, standardised like z when motion stats exist. Affine per channel, so it commutes
        with bilinear sampling."""
        c = self.cfg
        depth = DEPTH_NEAR + (DEPTH_FAR - DEPTH_NEAR) * x[..., 3:4]
        if c.motion_std:
            z = motion_lib.KEYS["z"].start
            depth = (depth - c.motion_mean[z]) / c.motion_std[z]
        return jnp.concatenate([x[..., :3] - 0.5, depth, x[..., 4:]], axis=-1)

    def input_at(self, features, uv):
        """The input RGB-D (B, T, in_channels) bilinearly sampled at uv, from an ``input_skip``
        cache; RGB centred, depth in metres, standardised like the motion's z when motion stats
        exist. Gathers the four neighbours of each point straight from the cache's space-to-depth
        layout (equal to sampling ``_input_pixels``, without rebuilding the full image per call)."""
        c = self.cfg
        s, k = HEAD_STRIDE, c.in_channels
        b, hs, ws, _ = features.shape
        flat = features[..., c.conv_dims[0]:].reshape(b, hs * ws * s * s, k)

        def index(y, x):  # pixel (y, x) sits in trunk cell (y // s, x // s), slot (y % s, x % s)
            return ((y // s) * ws + x // s) * (s * s) + (y % s) * s + x % s

        return self._normalise_pixels(bilinear_gather(flat, uv, hs * s, ws * s, index))

    def feature_map(self, image, train: bool = False):
        """The full-resolution C-channel feature map (B, H, W, C)."""
        return self.unet(image, train)

    def surface_offset(self, track, pixels):
        """How far each frame of ``track`` (B, T, 10, real units) lies beyond the visible surface under
        it, z - depth(uv) (B, T, 1), from the ``input_at`` samples ``pixels`` at its uv: in units of
        the standardised z when motion stats exist (both sides are standardised alike), else metres."""
        c = self.cfg
        z = track[..., motion_lib.KEYS["z"]]
        if c.motion_std:
            i = motion_lib.KEYS["z"].start
            z = (z - c.motion_mean[i]) / c.motion_std[i]
        return z - pixels[..., 3:4]

    def denoise(self, features, motion_t, t, cond=None, cond_keep=None, track=None):
        c = self.cfg
        d = c.d_model
        check_motion_shape(motion_t, "motion_t")
        b = motion_t.shape[0]
        if features.ndim != 4 or features.shape[0] != b or features.shape[-1] != c.cache_channels:
            raise ValueError(f"features (from encode_image) must have shape (B={b}, H/4, W/4, "
                             f"{c.cache_channels}), got {features.shape}")
        t = jnp.asarray(t, jnp.float32)
        if t.ndim > 1 or (t.ndim == 1 and t.shape[0] != b):
            raise ValueError(f"t must be a scalar or have shape ({b},), got {t.shape}")
        t = jnp.broadcast_to(t, (b,))

        if c.motion_std:  # per-channel standardised embedding and delta (DenoiserConfig)
            mean = jnp.asarray(c.motion_mean, jnp.float32)
            std = jnp.asarray(c.motion_std, jnp.float32)
        else:
            mean, std = 0.0, 1.0
        if track is None:
            track = motion_t
        elif track.shape != motion_t.shape:
            raise ValueError(f"track must have the shape of motion_t {motion_t.shape}, got {track.shape}")
        uv = motion_lib.uv(track)
        pixels = self.input_at(features, uv) if c.input_skip else None
        motion_in = (motion_t - mean) / std
        if c.surface_depth:
            motion_in = jnp.concatenate([motion_in, self.surface_offset(track, pixels)], axis=-1)
        motion_tok = self.motion_embed(motion_in)
        time_tok = self.time_embed(time_features(t, d))[:, None, :]
        seq = jnp.concatenate([motion_tok, time_tok], axis=1) + sinusoidal_positions(motion_lib.FRAMES + 1, d)
        img = self._tokens(self.image_tokens(features, uv), pixels)
        tokens = [seq, img + sinusoidal_positions(motion_lib.FRAMES, d)]

        mask = None
        if self.use_cond:
            if cond is None:
                cond = jnp.zeros_like(motion_t)
                cond_keep = jnp.zeros((b,), bool)
            check_motion_shape(cond, "cond")
            if cond.shape[0] != b:
                raise ValueError(f"cond must have batch size {b}, got {cond.shape[0]}")
            tokens.append(self.cond_embed((cond - mean) / std) + sinusoidal_positions(motion_lib.FRAMES, d))
            if cond_keep is not None:
                cond_keep = jnp.asarray(cond_keep, bool)
                if cond_keep.shape != (b,):
                    raise ValueError(f"cond_keep must have shape ({b},), got {cond_keep.shape}")
                n_other = 2 * motion_lib.FRAMES + 1
                keys = jnp.concatenate([jnp.ones((b, n_other), bool),
                                        jnp.broadcast_to(cond_keep[:, None], (b, motion_lib.FRAMES))], axis=1)
                mask = keys[:, None, None, :]  # (B, heads: broadcast, queries: broadcast, keys)
        elif cond is not None or cond_keep is not None:
            raise ValueError("this Denoiser was built with use_cond=False; it takes no cond tokens")

        x = jnp.concatenate(tokens, axis=1)
        for layer in self.layers:
            x = layer(x, mask)
        h = x[:, : motion_lib.FRAMES]
        out = motion_lib.join_keys({k: self.heads[k](h) for k in motion_lib.KEYS})
        return motion_t + out * std if self.output == "delta" else out
