"""Stretching a demonstration of any length to [0, 1] and resampling it (METHOD.md section 2).

Frame i of a T-frame recording sits at time i / (T - 1). Positions (u, v, z) and joint angles
use cubic splines (not-a-knot), orientation a rotation spline, the gripper linear
interpolation. Host-side numpy/scipy: it runs once per demonstration at generation time.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

from readjax.motion import FRAMES


def resample_times(n_in: int, n_out: int = FRAMES) -> tuple[np.ndarray, np.ndarray]:
    if n_in < 2:
        raise ValueError(f"a trajectory needs at least 2 frames to resample, got {n_in}")
    return np.linspace(0.0, 1.0, n_in), np.linspace(0.0, 1.0, n_out)


def resample_cubic(x: np.ndarray, n_out: int = FRAMES) -> np.ndarray:
    """(T, D) -> (n_out, D) with a cubic spline over normalised time."""
    t_in, t_out = resample_times(len(x), n_out)
    return CubicSpline(t_in, np.asarray(x, np.float64), axis=0)(t_out)


def resample_linear(x: np.ndarray, n_out: int = FRAMES) -> np.ndarray:
    t_in, t_out = resample_times(len(x), n_out)
    x = np.asarray(x, np.float64)
    if x.ndim == 1:
        return np.interp(t_out, t_in, x)
    return np.stack([np.interp(t_out, t_in, x[:, k]) for k in range(x.shape[1])], axis=1)


def resample_rotations(rot: np.ndarray, n_out: int = FRAMES) -> np.ndarray:
    """(T, 3, 3) rotation matrices -> (n_out, 3, 3) with a C2 rotation spline."""
    t_in, t_out = resample_times(len(rot), n_out)
    return RotationSpline(t_in, Rotation.from_matrix(np.asarray(rot, np.float64)))(t_out).as_matrix()


def resample_demo(uvz: np.ndarray, rot: np.ndarray, grip: np.ndarray, joints: np.ndarray,
                  n_out: int = FRAMES) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Resample one recorded demonstration (camera-frame uvz, rotations, grip, joints)."""
    return (
        resample_cubic(uvz, n_out).astype(np.float32),
        resample_rotations(rot, n_out).astype(np.float32),
        np.clip(resample_linear(grip, n_out), 0.0, 1.0).astype(np.float32),
        resample_cubic(joints, n_out).astype(np.float32),
    )
