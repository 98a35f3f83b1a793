"""Rotations and rigid transforms in jnp (quaternions are MuJoCo's w, x, y, z order).

Everything works on arbitrary leading batch dimensions and is differentiable.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def quat_to_mat(q: jax.Array) -> jax.Array:
    """Unit quaternion (..., 4) -> rotation matrix (..., 3, 3)."""
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    r = jnp.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    )
    return r.reshape(q.shape[:-1] + (3, 3))


def mat_to_quat(r: jax.Array) -> jax.Array:
    """Rotation matrix (..., 3, 3) -> unit quaternion (..., 4) with w >= 0 (branch-free)."""
    m = r
    t = jnp.stack(
        [
            1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
            1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
        ],
        axis=-1,
    )
    # Four candidate quaternions, each accurate when its leading component is large.
    cands = jnp.stack(
        [
            jnp.stack([t[..., 0], m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),
            jnp.stack([m[..., 2, 1] - m[..., 1, 2], t[..., 1], m[..., 1, 0] + m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0]], -1),
            jnp.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] + m[..., 0, 1], t[..., 2], m[..., 2, 1] + m[..., 1, 2]], -1),
            jnp.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 2, 1] + m[..., 1, 2], t[..., 3]], -1),
        ],
        axis=-2,
    )
    best = jnp.argmax(t, axis=-1)
    q = jnp.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    return q * jnp.where(q[..., :1] < 0, -1.0, 1.0)


def quat_mul(a: jax.Array, b: jax.Array) -> jax.Array:
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return jnp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conj(q: jax.Array) -> jax.Array:
    return q * jnp.array([1.0, -1.0, -1.0, -1.0], q.dtype)


def axis_angle_to_quat(axis: jax.Array, angle: jax.Array) -> jax.Array:
    axis = axis / jnp.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * jnp.asarray(angle)[..., None]
    return jnp.concatenate([jnp.cos(half), jnp.sin(half) * axis], axis=-1)


def yaw_quat(yaw: jax.Array) -> jax.Array:
    """Rotation about the world z axis."""
    yaw = jnp.asarray(yaw)
    z = jnp.zeros_like(yaw)
    return jnp.stack([jnp.cos(yaw / 2), z, z, jnp.sin(yaw / 2)], axis=-1)


def rot_z(angle: jax.Array) -> jax.Array:
    c, s = jnp.cos(angle), jnp.sin(angle)
    z, o = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack([c, -s, z, s, c, z, z, z, o], axis=-1).reshape(jnp.shape(angle) + (3, 3))


def slerp(q0: jax.Array, q1: jax.Array, t: jax.Array) -> jax.Array:
    """Spherical interpolation along the shorter arc; t broadcast against the batch."""
    t = jnp.asarray(t)[..., None]
    dot = jnp.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = jnp.where(dot < 0, -q1, q1)
    dot = jnp.abs(dot)
    theta = jnp.arccos(jnp.clip(dot, -1.0, 1.0))
    sin_t = jnp.sin(theta)
    small = sin_t < 1e-4
    safe = jnp.where(small, 1.0, sin_t)
    w0 = jnp.where(small, 1 - t, jnp.sin((1 - t) * theta) / safe)
    w1 = jnp.where(small, t, jnp.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def rotation_error(r_target: jax.Array, r_current: jax.Array) -> jax.Array:
    """World-frame rotation vector that rotates ``r_current`` onto ``r_target`` (..., 3)."""
    r = r_target @ jnp.swapaxes(r_current, -1, -2)
    return mat_to_rotvec(r)


def mat_to_rotvec(r: jax.Array) -> jax.Array:
    q = mat_to_quat(r)
    v = q[..., 1:]
    s = jnp.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2 * jnp.arctan2(s, q[..., :1])
    scale = jnp.where(s > 1e-8, angle / jnp.where(s > 1e-8, s, 1.0), 2.0)
    return v * scale


def rotation_angle(r_a: jax.Array, r_b: jax.Array) -> jax.Array:
    """Geodesic angle between two rotations (radians)."""
    r = r_a @ jnp.swapaxes(r_b, -1, -2)
    c = (jnp.trace(r, axis1=-2, axis2=-1) - 1) / 2
    return jnp.arccos(jnp.clip(c, -1.0, 1.0))


def rot6d_from_mat(r: jax.Array) -> jax.Array:
    """First two rows of the rotation matrix, flattened (..., 6) (METHOD.md section 2)."""
    return r[..., :2, :].reshape(r.shape[:-2] + (6,))


def mat_from_rot6d(x: jax.Array) -> jax.Array:
    """Gram-Schmidt back to a proper rotation (rows r1, r2, r1 x r2)."""
    a, b = x[..., :3], x[..., 3:6]
    r1 = a / jnp.maximum(jnp.linalg.norm(a, axis=-1, keepdims=True), 1e-8)
    b = b - jnp.sum(r1 * b, axis=-1, keepdims=True) * r1
    r2 = b / jnp.maximum(jnp.linalg.norm(b, axis=-1, keepdims=True), 1e-8)
    r3 = jnp.cross(r1, r2)
    return jnp.stack([r1, r2, r3], axis=-2)


def transform_points(rot: jax.Array, pos: jax.Array, p: jax.Array) -> jax.Array:
    """Apply x -> rot x + pos to points p (..., 3)."""
    return jnp.einsum("...ij,...j->...i", rot, p) + pos
