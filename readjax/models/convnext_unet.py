"""The ConvNeXt UNet image encoder of READ (METHOD.md section 6).

RGB-D image (B, H, W, 4) -> C-channel feature map (B, H, W, C) at FULL input resolution, from
which the denoiser samples one feature vector per motion frame (at its uv).

Layout (sizes from :class:`readjax.config.DenoiserConfig`; the released code's structure):

* stem: 3x3 conv to dims[0] + GELU at full resolution;
* encoder: stage 0 after a stride-4 4x4 conv + LayerNorm, stages 1-3 after LayerNorm + stride-2
  2x2 conv; each stage has ``enc_depths[i]`` ConvNeXt blocks (7x7 depthwise conv, LayerNorm,
  1x1 expand x4, GELU, 1x1 project, layer-scale, drop-path, residual);
* decoder, deepest first, 3 levels with skips: LayerNorm + stride-2 transposed conv to half the
  channels, concatenate the encoder's skip, 1x1 conv to dims[i], ``dec_depths[i]`` blocks;
* head: stride-4 4x4 transposed conv from the 1/4-resolution "trunk" output to C channels.

The head's kernel equals its stride, so every full-resolution pixel is a linear function of ONE
trunk pixel: F[4y+i, 4x+j] = T[y, x] @ K[i, j] + b. :meth:`ConvNeXtUNet.head_at` uses this to
return bilinear samples of F at arbitrary uv WITHOUT materialising F (identical values, see
``tests/models``) — the denoiser only ever needs 101 samples per image, and on a CPU the full
(B, H, W, C) map and its gradient cost more than the rest of the network. The trunk output
(B, H/4, W/4, dims[0]) is therefore what the denoiser caches per image; ``__call__`` still
returns the full map.

Two more choices: on the CPU backend the depthwise 7x7 conv is a sum of 49 shifted,
channel-scaled copies (exact; XLA-CPU's grouped convolution was 10-35x slower, measured), and norms are
per-pixel LayerNorms over channels (ConvNeXt's "channels_first" LayerNorm; the released code's
"layer" option normalises over C, H and W together). Drop-path rates grow linearly 0 ->
``drop_path`` over the encoder blocks and fall ``drop_path`` -> 0 over the decoder blocks
(shallowest level first), as in the released code. Training with drop-path > 0 needs
``train=True`` and an rng stream ``"dropout"``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import flax.linen as nn
import numpy as np

from readjax.config import DenoiserConfig

CONV_LN_EPS = 1e-6
DOWNSAMPLE = 32  # total stride of the encoder: H and W must be multiples of it
HEAD_STRIDE = 4  # the head upsamples the trunk output by this factor


class DropPath(nn.Module):
    """Stochastic depth: drop the whole residual branch per sample with probability ``rate``."""

    rate: float

    @nn.compact
    def __call__(self, x, train: bool):
        if not train or self.rate <= 0.0:
            return x
        keep = 1.0 - self.rate
        mask = jax.random.bernoulli(self.make_rng("dropout"), keep, (x.shape[0],) + (1,) * (x.ndim - 1))
        return jnp.where(mask, x / keep, 0.0)


def depthwise_conv(x: jax.Array, kernel: jax.Array, impl: str = "auto") -> jax.Array:
    """'SAME' depthwise convolution of x (B, H, W, C) with kernel (k, k, C), no bias.

    ``impl="shift"`` sums k*k shifted, channel-scaled copies (fast on XLA-CPU, where the grouped
    convolution was 3-35x slower at our sizes, measured); ``"grouped"`` is ``lax.conv`` with one group per
    channel (the fast path on GPUs); ``"auto"`` picks shift on the CPU backend. Both are exact.
    """
    k, c = kernel.shape[0], x.shape[-1]
    if kernel.shape != (k, k, c):
        raise ValueError(f"kernel must have shape (k, k, {c}), got {kernel.shape}")
    if impl == "auto":
        impl = "shift" if jax.default_backend() == "cpu" else "grouped"
    p = k // 2
    pads = ((p, k - 1 - p), (p, k - 1 - p))
    if impl == "grouped":
        return jax.lax.conv_general_dilated(x, kernel[:, :, None, :], (1, 1), pads,
                                            dimension_numbers=("NHWC", "HWIO", "NHWC"), feature_group_count=c)
    if impl != "shift":
        raise ValueError(f"impl must be 'auto', 'shift' or 'grouped', got {impl!r}")
    h, w = x.shape[1:3]
    xp = jnp.pad(x, ((0, 0),) + pads + ((0, 0),))
    # k*k shifted slices, each scaled per channel and summed: XLA fuses the whole sum into one
    # elementwise loop. (Stacking the k column shifts and reducing over the stack, this module's
    # earlier form, compiled faster but ran 40-370x slower forward and 2-10x slower backward on
    # XLA-CPU; the paper-preset UNet trunk went from 8.0 s to 0.74 s per image: BENCHMARKS.md.)
    out = 0.0
    for i in range(k):
        for j in range(k):
            out = out + xp[:, i:i + h, j:j + w, :] * kernel[i, j]
    return out


class DepthwiseConv(nn.Module):
    """'SAME' depthwise k x k convolution with bias (one filter per channel), see :func:`depthwise_conv`."""

    kernel_size: int = 7
    impl: str = "auto"

    @nn.compact
    def __call__(self, x):
        k, c = self.kernel_size, x.shape[-1]
        # fan_in of a depthwise filter is k*k (as for a grouped conv)
        init = nn.initializers.variance_scaling(1.0, "fan_in", "truncated_normal", in_axis=(0, 1), out_axis=-1)
        kernel = self.param("kernel", init, (k, k, c))
        bias = self.param("bias", nn.initializers.zeros, (c,))
        return depthwise_conv(x, kernel, self.impl) + bias


class ConvNeXtBlock(nn.Module):
    """7x7 depthwise conv -> LN -> 1x1 (4x) -> GELU -> 1x1 -> layer-scale -> drop-path, residual."""

    dim: int
    drop_path: float = 0.0
    layer_scale_init: float = 1e-6

    @nn.compact
    def __call__(self, x, train: bool = False):
        y = DepthwiseConv(7, name="dwconv")(x)
        y = nn.LayerNorm(epsilon=CONV_LN_EPS, name="norm")(y)
        y = nn.Dense(4 * self.dim, name="pwconv1")(y)
        y = nn.gelu(y, approximate=False)
        y = nn.Dense(self.dim, name="pwconv2")(y)
        if self.layer_scale_init > 0:
            gamma = self.param("gamma", nn.initializers.constant(self.layer_scale_init), (self.dim,))
            y = gamma * y
        return x + DropPath(self.drop_path)(y, train)


def check_image(image, in_channels: int) -> None:
    shape = getattr(image, "shape", None)
    if shape is None or len(shape) != 4 or shape[-1] != in_channels:
        raise ValueError(f"image must have shape (B, H, W, {in_channels}), got {shape}")
    if shape[1] % DOWNSAMPLE or shape[2] % DOWNSAMPLE:
        raise ValueError(f"image height and width must be multiples of {DOWNSAMPLE}, got {tuple(shape[1:3])}")


class ConvNeXtTrunk(nn.Module):
    """Stem, 4-stage encoder and 3-level decoder: image -> (B, H/4, W/4, dims[0])."""

    cfg: DenoiserConfig

    @nn.compact
    def __call__(self, image, train: bool = False):
        c = self.cfg
        check_image(image, c.in_channels)
        dims = c.conv_dims
        enc_rates = np.linspace(0.0, c.drop_path, max(sum(c.enc_depths), 1))
        dec_rates = np.linspace(c.drop_path, 0.0, max(sum(c.dec_depths), 1))

        x = nn.gelu(nn.Conv(dims[0], (3, 3), padding=1, name="stem")(image), approximate=False)
        skips = []
        cur = 0
        for i in range(4):
            if i == 0:
                x = nn.Conv(dims[0], (4, 4), strides=(4, 4), padding="VALID", name="down_0")(x)
                x = nn.LayerNorm(epsilon=CONV_LN_EPS, name="down_0_norm")(x)
            else:
                x = nn.LayerNorm(epsilon=CONV_LN_EPS, name=f"down_{i}_norm")(x)
                x = nn.Conv(dims[i], (2, 2), strides=(2, 2), padding="VALID", name=f"down_{i}")(x)
            for j in range(c.enc_depths[i]):
                block = ConvNeXtBlock(dims[i], float(enc_rates[cur]), c.layer_scale_init, name=f"enc_{i}_{j}")
                x = block(x, train)
                cur += 1
            skips.append(x)

        offsets = np.concatenate([[0], np.cumsum(c.dec_depths)]).astype(int)
        for i in (2, 1, 0):
            x = nn.LayerNorm(epsilon=CONV_LN_EPS, name=f"up_{i}_norm")(x)
            x = nn.ConvTranspose(dims[i + 1] // 2, (2, 2), strides=(2, 2), padding="VALID", name=f"up_{i}")(x)
            x = jnp.concatenate([x, skips[i]], axis=-1)
            x = nn.Conv(dims[i], (1, 1), name=f"fuse_{i}")(x)
            for j in range(c.dec_depths[i]):
                rate = float(dec_rates[offsets[i] + j])
                x = ConvNeXtBlock(dims[i], rate, c.layer_scale_init, name=f"dec_{i}_{j}")(x, train)
        return x


class ConvNeXtUNet(nn.Module):
    """RGB-D (B, H, W, in_channels) -> features (B, H, W, feature_channels); H, W multiples of 32.

    Methods: ``__call__(image, train=False)`` (full map) = ``head(trunk(image, train))``;
    ``trunk(image, train=False) -> (B, H/4, W/4, dims[0])``; ``head(t) -> (B, H, W, C)``;
    ``head_at(t, uv) -> (B, T, C)``: bilinear samples of ``head(t)`` at uv (B, T, 2), computed
    without the full map (same convention as :func:`readjax.models.denoiser.sample_features`).
    """

    cfg: DenoiserConfig

    def setup(self):
        c = self.cfg
        s = HEAD_STRIDE
        self.trunk_net = ConvNeXtTrunk(c)
        # one trunk pixel feeds s x s output pixels: fan_in = dims[0]
        init = nn.initializers.variance_scaling(1.0, "fan_in", "truncated_normal", in_axis=-2, out_axis=-1,
                                                batch_axis=(0, 1))
        self.head_kernel = self.param("head_kernel", init, (s, s, c.conv_dims[0], c.feature_channels))
        self.head_bias = self.param("head_bias", nn.initializers.zeros, (c.feature_channels,))

    def __call__(self, image, train: bool = False):
        return self.head(self.trunk(image, train))

    def trunk(self, image, train: bool = False):
        return self.trunk_net(image, train)

    def head(self, t):
        b, h, w, _ = t.shape
        s, c = HEAD_STRIDE, self.cfg.feature_channels
        out = jnp.einsum("byxk,ijkc->byixjc", t, self.head_kernel).reshape(b, h * s, w * s, c)
        return out + self.head_bias

    def head_at(self, t, uv):
        if t.ndim != 4 or t.shape[-1] != self.cfg.conv_dims[0]:
            raise ValueError(f"trunk features must have shape (B, h, w, {self.cfg.conv_dims[0]}), "
                             f"got {t.shape}")
        if uv.ndim != 3 or uv.shape[-1] != 2 or uv.shape[0] != t.shape[0]:
            raise ValueError(f"uv must have shape (B={t.shape[0]}, T, 2), got {uv.shape}")
        b, h, w, k = t.shape
        s = HEAD_STRIDE
        big_h, big_w = h * s, w * s
        (y0, y1, wy), (x0, x1, wx) = (bilinear_axis(uv[..., 1], big_h), bilinear_axis(uv[..., 0], big_w))
        flat = t.reshape(b, h * w, k)
        acc = 0.0
        for yi, fy in ((y0, 1 - wy), (y1, wy)):
            for xi, fx in ((x0, 1 - wx), (x1, wx)):
                src = (yi // s) * w + (xi // s)  # (B, T) trunk pixel
                sub = (yi % s) * s + (xi % s)  # (B, T) position inside its s x s output patch
                vec = jnp.take_along_axis(flat, src[..., None], axis=1)  # (B, T, k)
                onehot = jax.nn.one_hot(sub, s * s, dtype=t.dtype)  # (B, T, s*s)
                acc = acc + (fy * fx)[..., None, None] * onehot[..., :, None] * vec[..., None, :]
        kernel = self.head_kernel.reshape(s * s * k, self.cfg.feature_channels)
        return acc.reshape(b, uv.shape[1], s * s * k) @ kernel + self.head_bias


def bilinear_axis(coord: jax.Array, size: int):
    """Neighbour indices and weight along one axis for normalised coords in [-1, 1].

    Pixel i covers [i, i + 1) in pixel units, so coord c maps to (c + 1) size / 2 - 0.5, clamped to
    the outermost pixel centres. Returns (i0, i1, frac) with value = (1 - frac) v[i0] + frac v[i1].
    """
    p = jnp.clip((coord + 1.0) * (0.5 * size) - 0.5, 0.0, size - 1.0)
    f = jnp.floor(p)
    i0 = f.astype(jnp.int32)
    return i0, jnp.minimum(i0 + 1, size - 1), p - f
