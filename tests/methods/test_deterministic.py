"""The Deterministic baseline: ResNet18 layout, output shapes, and fitting a fixed batch."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.config import ResNetConfig
from readjax.methods import deterministic
from readjax.models.resnet import DeterministicPlanner, ResNetTrunk, param_count

from tests.methods.helpers import SIZE, fit, tiny_batch
from tests.models.helpers import key

TINY = ResNetConfig(input_size=SIZE, stage_widths=(8, 8, 16, 16), stage_blocks=(1, 1, 1, 1), norm_groups=4,
                    proj_dim=8, head_hidden=32)


def test_paper_layout_is_resnet18():
    cfg = ResNetConfig()
    trunk = jax.eval_shape(ResNetTrunk(cfg).init, key(0), jnp.zeros((1, 256, 256, 4)))
    # torchvision's resnet18 without fc (11,176,512 conv + norm parameters) + the 4th input channel
    assert param_count(trunk) == 11_176_512 + 64 * 7 * 7
    out = jax.eval_shape(ResNetTrunk(cfg).apply, trunk, jnp.zeros((1, 256, 256, 4)))
    assert out.shape == (1, 8, 8, 512)  # no global pooling
    assert cfg.flat_dim == 8 * 8 * 256 and cfg.hidden == cfg.flat_dim // 2
    with pytest.raises(ValueError, match="norm_groups"):
        ResNetConfig(stage_widths=(8, 16, 32, 48), norm_groups=32)
    with pytest.raises(ValueError, match="multiple of 32"):
        ResNetConfig(input_size=48)


def test_shapes_and_fit():
    model = DeterministicPlanner(TINY)
    batch = tiny_batch()
    params = jax.jit(model.init)(key(0), jnp.asarray(batch["image"]))
    out = jax.jit(model.apply)(params, jnp.asarray(batch["image"]))
    assert out.shape == (4, 101, 10) and np.all(np.isfinite(out))
    first, final = fit(deterministic.loss(model, augment=False), params, batch, steps=8)
    assert final < 0.7 * first
    with pytest.raises(ValueError, match="input_size"):
        model.apply(params, jnp.zeros((1, 64, 64, 4)))
