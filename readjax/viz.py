"""Pictures people would rather look at than read: first frames, labelled grids, demo videos,
motion overlays on the input image, loss curves."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image, ImageDraw

from readjax.sim.render import SceneRenderer


def first_frame(env, seed: int, size: int = 192) -> np.ndarray:
    """RGB (size, size, 3) uint8 of a task's first frame for ``seed``."""
    scene = env.sample_scene(jax.random.key(seed))
    with SceneRenderer(env.mj_model, size, size) as r:
        r.set_state(scene.qpos, scene.mocap_pos, scene.mocap_quat, env.recolour_ids, scene.rgba)
        rgb, _ = r.render(depth=False)
    return rgb


def expert_video(env, seed: int, size: int = 192, every: int = 2) -> list[np.ndarray]:
    """Frames of the expert demonstration for ``seed``: the MJX rollout replayed in C MuJoCo."""
    from readjax.data.generate import episode_fn
    from readjax.sim.reference import replay

    scenes, _, _, trace = episode_fn(env)(jnp.arange(2, dtype=jnp.int32) + seed)
    scene = jax.tree.map(lambda x: np.asarray(x)[0], scenes)
    tr = jax.tree.map(lambda x: np.asarray(x)[0], trace)
    frames = []
    with SceneRenderer(env.mj_model, size, size) as r:
        r.set_state(scene.qpos, scene.mocap_pos, scene.mocap_quat, env.recolour_ids, scene.rgba)
        frames.append(r.render(depth=False)[0])

        def grab(k, data):
            if k % every == 0:
                frames.append(r.render_data(data))

        replay(env, scene, tr, on_step=grab)
    return frames


def save_video(path: str | Path, frames: list[np.ndarray], fps: int = 25) -> None:
    import imageio.v2 as imageio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".gif":
        imageio.mimsave(path, frames, duration=1000 / fps, loop=0)
    else:
        imageio.mimsave(path, frames, fps=fps, macro_block_size=1)


def label_grid(images: list[np.ndarray], labels: list[str], cols: int = 4) -> Image.Image:
    """Images in a grid with a caption bar under each."""
    h, w = images[0].shape[:2]
    bar = 18
    rows = -(-len(images) // cols)
    canvas = Image.new("RGB", (cols * w, rows * (h + bar)), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    for i, (img, label) in enumerate(zip(images, labels)):
        x, y = (i % cols) * w, (i // cols) * (h + bar)
        canvas.paste(Image.fromarray(img), (x, y))
        draw.text((x + 4, y + h + 3), label, fill=(0, 0, 0))
    return canvas
