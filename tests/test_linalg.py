"""The pure-jnp Cholesky that replaces LAPACK's (which deadlocks in batched MJX on the CPU)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
import scipy.linalg

from readjax import linalg, tasks
from readjax.sim import mjx


def _spd(rng, n, batch=()):
    a = rng.normal(size=batch + (n, n))
    return a @ np.swapaxes(a, -1, -2) + n * np.eye(n)


def test_cholesky_matches_numpy():
    rng = np.random.default_rng(0)
    a = _spd(rng, 9, (5,)).astype(np.float32)
    l = np.asarray(linalg.cholesky_lower(jnp.asarray(a)))
    np.testing.assert_allclose(l, np.linalg.cholesky(a), rtol=1e-4, atol=1e-4)


def test_spd_solve_vector_and_matrix_rhs():
    rng = np.random.default_rng(1)
    a = _spd(rng, 7).astype(np.float32)
    b = rng.normal(size=(7,)).astype(np.float32)
    bm = rng.normal(size=(7, 3)).astype(np.float32)
    np.testing.assert_allclose(np.asarray(linalg.spd_solve(jnp.asarray(a), jnp.asarray(b))),
                               np.linalg.solve(a, b), rtol=1e-3, atol=1e-4)
    np.testing.assert_allclose(np.asarray(linalg.spd_solve(jnp.asarray(a), jnp.asarray(bm))),
                               np.linalg.solve(a, bm), rtol=1e-3, atol=1e-4)


def test_cho_solve_accepts_scipy_upper_factor():
    """MJX's io.py factorises with scipy (upper, garbage below): our cho_solve must ignore it."""
    rng = np.random.default_rng(2)
    a = _spd(rng, 6)
    c, lower = scipy.linalg.cho_factor(a)
    b = rng.normal(size=6)
    x = linalg.cho_solve((jnp.asarray(c, jnp.float32), lower), jnp.asarray(b, jnp.float32))
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(a, b), rtol=1e-3, atol=1e-4)


def test_installed_and_no_lapack_in_mjx_step():
    assert jsl.cho_factor is linalg.cho_factor_on_cpu and jsl.cho_solve is linalg.cho_solve_on_cpu
    env = tasks.make("pick_up_cup")
    step = jax.vmap(lambda d: mjx.step(env.mx, d))
    d = jax.tree.map(lambda x: jnp.stack([x, x]), env._data0)
    hlo = jax.jit(step).lower(d).as_text()
    assert "lapack" not in hlo.lower() and "potrf" not in hlo.lower()
