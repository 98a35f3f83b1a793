"""READ denoiser: feature sampling, shapes, gradients, delta/eps outputs, conditioning tokens."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from readjax.models import Denoiser, sample_features
from readjax.models.denoiser import time_features

from tests.models.helpers import TINY_DENOISER, jit_init, jitted, key, synthetic_batch, tree_finite, tree_norm

B = 2


@pytest.fixture(scope="module")
def inputs():
    image = jax.random.uniform(key(0), (B, 32, 32, 4))
    motion = synthetic_batch(B, seed=3)["motion"]
    return image, motion, jnp.array([0.2, 0.9])


@pytest.fixture(scope="module")
def den(inputs):
    image, motion, t = inputs
    model = Denoiser(TINY_DENOISER)
    params = jit_init(model, {"params": key(1), "dropout": key(2)}, image, motion, t)
    return model, params, {m: jitted(model, m) for m in ("encode_image", "denoise")}


# ----------------------------------------------------------------------------- sampling

def test_sample_features_at_pixel_centres_midpoints_and_borders():
    f = jax.random.normal(key(0), (1, 4, 6, 3))

    def centre(i, n):  # normalised coordinate of pixel centre i
        return 2 * (i + 0.5) / n - 1

    uv = jnp.array([[[centre(2, 6), centre(1, 4)],  # pixel (row 1, col 2)
                     [0.5 * (centre(2, 6) + centre(3, 6)), centre(1, 4)],  # between cols 2 and 3
                     [-1.5, -1.5], [1.5, 1.5]]])  # clamped to the corners
    out = sample_features(f, uv)
    np.testing.assert_allclose(out[0, 0], f[0, 1, 2], atol=1e-6)
    np.testing.assert_allclose(out[0, 1], 0.5 * (f[0, 1, 2] + f[0, 1, 3]), atol=1e-6)
    np.testing.assert_allclose(out[0, 2], f[0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(out[0, 3], f[0, 3, 5], atol=1e-6)
    g = jax.grad(lambda f, uv: jnp.sum(sample_features(f, uv) ** 2), argnums=(0, 1))(f, uv)
    assert tree_finite(g)
    with pytest.raises(ValueError):
        sample_features(f, uv[..., :1])


def test_time_features():
    tf = time_features(jnp.array([0.0, 1.0]), 8)
    assert tf.shape == (2, 8)
    np.testing.assert_allclose(tf[0], [0, 0, 0, 0, 1, 1, 1, 1], atol=1e-7)  # sin(0), cos(0)
    np.testing.assert_allclose(tf[1, 0], np.sin(1.0), atol=1e-6)


# ----------------------------------------------------------------------------- the network

def test_shapes_and_image_encoded_once(den, inputs):
    model, params, fn = den
    image, motion, t = inputs
    feats = fn["encode_image"](params, image)
    assert feats.shape == (B, 8, 8, TINY_DENOISER.conv_dims[0])
    out = fn["denoise"](params, feats, motion, t)
    assert out.shape == (B, 101, 10) and bool(jnp.all(jnp.isfinite(out)))
    np.testing.assert_allclose(jitted(model)(params, image, motion, t), out, atol=1e-5)
    # a scalar t broadcasts over the batch
    np.testing.assert_allclose(fn["denoise"](params, feats, motion, 0.9)[1], out[1], atol=1e-5)
    # image tokens = samples of the full-resolution map
    fmap = jitted(model, "feature_map")(params, image)
    assert fmap.shape == (B, 32, 32, TINY_DENOISER.feature_channels)
    tokens = jitted(model, "image_tokens")(params, feats, motion[..., :2])
    np.testing.assert_allclose(tokens, sample_features(fmap, motion[..., :2]), atol=1e-5)


def test_gradients_are_finite(den, inputs):
    model, params, _ = den
    image, motion, t = inputs

    @jax.jit
    def grads(p, k):
        def f(p):
            pred = model.apply(p, image, motion + 0.1, t, train=True, rngs={"dropout": k})
            return jnp.mean((pred - motion) ** 2)
        return jax.grad(f)(p)

    g = grads(params, key(4))
    assert tree_finite(g) and tree_norm(g) > 0
    # every parameter (UNet trunk, head, embeddings, transformer, heads) receives a gradient
    assert all(float(jnp.abs(x).max()) > 0 for x in jax.tree.leaves(g["params"]["unet"]))


def test_delta_and_eps_outputs_share_the_network(den, inputs):
    model, params, fn = den
    image, motion, t = inputs
    feats = fn["encode_image"](params, image)
    eps_model = Denoiser(TINY_DENOISER, output="eps")
    eps = jitted(eps_model, "denoise")(params, feats, motion, t)
    np.testing.assert_allclose(fn["denoise"](params, feats, motion, t) - motion, eps, atol=1e-5)
    with pytest.raises(ValueError, match="output"):
        bad = Denoiser(TINY_DENOISER, output="x0")
        jax.eval_shape(lambda f: bad.apply(params, f, motion, t, method="denoise"), feats)


def test_motion_normalisation_is_a_change_of_units(den, inputs):
    """With motion stats the network sees (M - mean) / std and its delta is scaled by std: the same
    parameters give mean + std * (the raw-unit network on the standardised motion, read at the real uv)."""
    import dataclasses

    model, params, fn = den
    image, motion, t = inputs
    mean = np.linspace(-0.5, 1.0, 10).astype(np.float32)
    std = np.linspace(0.02, 0.5, 10).astype(np.float32)
    norm_model = Denoiser(dataclasses.replace(TINY_DENOISER, motion_mean=tuple(map(float, mean)),
                                              motion_std=tuple(map(float, std))))
    feats = fn["encode_image"](params, image)
    out = jitted(norm_model, "denoise")(params, feats, motion, t)
    x = (motion - mean) / std
    ref = jax.jit(lambda p, f, m, tt, track: model.apply(p, f, m, tt, track=track, method="denoise"))(
        params, feats, x, t, motion)
    np.testing.assert_allclose(out, mean + std * ref, atol=1e-5)
    with pytest.raises(ValueError, match="motion_std"):
        dataclasses.replace(TINY_DENOISER, motion_mean=(0.0,) * 10, motion_std=(1.0,) * 9)


def test_conditioning_tokens(inputs):
    image, motion, t = inputs
    cond = motion[::-1]
    model = Denoiser(TINY_DENOISER, use_cond=True)
    params = jit_init(model, {"params": key(1)}, image, motion, t, cond)
    assert "cond_embed" in params["params"]

    @jax.jit
    def run(p, c, keep):  # output and gradient in one compile
        def f(p):
            out = model.apply(p, image, motion, t, c, keep)
            return jnp.sum(out**2), out
        return jax.value_and_grad(f, has_aux=True)(p)

    uncond = jax.jit(lambda p: model.apply(p, image, motion, t))(params)
    (_, dropped), _ = run(params, cond, jnp.array([False, False]))
    (_, kept), _ = run(params, cond, jnp.array([True, True]))
    (_, mixed), g = run(params, cond, jnp.array([True, False]))
    np.testing.assert_allclose(dropped, uncond, atol=1e-5)  # masked tokens = no tokens
    assert not np.allclose(kept, uncond, atol=1e-4)
    np.testing.assert_allclose(mixed[0], kept[0], atol=1e-5)
    np.testing.assert_allclose(mixed[1], uncond[1], atol=1e-5)
    assert tree_finite(g) and tree_norm(g["params"]["cond_embed"]) > 0


def test_input_checks(den, inputs):
    model, params, fn = den
    image, motion, t = inputs
    feats = fn["encode_image"](params, image)

    def shape_of(*args, **kw):
        return jax.eval_shape(lambda: model.apply(params, *args, method="denoise", **kw))

    with pytest.raises(ValueError, match="motion_t"):
        shape_of(feats, motion[:, :50], t)
    with pytest.raises(ValueError, match="features"):
        shape_of(jnp.zeros((B, 8, 8, 3)), motion, t)
    with pytest.raises(ValueError, match="t must"):
        shape_of(feats, motion, jnp.zeros(3))
    with pytest.raises(ValueError, match="use_cond"):
        shape_of(feats, motion, t, cond=motion)


def test_input_skip_reads_the_exact_pixel_under_uv(inputs):
    """With input_skip the cache carries the input pixels: the token at a pixel centre sees that
    pixel's RGB (centred) and its depth in metres (standardised like z when motion stats exist)."""
    import dataclasses

    from readjax.sim.render import DEPTH_FAR, DEPTH_NEAR

    image, motion, t = inputs
    cfg = dataclasses.replace(TINY_DENOISER, input_skip=True)
    model = Denoiser(cfg)
    params = jit_init(model, {"params": key(4), "dropout": key(5)}, image, motion, t)
    feats = jitted(model, "encode_image")(params, image)
    assert feats.shape == (B, 8, 8, cfg.cache_channels) and cfg.cache_channels == TINY_DENOISER.conv_dims[0] + 64
    rows, cols = np.array([[3, 17], [30, 0]]), np.array([[5, 22], [9, 31]])
    uv = jnp.stack([(2 * cols + 1) / 32 - 1, (2 * rows + 1) / 32 - 1], -1).astype(jnp.float32)  # (B, 2, 2)
    got = jax.jit(lambda p, f, u: model.apply(p, f, u, method="input_at"))(params, feats, uv)
    px = np.asarray(image)[np.arange(B)[:, None], rows, cols]  # (B, 2, 4)
    np.testing.assert_allclose(got[..., :3], px[..., :3] - 0.5, atol=1e-6)
    np.testing.assert_allclose(got[..., 3], DEPTH_NEAR + (DEPTH_FAR - DEPTH_NEAR) * px[..., 3], atol=1e-5)
    stats = dataclasses.replace(cfg, motion_mean=(0.0, 0.0, 1.2) + (0.0,) * 7, motion_std=(1.0, 1.0, 0.1) + (1.0,) * 7)
    got_n = jax.jit(lambda p, f, u: Denoiser(stats).apply(p, f, u, method="input_at"))(params, feats, uv)
    np.testing.assert_allclose(got_n[..., 3], (got[..., 3] - 1.2) / 0.1, rtol=1e-5, atol=1e-5)
    # between pixel centres and beyond the border: bilinear samples of the full normalised image
    from readjax.models.denoiser import sample_features

    uv_any = jax.random.uniform(key(6), (B, 7, 2), minval=-1.1, maxval=1.1)
    full = jax.jit(lambda p, f: model.apply(p, f, method="_input_pixels"))(params, feats)
    np.testing.assert_allclose(jax.jit(lambda p, f, u: model.apply(p, f, u, method="input_at"))(params, feats, uv_any),
                               sample_features(full, uv_any), atol=1e-5)
    # the UNet's samples ignore the skip; the transformer's tokens (and so the denoiser) use it
    tracks = jax.jit(lambda p, f, u: model.apply(p, f, u, method="track_tokens"))(params, feats, uv)
    brighter_tracks = jax.jit(lambda p, f, u: model.apply(p, f, u, method="track_tokens"))(
        params, feats.at[..., TINY_DENOISER.conv_dims[0]:].add(0.1), uv)
    assert not np.allclose(tracks, brighter_tracks)
    np.testing.assert_allclose(jax.jit(lambda p, f, u: model.apply(p, f, u, method="image_tokens"))(params, feats, uv),
                               jax.jit(lambda p, f, u: model.apply(p, f[..., :16], u, method="image_tokens"))(
                                   params, feats, uv), atol=0)
    out = jitted(model, "denoise")(params, feats, motion, t)
    brighter = feats.at[..., TINY_DENOISER.conv_dims[0]:].add(0.1)
    assert out.shape == motion.shape and not np.allclose(out, jitted(model, "denoise")(params, brighter, motion, t))


