"""Fixed-batch fitting and tiny inputs for the method tests."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax

from readjax.methods import common
from tests.models.helpers import key, synthetic_batch

B = 4
SIZE = 32  # TINY_DENOISER's image size


def tiny_batch(n: int = B, seed: int = 0) -> dict:
    """Synthetic FK-consistent motions, their 'retrieved' partners (a permutation) and random images."""
    b = synthetic_batch(n, seed=seed)
    m = np.asarray(b["motion"])
    images = np.asarray(jax.random.uniform(key(seed + 100), (n, SIZE, SIZE, 4)))
    return {"image": images, "motion": m, "retrieved": np.roll(m, 1, axis=0), "joints": np.asarray(b["joints"])}


def stats_of(batch) -> tuple:
    return tuple(jnp.asarray(s) for s in common.motion_stats(batch["motion"]))


def fit(loss_fn, params, batch, steps: int = 8, lr: float = 3e-3, return_params: bool = False):
    """Adam on one fixed batch with one fixed rng (so the loss is a function of the params only);
    returns the loss before and after ``steps`` steps (one compile: the step reports the loss of the
    params it starts from) and, with ``return_params``, the final params."""
    opt = optax.adam(lr)
    rng = key(7)

    @jax.jit
    def step(params, state, batch):
        (loss, _), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, batch, rng)
        updates, state = opt.update(grads, state, params)
        return optax.apply_updates(params, updates), state, loss

    state = opt.init(params)
    losses = []
    for _ in range(steps + 1):
        params, state, loss = step(params, state, batch)
        losses.append(float(loss))
    assert np.all(np.isfinite(losses))
    return (losses[0], losses[-1], params) if return_params else (losses[0], losses[-1])
