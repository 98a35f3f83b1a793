"""Camera model: (u, v, z) projection round trip, and agreement with the rendered image."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import tasks
from readjax.sim import camera as cam_lib
from readjax.sim.render import DEPTH_FAR, DEPTH_NEAR, SceneRenderer, normalise_depth


def test_uvz_round_trip():
    env = tasks.make("reach_target")
    cam = cam_lib.camera_from_model(env.mj_model, "front", 96, 96)
    pts = jax.random.uniform(jax.random.key(0), (500, 3), minval=jnp.array([0.2, -0.4, 0.0]),
                             maxval=jnp.array([0.8, 0.4, 0.6]))
    uvz = cam_lib.project_uvz(cam, pts)
    assert np.all(np.abs(np.asarray(uvz[:, :2])) < 1.2) and np.all(np.asarray(uvz[:, 2]) > 0.3)
    np.testing.assert_allclose(np.asarray(cam_lib.unproject_uvz(cam, uvz)), np.asarray(pts), atol=1e-5)


def test_params_serialise():
    env = tasks.make("reach_target")
    cam = cam_lib.camera_from_model(env.mj_model, "front", 64, 64)
    back = cam_lib.CameraParams.from_dict(cam.to_dict())
    np.testing.assert_allclose(back.intrinsics, cam.intrinsics)
    np.testing.assert_allclose(back.cam_to_world, cam.cam_to_world)


def test_projection_matches_rendered_pixels_and_depth():
    """The red target's projected (u, v, z) is where the renderer draws it."""
    env = tasks.make("reach_target")
    size = 128
    cam = cam_lib.camera_from_model(env.mj_model, "front", size, size)
    scene = env.sample_scene(jax.random.key(1))
    target = np.asarray(scene.mocap_pos[env.target_mocap])
    with SceneRenderer(env.mj_model, size, size) as r:
        r.set_state(scene.qpos, scene.mocap_pos, scene.mocap_quat, env.recolour_ids, scene.rgba)
        rgb, depth = r.render()
    red = (rgb[..., 0] > 180) & (rgb[..., 1] < 60) & (rgb[..., 2] < 60)
    assert red.sum() > 5
    v_px, u_px = np.nonzero(red)
    u, v, z = np.asarray(cam_lib.project_uvz(cam, jnp.asarray(target)))
    assert abs((u_px.mean() + 0.5) / size * 2 - 1 - u) < 0.03
    assert abs((v_px.mean() + 0.5) / size * 2 - 1 - v) < 0.03
    # the nearest red pixel's depth is the sphere's near surface: the centre depth minus ~its radius
    assert abs(depth[red].min() - (z - 0.03)) < 0.01
    d01 = normalise_depth(depth)
    assert d01.min() >= 0 and d01.max() <= 1 and DEPTH_NEAR < depth.min() < DEPTH_FAR
