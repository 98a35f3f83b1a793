"""Pictures people would rather look at than read: first frames, labelled grids, demo videos,
motion overlays on the input image, loss curves."""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image, ImageDraw

from readjax.data.generate import episode_fn
from readjax.sim.reference import replay
from readjax.prng import seed_pure
from readjax.sim.render import SceneRenderer


def first_frame(env, seed: int, size: int = 192) -> np.ndarray:
    """RGB (size, size, 3) uint8 of a task's first frame for ``seed``."""
    scene = env.sample_scene(jax.random.key(seed))
    with SceneRenderer(env.mj_model, size, size) as r:
        r.set_state(scene.qpos, scene.mocap_pos, scene.mocap_quat, env.recolour_ids, scene.rgba)
        rgb, _ = r.render(depth=False)
    return rgb


def first_frames(env, seeds, size: int = 192) -> list[np.ndarray]:
    """RGB (size, size, 3) uint8 first frames of a task for several ``seeds`` (their scenes sampled in
    one batch: a scene is a function of its seed alone, so each equals ``first_frame(env, seed)``)."""
    seeds = jnp.asarray(list(seeds), jnp.int32)
    scenes = jax.jit(jax.vmap(lambda s: env.sample_scene(seed_pure(s))))(seeds)
    frames = []
    with SceneRenderer(env.mj_model, size, size) as r:
        for i in range(len(seeds)):
            scene = jax.tree.map(lambda x: np.asarray(x)[i], scenes)
            r.set_state(scene.qpos, scene.mocap_pos, scene.mocap_quat, env.recolour_ids, scene.rgba)
            frames.append(r.render(depth=False)[0])
    return frames


def expert_video(env, seed: int, size: int = 192, every: int = 2) -> list[np.ndarray]:
    """Frames of the expert demonstration for ``seed``: the MJX rollout replayed in C MuJoCo."""
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


def motion_overlay(images: np.ndarray, layers: list[tuple[str, np.ndarray, tuple]], path: str | Path,
                   titles: list[str] | None = None, scale: int = 4) -> None:
    """Draw motions' uv paths over their input images (the paper's Figure 13).

    ``images`` (B, H, W, 4) RGB-D in [0, 1]; ``layers``: (label, motions (B, 101, 10), RGB colour).
    A filled dot marks the frames where the gripper is closed.
    """
    tiles = []
    for b in range(len(images)):
        rgb = (np.clip(images[b, ..., :3], 0, 1) * 255).astype(np.uint8)
        img = Image.fromarray(rgb).resize((rgb.shape[1] * scale, rgb.shape[0] * scale), Image.NEAREST)
        draw = ImageDraw.Draw(img)
        w, h = img.size
        for label, motions, colour in layers:
            uv = np.asarray(motions[b][:, :2])
            pts = [((u + 1) * w / 2, (v + 1) * h / 2) for u, v in uv]
            draw.line(pts, fill=colour, width=2)
            for (x, y), g in zip(pts[::4], np.asarray(motions[b][::4, 9])):
                if g < 0.5:
                    draw.ellipse([x - 2, y - 2, x + 2, y + 2], fill=colour)
        if titles:
            draw.text((4, 4), titles[b], fill=(255, 255, 255))
        tiles.append(np.asarray(img))
    legend_h = 16
    grid = label_grid(tiles, [""] * len(tiles), cols=min(4, len(tiles)))
    canvas = Image.new("RGB", (grid.width, grid.height + legend_h), (255, 255, 255))
    canvas.paste(grid, (0, legend_h))
    draw = ImageDraw.Draw(canvas)
    x = 4
    for label, _, colour in layers:
        draw.rectangle([x, 4, x + 10, 12], fill=colour)
        draw.text((x + 14, 2), label, fill=(0, 0, 0))
        x += 14 + 7 * len(label) + 16
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    canvas.save(path)


def rollout_video(env, scenes, traces, size: int = 160, every: int = 2, max_episodes: int = 4) -> list[np.ndarray]:
    """Side-by-side frames of executed rollouts (replayed in C MuJoCo from their recorded controls)."""
    n = min(max_episodes, len(np.asarray(scenes.qpos)))
    per_episode = []
    with SceneRenderer(env.mj_model, size, size) as r:
        for i in range(n):
            sc = jax.tree.map(lambda x: np.asarray(x)[i], scenes)
            tr = jax.tree.map(lambda x: np.asarray(x)[i], traces)
            frames = []
            r.set_state(sc.qpos, sc.mocap_pos, sc.mocap_quat, env.recolour_ids, sc.rgba)
            frames.append(r.render(depth=False)[0])
            replay(env, sc, tr, on_step=lambda k, d: frames.append(r.render_data(d)) if k % every == 0 else None)
            per_episode.append(frames)
    length = max(len(f) for f in per_episode)
    return [np.concatenate([f[min(t, len(f) - 1)] for f in per_episode], axis=1) for t in range(length)]
