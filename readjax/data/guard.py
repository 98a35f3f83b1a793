"""The scene guard: before a plan is executed, prove its scene is the one its image shows.

Evaluation plans from a stored image and executes in a stored scene. If the two ever disagree
(a scene re-sampled from its seed under a batch-dependent PRNG did, for two thirds of the test
episodes before dataset format 2), every success rate is wrong while nothing crashes. So each
scene's first frame is re-rendered and compared with the image: the largest absolute difference
must stay within ``RGB_TOL`` on RGB and ``DEPTH_TOL`` on normalised depth, or evaluation stops
with an error naming the episodes. The check is always on; it costs one render per episode.
"""

from __future__ import annotations

import numpy as np

from readjax.data.store import Dataset, DatasetError, resize_images
from readjax.sim.render import SceneRenderer, render_scenes

RGB_TOL = 2 / 255  # max abs difference, RGB in [0, 1]
DEPTH_TOL = 2 / 255  # max abs difference, depth normalised to [0, 1] (~1.7 cm)


class SceneMismatchError(DatasetError):
    """Stored scenes that do not render to the images the plans were made from."""


def scene_image_errors(env, ds: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Per episode, the max abs RGB and depth difference between its re-rendered scene and its
    image. Scenes render at the size the dataset was generated at, then shrink like the images."""
    size = int(ds.meta.get("image_size", ds.image_size))
    with SceneRenderer(env.mj_model, size, size, ds.meta.get("camera_name", "front")) as renderer:
        rgb, depth = render_scenes(renderer, env, ds.scenes)
    rendered = np.concatenate([rgb.astype(np.float32) / 255.0, depth[..., None]], -1)
    rendered = resize_images(rendered, ds.image_size)
    diff = np.abs(rendered - ds.rgbd)
    return diff[..., :3].max(axis=(1, 2, 3)), diff[..., 3].max(axis=(1, 2))


def check_scene_images(env, ds: Dataset, rgb_tol: float = RGB_TOL, depth_tol: float = DEPTH_TOL) -> None:
    """Raise :class:`SceneMismatchError` naming every episode whose scene is not its image."""
    if len(ds) == 0:
        return
    if ds.scenes is None:
        raise SceneMismatchError(f"{ds.task}/{ds.split}: the dataset holds no scenes to execute plans in")
    rgb_err, depth_err = scene_image_errors(env, ds)
    bad = np.flatnonzero((rgb_err > rgb_tol) | (depth_err > depth_tol))
    if len(bad):
        shown = ", ".join(f"#{i} (seed {ds.seeds[i]}: RGB {rgb_err[i] * 255:.0f}/255, depth "
                          f"{depth_err[i] * 255:.1f}/255)" for i in bad[:8])
        more = f" and {len(bad) - 8} more" if len(bad) > 8 else ""
        raise SceneMismatchError(
            f"{ds.task}/{ds.split}: {len(bad)} of {len(ds)} stored scenes do not render to their images "
            f"(tolerance RGB {rgb_tol * 255:.0f}/255, depth {depth_tol * 255:.0f}/255): {shown}{more}; "
            f"the dataset is inconsistent, regenerate it")
