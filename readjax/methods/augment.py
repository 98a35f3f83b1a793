"""RGB augmentation for training the image-conditioned models (METHOD.md section 6).

Applied inside the jitted train step to the RGB channels only (depth is left as measured):
Gaussian noise, brightness, a 3x3 blur and pixel dropout, each with its own probability. The
paper also uses JPEG artefacts; there is no jittable JPEG codec in JAX, so it is left out.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def augment_rgb(key: jax.Array, images: jax.Array, p: float = 0.5) -> jax.Array:
    """images (B, H, W, 4) in [0, 1] -> augmented copy (RGB only), per-sample random choices."""
    with jax.named_scope("augment"):  # profiles attribute its ops (experiments.bench train)
        return _augment_rgb(key, images, p)


def _augment_rgb(key: jax.Array, images: jax.Array, p: float) -> jax.Array:
    b = images.shape[0]
    k_sel, k_noise, k_bright, k_drop = jax.random.split(key, 4)
    use = jax.random.uniform(k_sel, (4, b)) < p
    rgb, depth = images[..., :3], images[..., 3:]
    sel = lambda i, a, x: jnp.where(use[i][:, None, None, None], a, x)  # noqa: E731
    rgb = sel(0, rgb + 0.03 * jax.random.normal(k_noise, rgb.shape), rgb)
    scale = jax.random.uniform(k_bright, (b, 1, 1, 1), minval=0.75, maxval=1.25)
    rgb = sel(1, rgb * scale, rgb)
    padded = jnp.pad(rgb, ((0, 0), (1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = rgb.shape[1:3]
    blur = sum(padded[:, i:i + h, j:j + w] for i in range(3) for j in range(3)) / 9.0
    rgb = sel(2, blur, rgb)
    keep = jax.random.uniform(k_drop, rgb.shape[:3] + (1,)) > 0.03
    rgb = sel(3, rgb * keep, rgb)
    return jnp.concatenate([jnp.clip(rgb, 0.0, 1.0), depth], axis=-1)
