"""The pinhole camera model: intrinsics/extrinsics as data, world <-> camera <-> (u, v, z).

Conventions (OpenCV): the camera frame has x right, y down, z forward (optical axis).
(u, v) are pixel coordinates normalised to [-1, 1] over the image (u across, v down), z is
the depth along the optical axis in metres; p_cam = z * K^-1 [u_px, v_px, 1].
Pure jnp/numpy with no MuJoCo import, so the models and the motion format can use it;
:func:`readjax.sim.camera.camera_from_model` builds a :class:`CameraParams` from a MuJoCo camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

DEPTH_NEAR = 0.3  # metres; the fixed planes of the normalised depth channel
DEPTH_FAR = 2.5


@dataclass(frozen=True, eq=False)
class CameraParams:
    """A fixed camera: ``intrinsics`` (3, 3) in pixels, ``cam_to_world`` (4, 4), image size.

    Hashable by value, so jitted functions can be cached per camera.
    """

    intrinsics: np.ndarray
    cam_to_world: np.ndarray
    width: int
    height: int

    def _key(self):
        return (np.asarray(self.intrinsics, np.float64).round(9).tobytes(),
                np.asarray(self.cam_to_world, np.float64).round(9).tobytes(), int(self.width), int(self.height))

    def __hash__(self):
        return hash(self._key())

    def __eq__(self, other):
        return isinstance(other, CameraParams) and self._key() == other._key()

    @property
    def rotation(self) -> np.ndarray:
        """Camera-to-world rotation (columns: camera axes in world)."""
        return self.cam_to_world[:3, :3]

    @property
    def position(self) -> np.ndarray:
        return self.cam_to_world[:3, 3]

    def to_dict(self) -> dict:
        return {
            "intrinsics": np.asarray(self.intrinsics).tolist(),
            "cam_to_world": np.asarray(self.cam_to_world).tolist(),
            "width": int(self.width),
            "height": int(self.height),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "CameraParams":
        return cls(np.asarray(d["intrinsics"], np.float64), np.asarray(d["cam_to_world"], np.float64),
                   int(d["width"]), int(d["height"]))


def world_to_camera(cam: CameraParams, p_world: jax.Array) -> jax.Array:
    r = jnp.asarray(cam.rotation, jnp.float32)
    return jnp.einsum("ji,...j->...i", r, p_world - jnp.asarray(cam.position, jnp.float32))


def camera_to_world(cam: CameraParams, p_cam: jax.Array) -> jax.Array:
    r = jnp.asarray(cam.rotation, jnp.float32)
    return jnp.einsum("ij,...j->...i", r, p_cam) + jnp.asarray(cam.position, jnp.float32)


def rotation_to_camera(cam: CameraParams, r_world: jax.Array) -> jax.Array:
    """A world-frame orientation expressed in the camera frame."""
    return jnp.asarray(cam.rotation.T, jnp.float32) @ r_world


def rotation_to_world(cam: CameraParams, r_cam: jax.Array) -> jax.Array:
    return jnp.asarray(cam.rotation, jnp.float32) @ r_cam


def project_uvz(cam: CameraParams, p_world: jax.Array) -> jax.Array:
    """World points (..., 3) -> (u, v, z) with u, v normalised to [-1, 1] (..., 3)."""
    pc = world_to_camera(cam, p_world)
    k = cam.intrinsics
    z = pc[..., 2]
    u_px = k[0, 0] * pc[..., 0] / z + k[0, 2]
    v_px = k[1, 1] * pc[..., 1] / z + k[1, 2]
    return jnp.stack([2 * u_px / cam.width - 1, 2 * v_px / cam.height - 1, z], axis=-1)


def unproject_uvz(cam: CameraParams, uvz: jax.Array) -> jax.Array:
    """Inverse of :func:`project_uvz`: (u, v, z) (..., 3) -> world points (..., 3)."""
    k = cam.intrinsics
    u_px = (uvz[..., 0] + 1) * cam.width / 2
    v_px = (uvz[..., 1] + 1) * cam.height / 2
    z = uvz[..., 2]
    pc = jnp.stack([(u_px - k[0, 2]) / k[0, 0] * z, (v_px - k[1, 2]) / k[1, 1] * z, z], axis=-1)
    return camera_to_world(cam, pc)
