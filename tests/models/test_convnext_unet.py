"""ConvNeXt UNet: full-resolution output, exact sparse head sampling, depthwise conv, drop-path."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.models.convnext_unet import ConvNeXtUNet, DropPath, depthwise_conv
from readjax.models.denoiser import sample_features

from tests.models.helpers import TINY_UNET, jit_init, jitted, key, tree_finite, tree_norm


@pytest.fixture(scope="module")
def unet():
    model = ConvNeXtUNet(TINY_UNET)
    image = jax.random.uniform(key(0), (2, 32, 32, 4))
    params = jit_init(model, key(1), image)
    return model, params, image


def test_full_resolution_feature_map(unet):
    model, params, image = unet
    full = jitted(model)(params, image)
    trunk = jitted(model, "trunk")(params, image)
    assert full.shape == (2, 32, 32, TINY_UNET.feature_channels)
    assert trunk.shape == (2, 8, 8, TINY_UNET.conv_dims[0])
    assert bool(jnp.all(jnp.isfinite(full)))
    np.testing.assert_allclose(jitted(model, "head")(params, trunk), full, atol=1e-6)


def test_head_at_equals_sampling_the_full_map(unet):
    model, params, image = unet
    full = jitted(model)(params, image)
    trunk = jitted(model, "trunk")(params, image)
    uv = jax.random.uniform(key(2), (2, 64, 2), minval=-1.3, maxval=1.3)  # includes the borders
    sparse = jitted(model, "head_at")(params, trunk, uv)
    assert sparse.shape == (2, 64, TINY_UNET.feature_channels)
    np.testing.assert_allclose(sparse, sample_features(full, uv), atol=1e-5)


def test_gradients_are_finite_with_drop_path(unet):
    model, params, image = unet

    @jax.jit
    def grads(p, k):
        return jax.grad(lambda p: jnp.mean(model.apply(p, image, True, rngs={"dropout": k}) ** 2))(p)

    g = grads(params, key(3))
    assert tree_finite(g) and tree_norm(g) > 0


def test_drop_path_drops_whole_samples_in_training_only():
    x = jnp.ones((64, 3, 3, 2))
    dp = DropPath(0.5)
    out = dp.apply({}, x, True, rngs={"dropout": key(0)})
    per_sample = np.asarray(out).reshape(64, -1)
    assert set(np.unique(per_sample)) == {0.0, 2.0}  # dropped, or kept and rescaled by 1 / (1 - p)
    assert np.all(per_sample.min(axis=1) == per_sample.max(axis=1))
    assert 10 < int((per_sample[:, 0] == 0).sum()) < 54
    np.testing.assert_array_equal(dp.apply({}, x, False), x)


def test_depthwise_shift_equals_grouped_conv():
    x = jax.random.normal(key(0), (2, 9, 11, 5))
    k = jax.random.normal(key(1), (7, 7, 5))
    shift = jax.jit(lambda x, k: depthwise_conv(x, k, "shift"))(x, k)
    grouped = jax.jit(lambda x, k: depthwise_conv(x, k, "grouped"))(x, k)
    np.testing.assert_allclose(shift, grouped, atol=1e-4)
    with pytest.raises(ValueError):
        depthwise_conv(x, k, "fft")


def test_input_checks(unet):
    model, params, _ = unet
    with pytest.raises(ValueError, match="multiples of 32"):
        jax.eval_shape(lambda i: model.apply(params, i), jnp.zeros((1, 48, 48, 4)))
    with pytest.raises(ValueError, match="4"):
        jax.eval_shape(lambda i: model.apply(params, i), jnp.zeros((1, 32, 32, 3)))
