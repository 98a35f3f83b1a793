"""Seed-pure keys: a threefry key whatever the default PRNG, and draws that do not depend on the batch."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.prng import THREEFRY, seed_pure


def _data(k):
    return np.asarray(jax.random.key_data(k))


def test_an_rbg_key_maps_to_the_threefry_key_of_the_same_seed_and_history():
    rbg = jax.random.key(7, impl="rbg")
    tf = jax.random.key(7, impl=THREEFRY)
    np.testing.assert_array_equal(_data(seed_pure(rbg)), _data(tf))
    np.testing.assert_array_equal(_data(seed_pure(jax.random.fold_in(rbg, 3))), _data(jax.random.fold_in(tf, 3)))
    np.testing.assert_array_equal(_data(seed_pure(jax.random.split(rbg, 4))), _data(jax.random.split(tf, 4)))
    assert seed_pure(tf) is tf


def test_integer_seeds_give_one_key_each():
    keys = seed_pure(np.arange(5))
    assert keys.shape == (5,) and str(jax.random.key_impl(keys)) == THREEFRY
    np.testing.assert_array_equal(_data(keys[3]), _data(seed_pure(3)))
    with pytest.raises(TypeError, match="integer seeds"):
        seed_pure(np.ones(3, np.float32))


def test_vmapped_draws_are_a_function_of_their_own_key():
    """The invariant rbg breaks: element i of a vmapped draw must depend on key i only."""
    draw = jax.jit(jax.vmap(lambda s: jax.random.uniform(seed_pure(s), (3,))))
    big = draw(jnp.arange(100))
    np.testing.assert_array_equal(draw(jnp.arange(40, 43))[1], big[41])
    np.testing.assert_array_equal(draw(jnp.array([41]))[0], big[41])
