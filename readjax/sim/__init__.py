"""Simulation core: MJX scenes, kinematics, IK, control, grasping, camera, rendering."""

import contextlib
import io

import readjax  # noqa: F401  (XLA flags before jax/mujoco.mjx are imported)

with contextlib.redirect_stdout(io.StringIO()):
    # mujoco.mjx prints two harmless "Failed to import warp" lines on import.
    from mujoco import mjx  # noqa: F401
