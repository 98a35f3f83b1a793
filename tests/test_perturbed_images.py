"""Table 9's perturbed test images: a function of each episode's own seed, whatever the subset."""

from __future__ import annotations

import numpy as np

from readjax.evaluation import EvalConfig, perturb_images


def _images(n=4):
    rng = np.random.default_rng(0)
    rgbd = rng.uniform(size=(n, 8, 8, 4)).astype(np.float32)
    return rgbd, np.arange(1000, 1000 + n)


def test_clean_images_pass_through():
    rgbd, seeds = _images()
    assert perturb_images(rgbd, EvalConfig(), 0, seeds) is rgbd


def test_an_episodes_noise_depends_on_its_seed_not_its_company():
    rgbd, seeds = _images()
    cfg = EvalConfig(image_noise=0.1, brightness=0.7)
    together = perturb_images(rgbd, cfg, 0, seeds)
    alone = perturb_images(rgbd[[2]], cfg, 0, seeds[[2]])
    np.testing.assert_array_equal(together[2], alone[0])
    reordered = perturb_images(rgbd[::-1], cfg, 0, seeds[::-1])
    np.testing.assert_array_equal(together, reordered[::-1])
    assert not np.array_equal(perturb_images(rgbd, cfg, 1, seeds), together)  # the evaluation's seed matters
    np.testing.assert_array_equal(together[..., 3], rgbd[..., 3])  # depth untouched
    assert together.dtype == np.float32 and together.min() >= 0 and together.max() <= 1


def test_brightness_alone_scales_and_clips():
    rgbd, seeds = _images()
    out = perturb_images(rgbd, EvalConfig(brightness=1.5), 0, seeds)
    np.testing.assert_allclose(out[..., :3], np.clip(rgbd[..., :3] * 1.5, 0, 1), rtol=1e-6)
