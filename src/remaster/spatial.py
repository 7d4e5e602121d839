"""Rigid transforms: rotations, homogeneous matrices and Euler angles (SI units, radians).

All functions broadcast over leading dimensions: an angle array of shape (...,) gives
matrices of shape (..., 3, 3) or (..., 4, 4).
"""

from __future__ import annotations

import numpy as np


def _plane_rotation(angle, first: int, second: int) -> np.ndarray:
    """Rotations (..., 3, 3) by `angle` (...,) in the plane of axes `first` -> `second`, filled in
    place: nested np.stack calls cost more than the arithmetic on a sampler's hot path."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(np.shape(c) + (3, 3))
    out[..., 3 - first - second, 3 - first - second] = 1.0
    out[..., first, first] = c
    out[..., second, second] = c
    out[..., first, second] = -s
    out[..., second, first] = s
    return out


def rot_x(angle) -> np.ndarray:
    """Rotation about X, shape (..., 3, 3)."""
    return _plane_rotation(angle, 1, 2)


def rot_y(angle) -> np.ndarray:
    """Rotation about Y, shape (..., 3, 3)."""
    return _plane_rotation(angle, 2, 0)


def rot_z(angle) -> np.ndarray:
    """Rotation about Z, shape (..., 3, 3)."""
    return _plane_rotation(angle, 0, 1)


def skew(v) -> np.ndarray:
    """Cross-product matrix K with K @ x = v x x, shape (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    zero = np.zeros_like(v[..., 0])
    return np.stack(
        [
            np.stack([zero, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], zero, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], zero], -1),
        ],
        -2,
    )


def rot_axis(axis, angle) -> np.ndarray:
    """Rotation by `angle` about the unit vector `axis` (Rodrigues), shape (..., 3, 3)."""
    axis = np.asarray(axis, dtype=float)
    k = skew(axis)
    angle = np.asarray(angle, dtype=float)[..., None, None]
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def rotation_vector_to_matrix(vector) -> np.ndarray:
    """Rotation exp([phi]x) of rotation vectors phi (..., 3) rad: the angle |phi| about phi's
    direction (Rodrigues), shape (..., 3, 3); the identity for phi = 0."""
    vector = np.asarray(vector, dtype=float)
    angle = np.linalg.norm(vector, axis=-1)
    k = skew(vector)
    # sin(a)/a and (1 - cos a)/a^2 by their series below 1e-4 rad, where the quotients lose digits
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    first = np.where(small, 1.0 - angle**2 / 6.0, np.sin(safe) / safe)
    second = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + first[..., None, None] * k + second[..., None, None] * (k @ k)


def matrix_to_rotation_vector(rotation) -> np.ndarray:
    """Rotation vectors (..., 3) rad of rotations (..., 3, 3) turning by less than pi: the inverse
    of `rotation_vector_to_matrix`."""
    rotation = np.asarray(rotation, dtype=float)
    v = 0.5 * np.stack(
        [
            rotation[..., 2, 1] - rotation[..., 1, 2],
            rotation[..., 0, 2] - rotation[..., 2, 0],
            rotation[..., 1, 0] - rotation[..., 0, 1],
        ],
        axis=-1,
    )  # sin(angle) times the axis
    sine = np.linalg.norm(v, axis=-1)
    angle = np.arctan2(sine, 0.5 * (np.trace(rotation, axis1=-2, axis2=-1) - 1.0))
    ratio = np.where(sine < 1e-8, 1.0 + angle**2 / 6.0, angle / np.where(sine < 1e-8, 1.0, sine))
    return ratio[..., None] * v


def euler_zyx_to_matrix(yaw, pitch, roll) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), the ZYX convention of the paper, shape (..., 3, 3)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_to_euler_zyx(rotation) -> np.ndarray:
    """Inverse of `euler_zyx_to_matrix`: (..., 3) array of (yaw, pitch, roll) in rad.

    Pitch lies in [-pi/2, pi/2]; at pitch = +-pi/2 (gimbal lock) roll is set to 0.
    """
    r = np.asarray(rotation, dtype=float)
    pitch = np.arcsin(np.clip(-r[..., 2, 0], -1.0, 1.0))
    locked = np.abs(r[..., 2, 0]) > 1.0 - 1e-12
    yaw = np.where(locked, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    roll = np.where(locked, 0.0, np.arctan2(r[..., 2, 1], r[..., 2, 2]))
    return np.stack([yaw, pitch, roll], -1)


def rpy_to_matrix(roll, pitch, yaw) -> np.ndarray:
    """URDF's fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return euler_zyx_to_matrix(yaw, pitch, roll)


def homogeneous(rotation=None, translation=None) -> np.ndarray:
    """4x4 homogeneous transform(s) from a rotation (..., 3, 3) and a translation (..., 3)."""
    rotation = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    translation = np.zeros(3) if translation is None else np.asarray(translation, dtype=float)
    shape = np.broadcast_shapes(rotation.shape[:-2], translation.shape[:-1])
    t = np.zeros(shape + (4, 4))
    t[..., :3, :3] = rotation
    t[..., :3, 3] = translation
    t[..., 3, 3] = 1.0
    return t


def rotation_angle(rotation) -> float:
    """Angle (rad) of a rotation matrix (3, 3), accurate near 0 (unlike arccos of the trace)."""
    rotation = np.asarray(rotation, dtype=float)
    skew = rotation - rotation.T
    sine = np.linalg.norm([skew[2, 1], skew[0, 2], skew[1, 0]]) / 2.0
    return float(np.arctan2(sine, (np.trace(rotation) - 1.0) / 2.0))


def invert(transform) -> np.ndarray:
    """Inverse of rigid homogeneous transform(s), (..., 4, 4)."""
    t = np.asarray(transform, dtype=float)
    r_t = np.swapaxes(t[..., :3, :3], -1, -2)
    return homogeneous(r_t, -(r_t @ t[..., :3, 3, None])[..., 0])


def translation(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    """Pure translation, 4x4."""
    return homogeneous(None, np.array([x, y, z], dtype=float))


def transform_points(transform, points) -> np.ndarray:
    """Apply transform(s) (..., 4, 4) to points (..., 3)."""
    t = np.asarray(transform, dtype=float)
    p = np.asarray(points, dtype=float)
    return (t[..., :3, :3] @ p[..., None])[..., 0] + t[..., :3, 3]
