"""RLBench's placement rules (readjax.sim.placement): turned boxes stay inside their boundary, and the
per-seed rejection loop gives every seed the same result alone and in any batch."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.prng import seed_pure
from readjax.sim import placement


def test_turned_extent_of_a_box_turned_a_quarter():
    lo, hi = placement.turned_extent([-0.1, -0.02], [0.3, 0.02], jnp.pi / 2)
    np.testing.assert_allclose(lo, [-0.02, -0.1], atol=1e-6)
    np.testing.assert_allclose(hi, [0.02, 0.3], atol=1e-6)


def test_spawned_boxes_lie_inside_the_boundary_at_every_yaw():
    keys = jax.random.split(jax.random.key(0, impl="threefry2x32"), 2000)
    box_lo, box_hi = jnp.array([-0.05, -0.15]), jnp.array([0.25, 0.15])
    xy, yaw, fits = jax.vmap(lambda k: placement.place_task(k, box_lo, box_hi))(keys)
    assert bool(fits.all())
    corners = jnp.array([[-0.05, -0.15], [0.25, -0.15], [-0.05, 0.15], [0.25, 0.15]])
    world = jax.vmap(lambda p, a: placement.to_world(p, a, corners))(xy, yaw)
    assert float(world[..., 0].min()) >= placement.WORKSPACE_LOW[0] - 1e-6
    assert float(world[..., 0].max()) <= placement.WORKSPACE_HIGH[0] + 1e-6
    assert float(world[..., 1].min()) >= placement.WORKSPACE_LOW[1] - 1e-6
    assert float(world[..., 1].max()) <= placement.WORKSPACE_HIGH[1] + 1e-6
    # the full turn is used, and the positions spread over the workspace
    assert float(yaw.min()) < -3.0 and float(yaw.max()) > 3.0
    assert float(xy[:, 1].max() - xy[:, 1].min()) > 0.5


def test_a_box_larger_than_its_boundary_does_not_fit():
    _, _, fits = placement.spawn_in_boundary(jax.random.key(1, impl="threefry2x32"), [0, 0], [0.1, 0.1],
                                             [-0.2, -0.2], [0.2, 0.2])
    assert not bool(fits)


def _draw(key):
    return jax.random.uniform(key, (3,))


def _accept(x):  # a data-dependent rule accepting ~20 % of candidates
    return x[0] < 0.2


@pytest.mark.parametrize("batch", [1, 5, 64])
def test_rejection_loop_is_a_function_of_each_seed_alone(batch):
    seeds = np.arange(100, 100 + 64)
    alone = [jax.jit(lambda k: placement.first_accepted(k, _draw, _accept, 50))(seed_pure(int(s)))
             for s in seeds[:batch]]
    fn = jax.jit(jax.vmap(lambda k: placement.first_accepted(k, _draw, _accept, 50)))
    cand, ok, tries = fn(seed_pure(jnp.asarray(seeds[:batch], jnp.int32)))
    for i, (c, o, t) in enumerate(alone):
        np.testing.assert_array_equal(np.asarray(c), np.asarray(cand[i]))
        assert int(t) == int(tries[i]) and bool(o) == bool(ok[i])
    assert bool(ok.all()) and float(cand[:, 0].max()) < 0.2
    if batch == 64:  # the tries differ between seeds: lanes stopped at their own candidate
        assert len(set(np.asarray(tries).tolist())) > 3


def test_rejection_loop_gives_up_after_max_tries():
    cand, ok, tries = placement.first_accepted(seed_pure(3), _draw, lambda x: x[0] < -1.0, 7)
    assert not bool(ok) and int(tries) == 7
