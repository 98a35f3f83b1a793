"""The Deterministic baseline's network (METHOD.md section 10, supplement section 7, Fig. 12a).

RGB-D image (B, S, S, 4) -> motion (B, 101, 10) in one forward pass:

* ResNet18 trunk from scratch with 4 input channels and no global pooling: 7x7 stride-2 conv,
  3x3 stride-2 max-pool, four stages of ``stage_blocks`` basic blocks (3x3 conv, norm, ReLU, 3x3
  conv, norm, residual, ReLU; a 1x1 strided projection when the shape changes) with widths
  ``stage_widths`` and strides 1, 2, 2, 2 -> (B, S/32, S/32, 512);
* a per-location linear 512 -> ``proj_dim`` (256), flattened -> (B, (S/32)^2 * proj_dim);
* per-key two-layer GELU MLPs (flat -> ``hidden`` -> 101 * dim_key) reshaped to the motion keys.

Deviation from the released code (timm resnet18): GroupNorm (``norm_groups``) instead of
BatchNorm, so the model has no batch statistics and train/eval behave alike; initialisers are
Flax's defaults (He-normal for the convolutions).
"""

from __future__ import annotations

import flax.linen as nn
import jax

from readjax.config import ResNetConfig
from readjax import motion as motion_lib
from readjax.models.convnext_unet import check_image
from readjax.models.vae import KEY_DIMS

_conv_init = nn.initializers.variance_scaling(2.0, "fan_out", "normal")


class BasicBlock(nn.Module):
    features: int
    stride: int
    groups: int

    @nn.compact
    def __call__(self, x):
        conv = lambda f, k, s, name: nn.Conv(f, (k, k), (s, s), padding=k // 2, use_bias=False,  # noqa: E731
                                             kernel_init=_conv_init, name=name)
        y = conv(self.features, 3, self.stride, "conv1")(x)
        y = nn.relu(nn.GroupNorm(self.groups, name="norm1")(y))
        y = conv(self.features, 3, 1, "conv2")(y)
        y = nn.GroupNorm(self.groups, name="norm2")(y)
        if self.stride != 1 or x.shape[-1] != self.features:
            x = conv(self.features, 1, self.stride, "down_conv")(x)
            x = nn.GroupNorm(self.groups, name="down_norm")(x)
        return nn.relu(x + y)


class ResNetTrunk(nn.Module):
    """ResNet18-style trunk without global pooling: (B, S, S, C) -> (B, S/32, S/32, widths[-1])."""

    cfg: ResNetConfig

    @nn.compact
    def __call__(self, image):
        c = self.cfg
        x = nn.Conv(c.stage_widths[0], (7, 7), (2, 2), padding=3, use_bias=False, kernel_init=_conv_init,
                    name="stem_conv")(image)
        x = nn.relu(nn.GroupNorm(c.norm_groups, name="stem_norm")(x))
        x = nn.max_pool(x, (3, 3), (2, 2), padding=((1, 1), (1, 1)))
        for i, (w, n) in enumerate(zip(c.stage_widths, c.stage_blocks)):
            for j in range(n):
                x = BasicBlock(w, 2 if (i > 0 and j == 0) else 1, c.norm_groups, name=f"stage{i}_block{j}")(x)
        return x


class DeterministicPlanner(nn.Module):
    """Image -> motion (see the module docstring). ``__call__(image) -> (B, 101, 10)``."""

    cfg: ResNetConfig

    @nn.compact
    def __call__(self, image):
        c = self.cfg
        check_image(image, 4)
        if image.shape[1:3] != (c.input_size, c.input_size):
            raise ValueError(f"image must be {c.input_size}x{c.input_size} (ResNetConfig.input_size), got "
                             f"{image.shape[1:3]}")
        b = image.shape[0]
        x = ResNetTrunk(c, name="trunk")(image)
        x = nn.Dense(c.proj_dim, name="proj")(x).reshape(b, -1)
        parts = {}
        for k, dim in KEY_DIMS.items():
            h = nn.gelu(nn.Dense(c.hidden, name=f"{k}_hidden")(x), approximate=False)
            parts[k] = nn.Dense(motion_lib.FRAMES * dim, name=f"{k}_out")(h).reshape(
                b, motion_lib.FRAMES, dim)
        return motion_lib.join_keys(parts)


def param_count(params) -> int:
    return int(sum(x.size for x in jax.tree.leaves(params)))


__all__ = ["BasicBlock", "DeterministicPlanner", "ResNetTrunk", "param_count"]
