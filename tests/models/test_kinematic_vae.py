"""[beyond] The kinematics-aware autoencoder: joint limits, FK consistency, gradients, training."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from readjax import motion as mo
from readjax.models import KinematicAE, KinematicConstants, fk_motion, make_autoencoder
from readjax.sim import kinematics as kin

from tests.models.helpers import (TINY_VAE, chain_and_camera, jit_init, jitted, key, synthetic_batch,
                                  tree_finite, tree_norm)

KIN_VAE = dataclasses.replace(TINY_VAE, kinematic=True)


@pytest.fixture(scope="module")
def batch():
    return synthetic_batch(8, seed=2)


@pytest.fixture(scope="module")
def kae(batch):
    chain, cam = chain_and_camera()
    model = make_autoencoder(KIN_VAE, chain, cam)
    params = jit_init(model, key(0), batch["motion"])
    return model, params, {m: jitted(model, m) for m in ("code", "decode_with_joints", "loss")}


def test_factory_and_constants():
    chain, cam = chain_and_camera()
    assert isinstance(make_autoencoder(KIN_VAE, chain, cam), KinematicAE)
    with pytest.raises(ValueError, match="chain"):
        make_autoencoder(KIN_VAE)
    # content-hashed constants: equal modules built twice hash equal (jit static arguments)
    a, b = KinematicConstants(chain, cam), KinematicConstants(chain, cam)
    assert a == b and hash(a) == hash(b)
    assert hash(make_autoencoder(KIN_VAE, chain, cam)) == hash(make_autoencoder(KIN_VAE, chain, cam))
    with pytest.raises(ValueError):
        KinematicConstants(chain, {"not": "a camera"})


def test_fk_motion_matches_the_motion_format(batch):
    chain, cam = chain_and_camera()
    motion = jax.jit(lambda q, g: fk_motion(chain, cam, q, g))(batch["joints"], mo.grip(batch["motion"]))
    np.testing.assert_allclose(motion, batch["motion"], atol=1e-5)


def test_decoded_joints_stay_inside_the_limits(kae, batch):
    model, params, fn = kae
    chain, cam = chain_and_camera()
    mu = fn["code"](params, batch["motion"])
    z = jnp.concatenate([mu, 100.0 * jax.random.normal(key(3), mu.shape), -1e4 * jnp.ones_like(mu),
                         1e4 * jnp.ones_like(mu)])
    motion, q = fn["decode_with_joints"](params, z)
    assert motion.shape == (32, 101, 10) and q.shape == (32, 101, 7)
    assert bool(jnp.all(q > chain.lower)) and bool(jnp.all(q < chain.upper))
    # the decoded motion is the FK of the decoded joints, in the readjax motion format
    expect = jax.jit(lambda q, g: mo.encode(cam, *kin.fk(chain, q), g))(q, mo.grip(motion)[..., 0])
    np.testing.assert_allclose(motion, expect, atol=2e-5)


def test_loss_terms_and_checks(kae, batch):
    model, params, fn = kae
    total, m = fn["loss"](params, batch, None)
    assert set(m) == {"loss", "kl", "joints", "uv", "z", "rot6d", "grip"}
    w = KIN_VAE.loss_weights
    expect = (sum(w[k] * m[k] for k in ("uv", "z", "rot6d", "grip")) + KIN_VAE.w_joint * m["joints"]
              + KIN_VAE.kl_weight * m["kl"])
    np.testing.assert_allclose(total, expect, rtol=1e-5)
    with pytest.raises(ValueError, match="joints"):
        model.apply(params, {"motion": batch["motion"]}, method="loss")
    with pytest.raises(ValueError, match="joints"):
        model.apply(params, {"motion": batch["motion"], "joints": batch["joints"][..., :6]}, method="loss")


def test_training_reduces_the_loss_with_finite_gradients(kae, batch):
    model, params, fn = kae
    opt = optax.adam(3e-3)
    state = opt.init(params)

    @jax.jit
    def step(p, s, k):
        (loss, _), g = jax.value_and_grad(lambda p: model.apply(p, batch, k, method="loss"), has_aux=True)(p)
        u, s = opt.update(g, s, p)
        return optax.apply_updates(p, u), s, g

    first, m0 = fn["loss"](params, batch, None)
    for i in range(40):
        params, state, grads = step(params, state, key(i))
        if i == 0:
            assert tree_finite(grads) and tree_norm(grads) > 0
    last, m1 = fn["loss"](params, batch, None)
    assert float(last) < 0.5 * float(first), (float(first), float(last))
    assert float(m1["joints"]) < float(m0["joints"])
