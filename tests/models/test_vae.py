"""The paper's motion VAE: shapes, gradients, loss, training progress, input checks."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from readjax.models import MotionVAE, make_autoencoder
from readjax.models.vae import kl_divergence, motion_mse, sinusoidal_positions

from tests.models.helpers import TINY_VAE, jit_init, jitted, key, synthetic_batch, tree_finite, tree_norm


@pytest.fixture(scope="module")
def batch():
    return synthetic_batch(8, seed=1)


@pytest.fixture(scope="module")
def vae(batch):
    """The model, its params and jitted methods (compiled once for the module)."""
    model = make_autoencoder(TINY_VAE)
    params = jit_init(model, key(0), batch["motion"])
    return model, params, {m: jitted(model, m) for m in ("encode", "decode", "loss")}


def test_factory_gives_the_paper_vae():
    assert isinstance(make_autoencoder(TINY_VAE), MotionVAE)
    with pytest.raises(ValueError):
        make_autoencoder({"width": 16})


def test_shapes_and_posterior_mean_code(vae, batch):
    model, params, fn = vae
    mu, logvar = fn["encode"](params, batch["motion"])
    assert mu.shape == logvar.shape == (8, TINY_VAE.latent_dim)
    np.testing.assert_array_equal(jitted(model, "code")(params, batch["motion"]), mu)
    rec = fn["decode"](params, mu)
    assert rec.shape == (8, 101, 10)


def test_batched_code_and_decode_equal_one_at_a_time(vae, batch):
    """A motion's code and a code's decoding do not depend on the rest of the batch."""
    model, params, fn = vae
    code, decode = jitted(model, "code"), fn["decode"]
    z = code(params, batch["motion"])
    rec = decode(params, z)
    for i in (0, 3, 7):
        np.testing.assert_allclose(code(params, batch["motion"][i:i + 1])[0], z[i], atol=1e-5)
        np.testing.assert_allclose(decode(params, z[i:i + 1])[0], rec[i], atol=1e-5)


def test_latent_projection_when_latent_dim_differs_from_width(batch):
    """latent_dim != width adds linear maps (checked abstractly: shapes only, nothing compiled)."""
    model = MotionVAE(dataclasses.replace(TINY_VAE, latent_dim=8))
    params = jax.eval_shape(model.init, key(0), batch["motion"])
    assert params["params"]["encoder"]["mu_proj"]["kernel"].shape == (16, 8)
    assert params["params"]["body"]["latent_proj"]["kernel"].shape == (8, 16)
    mu, _ = jax.eval_shape(lambda p, m: model.apply(p, m, method="encode"), params, batch["motion"])
    assert mu.shape == (8, 8)
    rec = jax.eval_shape(lambda p, z: model.apply(p, z, method="decode"), params, mu)
    assert rec.shape == (8, 101, 10)


def test_loss_terms(vae, batch):
    model, params, fn = vae
    total, metrics = fn["loss"](params, batch, None)
    mu, logvar = fn["encode"](params, batch["motion"])
    rec = fn["decode"](params, mu)
    mse = motion_mse(rec, batch["motion"])
    w = TINY_VAE.loss_weights  # uv 10, z 100 (metres), rot6d 1, grip 1
    expect = sum(w[k] * mse[k] for k in w) + TINY_VAE.kl_weight * kl_divergence(mu, logvar)
    np.testing.assert_allclose(total, expect, rtol=1e-5)
    assert set(metrics) == {"loss", "kl", "uv", "z", "rot6d", "grip"}
    # key=None is deterministic (z = mu); a key samples z
    again, _ = fn["loss"](params, batch, None)
    assert float(again) == float(total)
    s1, _ = fn["loss"](params, batch, key(1))
    s2, _ = fn["loss"](params, batch, key(2))
    assert float(s1) != float(s2)


def test_kl_of_standard_normal_is_zero():
    assert float(kl_divergence(jnp.zeros((3, 4)), jnp.zeros((3, 4)))) == 0.0
    np.testing.assert_allclose(kl_divergence(jnp.ones((2, 4)), jnp.zeros((2, 4))), 2.0)


def test_sinusoidal_positions():
    pe = sinusoidal_positions(5, 6)
    assert pe.shape == (5, 6)
    np.testing.assert_allclose(pe[:, 0], np.sin(np.arange(5)), atol=1e-6)
    np.testing.assert_allclose(pe[:, 1], np.cos(np.arange(5)), atol=1e-6)
    np.testing.assert_allclose(pe[3, 4], np.sin(3 * 10000 ** (-4 / 6)), atol=1e-6)


def test_training_reduces_the_loss_with_finite_gradients(vae, batch):
    model, params, fn = vae
    assert "mu_proj" not in params["params"]["encoder"]  # latent_dim == width: no projection
    opt = optax.adam(3e-3)
    state = opt.init(params)

    @jax.jit
    def step(p, s, k):
        (loss, _), g = jax.value_and_grad(lambda p: model.apply(p, batch, k, method="loss"), has_aux=True)(p)
        u, s = opt.update(g, s, p)
        return optax.apply_updates(p, u), s, g

    first, _ = fn["loss"](params, batch, None)
    for i in range(40):
        params, state, grads = step(params, state, key(i))
        if i == 0:
            assert tree_finite(grads) and tree_norm(grads) > 0
            assert jax.tree.structure(grads) == jax.tree.structure(params)
    last, metrics = fn["loss"](params, batch, None)
    assert float(last) < 0.5 * float(first), (float(first), float(last))
    assert float(metrics["uv"]) < 0.05


def test_input_checks(vae, batch):
    model, params, _ = vae
    with pytest.raises(ValueError, match="101, 10"):
        jax.eval_shape(lambda m: model.apply(params, m, method="encode"), batch["motion"][:, :100])
    with pytest.raises(ValueError, match="latent"):
        bad_latent = jnp.zeros((2, TINY_VAE.latent_dim + 1))
        jax.eval_shape(lambda z: model.apply(params, z, method="decode"), bad_latent)
    with pytest.raises(ValueError, match="motion"):
        model.apply(params, {"joints": batch["joints"]}, method="loss")


@pytest.mark.parametrize("masked", [False, True])
def test_attention_is_flaxs_multi_head_attention(masked):
    """The head-major attention has Flax's parameters (names, shapes, initial values: checkpoints
    load either way) and computes the same function, with and without a key mask."""
    import flax.linen as nn

    from readjax.models.vae import Attention

    rng = np.random.default_rng(0)
    x = jnp.asarray(rng.normal(size=(2, 9, 32)), jnp.float32)
    memory = jnp.asarray(rng.normal(size=(2, 5, 32)), jnp.float32)
    mask = (jnp.arange(5)[None, None, None, :] < jnp.array([2, 5])[:, None, None, None]) if masked else None
    ref = nn.MultiHeadDotProductAttention(num_heads=4, qkv_features=32, out_features=32)
    ours = Attention(4, 32)
    p_ref, p_ours = ref.init(key(0), x, memory), ours.init(key(0), x, memory)
    jax.tree.map(np.testing.assert_array_equal, p_ref, p_ours)
    np.testing.assert_allclose(ours.apply(p_ref, x, memory, mask=mask), ref.apply(p_ref, x, memory, mask=mask),
                               atol=2e-6)
