"""Offscreen RGB-D rendering of a scene's first frame with C MuJoCo (EGL/OSMesa).

MJX has no CPU renderer, so the first frame is drawn by ``mujoco.Renderer`` from the episode's
initial state. Shadows, reflections and the skybox are off (~40 ms instead of ~300 ms per
frame on the CPU). Depth is returned in metres and normalised to [0, 1] between fixed planes
(:data:`DEPTH_NEAR`, :data:`DEPTH_FAR`) as METHOD.md section 3 prescribes.
"""

from __future__ import annotations

import mujoco
import numpy as np

from readjax.camera import DEPTH_FAR, DEPTH_NEAR  # the depth planes live with the camera model


def normalise_depth(depth_m: np.ndarray) -> np.ndarray:
    return np.clip((depth_m - DEPTH_NEAR) / (DEPTH_FAR - DEPTH_NEAR), 0.0, 1.0).astype(np.float32)


class SceneRenderer:
    """Renders RGB-D images of a model's named camera; create once, reuse, close."""

    def __init__(self, model: mujoco.MjModel, width: int = 256, height: int = 256, camera: str = "front"):
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(
                f"{width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
            )
        self.model = model
        self.data = mujoco.MjData(model)
        self.camera = camera
        self.width, self.height = width, height
        self._rgba0 = model.geom_rgba.copy()
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        flags = self._renderer.scene.flags
        for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                     mujoco.mjtRndFlag.mjRND_SKYBOX):
            flags[flag] = False
        self._options = mujoco.MjvOption()

    def set_state(self, qpos, mocap_pos=None, mocap_quat=None, geom_ids=(), rgba=None) -> None:
        self.data.qpos[:] = np.asarray(qpos)
        if self.model.nmocap:
            self.data.mocap_pos[:] = np.asarray(mocap_pos).reshape(-1, 3)
            self.data.mocap_quat[:] = np.asarray(mocap_quat).reshape(-1, 4)
        self.model.geom_rgba[:] = self._rgba0
        if len(geom_ids):
            self.model.geom_rgba[np.asarray(geom_ids)] = np.asarray(rgba).reshape(-1, 4)
        mujoco.mj_forward(self.model, self.data)

    def render_data(self, data: mujoco.MjData) -> np.ndarray:
        """RGB of another MjData of the same model (e.g. a replay in progress)."""
        self._renderer.update_scene(data, camera=self.camera, scene_option=self._options)
        return self._renderer.render().copy()

    def render(self, depth: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """RGB uint8 (H, W, 3) and depth in metres (H, W) of the current state."""
        self._renderer.disable_depth_rendering()
        self._renderer.update_scene(self.data, camera=self.camera, scene_option=self._options)
        rgb = self._renderer.render().copy()
        d = None
        if depth:
            self._renderer.enable_depth_rendering()
            self._renderer.update_scene(self.data, camera=self.camera, scene_option=self._options)
            d = self._renderer.render().copy()
            self._renderer.disable_depth_rendering()
        return rgb, d

    def rgbd(self) -> np.ndarray:
        """(H, W, 4) float32: RGB in [0, 1] and normalised depth."""
        rgb, d = self.render(depth=True)
        return np.concatenate([rgb.astype(np.float32) / 255.0, normalise_depth(d)[..., None]], axis=-1)

    def close(self) -> None:
        if self._renderer is not None:
            self.model.geom_rgba[:] = self._rgba0
            self._renderer.close()
            self._renderer = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def render_scenes(renderer: SceneRenderer, env, scenes) -> tuple[np.ndarray, np.ndarray]:
    """First frames of a batch of scenes (leaves (B, ...)): RGB (B, H, W, 3) uint8 and normalised
    depth (B, H, W) float32, exactly as datasets store them."""
    rgb, depth = [], []
    qpos, mpos, mquat, rgba = (np.asarray(x) for x in (scenes.qpos, scenes.mocap_pos, scenes.mocap_quat,
                                                       scenes.rgba))
    for b in range(len(qpos)):
        renderer.set_state(qpos[b], mpos[b], mquat[b], env.recolour_ids, rgba[b])
        c, d = renderer.render(depth=True)
        rgb.append(c)
        depth.append(normalise_depth(d))
    return np.stack(rgb), np.stack(depth)
