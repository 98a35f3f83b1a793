"""Small dense linear algebra in pure jnp (no LAPACK custom calls).

MJX factorises its (small, nv x nv) mass matrix and Newton Hessian with
``jax.scipy.linalg.cho_factor``; on the CPU, jaxlib's batched LAPACK ``potrf`` deadlocks at
batch ~128 (../shared/STACK.md). These replacements are a column-by-column Cholesky and two
triangular solves written with ``lax.fori_loop``: exact to float32 round-off, vmap-able,
differentiable, and fast for the n <= ~80 systems that occur here.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jax import lax


def cholesky_lower(a: jax.Array) -> jax.Array:
    """Lower-triangular L with a = L L^T for a symmetric positive-definite ``a`` (..., n, n)."""
    n = a.shape[-1]
    idx = jnp.arange(n)

    def body(j, l):
        row_j = l[..., j, :]  # only columns < j are filled
        s = a[..., :, j] - jnp.einsum("...ik,...k->...i", l, row_j)
        d = jnp.sqrt(jnp.maximum(s[..., j], 1e-30))
        col = jnp.where(idx > j, s / d[..., None], 0.0)
        col = jnp.where(idx == j, d[..., None], col)
        return l.at[..., :, j].set(col)

    return lax.fori_loop(0, n, body, jnp.zeros_like(a))


def solve_lower(l: jax.Array, b: jax.Array) -> jax.Array:
    """Solve L x = b (forward substitution); b is (..., n) or (..., n, k)."""
    vec = b.ndim == l.ndim - 1
    bb = b[..., None] if vec else b
    n = l.shape[-1]

    def body(i, x):
        r = bb[..., i, :] - jnp.einsum("...k,...kc->...c", l[..., i, :], x)
        return x.at[..., i, :].set(r / l[..., i, i][..., None])

    x = lax.fori_loop(0, n, body, jnp.zeros_like(bb))
    return x[..., 0] if vec else x


def solve_upper_t(l: jax.Array, b: jax.Array) -> jax.Array:
    """Solve L^T x = b (back substitution) for lower-triangular L."""
    vec = b.ndim == l.ndim - 1
    bb = b[..., None] if vec else b
    n = l.shape[-1]

    def body(k, x):
        i = n - 1 - k
        r = bb[..., i, :] - jnp.einsum("...k,...kc->...c", l[..., :, i], x)
        return x.at[..., i, :].set(r / l[..., i, i][..., None])

    x = lax.fori_loop(0, n, body, jnp.zeros_like(bb))
    return x[..., 0] if vec else x


def spd_solve(a: jax.Array, b: jax.Array) -> jax.Array:
    """x = a^-1 b for symmetric positive-definite a."""
    l = cholesky_lower(a)
    return solve_upper_t(l, solve_lower(l, b))


def cho_factor(a, lower: bool = False, overwrite_a: bool = False, check_finite: bool = True):
    """Drop-in for ``jax.scipy.linalg.cho_factor``: returns a clean triangular factor."""
    del overwrite_a, check_finite
    l = cholesky_lower(jnp.asarray(a))
    return (l, True) if lower else (jnp.swapaxes(l, -1, -2), False)


def cho_solve(c_and_lower, b, overwrite_b: bool = False, check_finite: bool = True):
    """Drop-in for ``jax.scipy.linalg.cho_solve``; accepts factors from scipy/numpy too."""
    del overwrite_b, check_finite
    c, lower = c_and_lower
    c = jnp.asarray(c)
    l = jnp.tril(c) if lower else jnp.swapaxes(jnp.triu(c), -1, -2)
    return solve_upper_t(l, solve_lower(l, jnp.asarray(b)))


_original = None  # jax.scipy.linalg's own (cho_factor, cho_solve), kept when the replacements go in


def cho_factor_on_cpu(*args, **kwargs):
    """``jax.scipy.linalg.cho_factor`` once installed: :func:`cho_factor` on the CPU backend, the
    original elsewhere (the backend is looked up at the call)."""
    return (cho_factor if jax.default_backend() == "cpu" else _original[0])(*args, **kwargs)


def cho_solve_on_cpu(*args, **kwargs):
    """``jax.scipy.linalg.cho_solve`` once installed: :func:`cho_solve` on the CPU, the original elsewhere."""
    return (cho_solve if jax.default_backend() == "cpu" else _original[1])(*args, **kwargs)


def install_cpu_cholesky(force: bool = False) -> bool:
    """Route ``jax.scipy.linalg.cho_factor/cho_solve`` through the pure-jnp versions.

    Only on the CPU backend (GPU solvers have no such deadlock), unless ``force``. The backend is
    looked up at each call (:func:`cho_factor_on_cpu`), not here: installing (``import readjax``)
    does not start JAX's backend, so a process may still join a multi-process run afterwards
    (:mod:`readjax.distributed`). Returns whether a replacement is installed (always).
    """
    global _original
    if _original is None:
        _original = (jsl.cho_factor, jsl.cho_solve)
    if force:
        jsl.cho_factor, jsl.cho_solve = cho_factor, cho_solve
    else:
        jsl.cho_factor, jsl.cho_solve = cho_factor_on_cpu, cho_solve_on_cpu
    return True