def test_surface_depth_reads_z_beyond_the_visible_surface(inputs):
    """With surface_depth each motion token also embeds z - depth(uv): the frame's distance beyond
    the surface the image shows under it, in standardised-z units (metres without stats). Moving
    a frame and the whole depth image back by the same distance leaves that offset, and so the
    token, unchanged; moving the frame alone changes it."""
    import dataclasses

    from readjax.sim.render import DEPTH_FAR, DEPTH_NEAR

    image, motion, t = inputs
    with pytest.raises(ValueError, match="input_skip"):
        dataclasses.replace(TINY_DENOISER, surface_depth=True)
    stats = dict(motion_mean=(0.0, 0.0, 1.2) + (0.0,) * 7, motion_std=(1.0, 1.0, 0.1) + (1.0,) * 7)
    for extra in ({}, stats):
        cfg = dataclasses.replace(TINY_DENOISER, input_skip=True, surface_depth=True, **extra)
        model = Denoiser(cfg)
        params = jit_init(model, {"params": key(7), "dropout": key(8)}, image, motion, t)
        flat = image.at[..., 3].set(0.25)  # depth DEPTH_NEAR + 0.25 (FAR - NEAR) everywhere
        feats = jitted(model, "encode_image")(params, flat)
        pixels = jax.jit(lambda p, f, u: model.apply(p, f, u, method="input_at"))(params, feats, motion[..., :2])
        off = jax.jit(lambda p, m, px: model.apply(p, m, px, method="surface_offset"))(params, motion, pixels)
        metres = motion[..., 2:3] - (DEPTH_NEAR + 0.25 * (DEPTH_FAR - DEPTH_NEAR))
        np.testing.assert_allclose(off, metres / (0.1 if extra else 1.0), rtol=1e-4, atol=1e-4)
        back = jitted(model, "encode_image")(params, flat.at[..., 3].add(0.05 / (DEPTH_FAR - DEPTH_NEAR)))
        px_back = jax.jit(lambda p, f, u: model.apply(p, f, u, method="input_at"))(params, back, motion[..., :2])
        off_back = jax.jit(lambda p, m, px: model.apply(p, m, px, method="surface_offset"))(
            params, motion.at[..., 2].add(0.05), px_back)
        np.testing.assert_allclose(off_back, off, rtol=1e-4, atol=1e-4)
        out = jitted(model, "denoise")(params, feats, motion, t)
        moved = jitted(model, "denoise")(params, feats, motion.at[..., 2].add(0.05), t)
        assert out.shape == motion.shape and np.isfinite(out).all() and not np.allclose(out, moved)
        g = jax.grad(lambda m: jnp.sum(model.apply(params, feats, m, t, method="denoise")))(motion)
        assert np.isfinite(g).all()
