# SPDX-License-Identifier: Apache-2.0
"""Rotations in skynav's conventions, for one rotation or a stack: matrices, quaternions, ZYZ and RPY angles, tilt.

Conventions (docs/interfaces.md, "Frames and angles"): a rotation acts on column vectors; quaternions are
(x, y, z, w), as geometry_msgs/Quaternion orders them; ZYZ angles (alpha, beta, gamma) in rad mean
R = Rz(alpha) Ry(beta) Rz(gamma), and beta is the angle by which R tilts the z axis; RPY angles (roll, pitch, yaw)
in rad mean R = Rz(yaw) Ry(pitch) Rx(roll), turns about the fixed axes X, Y, Z (REP-103, URDF). The compass
rotation between a snapshot and the current view is R with d_snapshot = R d_current; from ground-truth
orientations Q_s and Q_c of camera_link in map it is Q_s^-1 Q_c. Every function broadcasts over leading axes:
(3, 3) or (..., 3, 3) matrices, (4,) or (..., 4) quaternions, scalars or arrays of angles.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Union, overload

import numpy as np

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

RotationLike = Union[
    'Rotation', np.ndarray, tuple, list
]  # a scipy Rotation, matrices (..., 3, 3) or quaternions (..., 4)


#: Largest tilt between two views of a ground robot's upward camera (rad): a mower's camera tilts by some 20-25
#: degrees on rough lawn, so two views on opposite slopes differ by up to 45 (the bundled bumpy homing grid: 35 at
#: most; the compass sets: 36). The compass searches no further by default; a wider bound lets more wrong hypotheses
#: in (see docs/methods.md, "The 3D compass").
MAX_TILT = float(np.radians(45.0))


def _scipy_rotation() -> type[Rotation]:
    """Return scipy's Rotation class."""
    # imported on first use: scipy.spatial takes some 0.2 s to load, which every node's start would pay
    from scipy.spatial.transform import Rotation  # noqa: PLC0415 (scipy.spatial loads in 0.2 s and every node imports this module at start-up)

    return Rotation


def as_matrix(rotation: RotationLike) -> np.ndarray:
    """Return the rotation matrices (..., 3, 3) of a scipy Rotation, matrices (..., 3, 3) or quaternions (..., 4)."""
    if not isinstance(rotation, (np.ndarray, tuple, list)) and isinstance(rotation, _scipy_rotation()):
        return rotation.as_matrix()
    array = np.asarray(rotation, dtype=float)
    if array.shape[-2:] == (3, 3):
        return array
    if array.shape[-1:] == (4,):
        return _scipy_rotation().from_quat(array.reshape(-1, 4)).as_matrix().reshape(array.shape[:-1] + (3, 3))
    raise ValueError(f'a rotation must be 3x3 matrices or quaternions (x, y, z, w), got shape {array.shape}')


def as_quaternion(rotation: RotationLike) -> np.ndarray:
    """Return the unit quaternions (..., 4) (x, y, z, w) of rotations, w >= 0."""
    matrices = as_matrix(rotation)
    quaternions = _scipy_rotation().from_matrix(matrices.reshape(-1, 3, 3)).as_quat(canonical=True)
    return quaternions.reshape(matrices.shape[:-2] + (4,))


def zyz_matrix(alpha, beta, gamma) -> np.ndarray:
    """Return the matrices Rz(alpha) Ry(beta) Rz(gamma) (..., 3, 3) of ZYZ angles (rad; arrays broadcast)."""
    angles = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (alpha, beta, gamma)))
    ca, sa, cb, sb, cg, sg = (f(x) for x in angles for f in (np.cos, np.sin))
    return np.stack(
        [
            np.stack([ca * cb * cg - sa * sg, -ca * cb * sg - sa * cg, ca * sb], -1),
            np.stack([sa * cb * cg + ca * sg, -sa * cb * sg + ca * cg, sa * sb], -1),
            np.stack([-sb * cg, sb * sg, cb], -1),
        ],
        -2,
    )


@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: np.ndarray) -> np.ndarray: ...
def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Return angles (rad, a scalar or an array) wrapped into [-pi, pi)."""
    wrapped = (np.asarray(angle, dtype=float) + np.pi) % (2 * np.pi) - np.pi
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def yaw_matrix(angle) -> np.ndarray:
    """Return Rz(angle) (..., 3, 3): the turn by angle (rad) about +z, counter-clockwise seen from +z."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(np.shape(c) + (3, 3))
    out[..., 0, 0] = out[..., 1, 1] = c
    out[..., 0, 1], out[..., 1, 0] = -s, s
    out[..., 2, 2] = 1.0
    return out


def rpy_matrix(roll, pitch, yaw) -> np.ndarray:
    """Return the matrices Rz(yaw) Ry(pitch) Rx(roll) (..., 3, 3) of roll, pitch and yaw (rad; arrays broadcast):
    REP-103's and URDF's RPY, turns about the fixed axes X, then Y, then Z."""
    angles = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (roll, pitch, yaw)))
    cr, sr, cp, sp, cy, sy = (f(x) for x in angles for f in (np.cos, np.sin))
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            np.stack([-sp, cp * sr, cp * cr], -1),
        ],
        -2,
    )


def rpy_angles(rotation: RotationLike) -> tuple[np.ndarray, np.ndarray, np.ndarray] | tuple[float, float, float]:
    """Return (roll, pitch, yaw) in rad of rotations (rpy_matrix's angles), pitch in [-pi/2, pi/2]; at pitch +-pi/2,
    where only yaw - roll (or yaw + roll) is defined, roll is 0. One rotation gives floats."""
    r = as_matrix(rotation)
    pitch = np.arctan2(-r[..., 2, 0], np.hypot(r[..., 0, 0], r[..., 1, 0]))
    locked = np.hypot(r[..., 2, 1], r[..., 2, 2]) < 1e-12
    roll = np.where(locked, 0.0, np.arctan2(r[..., 2, 1], r[..., 2, 2]))
    yaw = np.where(locked, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    if r.ndim == 2:
        return float(roll), float(pitch), float(yaw)
    return roll, pitch, yaw


def zyz_angles(rotation: RotationLike) -> tuple[np.ndarray, np.ndarray, np.ndarray] | tuple[float, float, float]:
    """Return the ZYZ angles (alpha, beta, gamma) in rad of rotations, exact near gimbal lock; gamma in [-pi, pi).

    alpha comes from the third column, and gamma from the well-conditioned sum (beta <= pi/2) or difference
    (beta > pi/2) of the angles read off the upper-left 2x2 block, so the matrix rebuilt from the angles matches R
    to rounding (scipy's as_euler loses about 1e-8 near beta = 0 or pi). One rotation gives floats.
    """
    r = as_matrix(rotation)
    alpha = np.arctan2(r[..., 1, 2], r[..., 0, 2])
    beta = np.arctan2(np.hypot(r[..., 0, 2], r[..., 1, 2]), r[..., 2, 2])
    total = np.arctan2(r[..., 1, 0] - r[..., 0, 1], r[..., 0, 0] + r[..., 1, 1])  # (1 + cos beta)(sin, cos)(a + g)
    difference = np.arctan2(-(r[..., 1, 0] + r[..., 0, 1]), -(r[..., 0, 0] - r[..., 1, 1]))  # (a - g)
    gamma = np.where(r[..., 2, 2] >= 0, total - alpha, alpha - difference)
    gamma = np.remainder(gamma + np.pi, 2 * np.pi) - np.pi
    if r.ndim == 2:
        return float(alpha), float(beta), float(gamma)
    return alpha, beta, gamma


def rotation_angle(first: RotationLike, second: RotationLike) -> np.ndarray | float:
    """Return the angle (rad) of first^T second: how far apart two rotations (or two stacks of them) are."""
    a, b = as_matrix(first), as_matrix(second)
    # trace(A^T B) = 1 + 2 cos(angle), summed elementwise: the compass's and the exhaustive search's separation of
    # grid rotations exactly whole steps apart depends on this rounding (an einsum moves figures of the baseline)
    cosine = (np.sum(a * b, axis=(-2, -1)) - 1.0) / 2.0
    angle = np.arccos(np.clip(cosine, -1.0, 1.0))
    return float(angle) if np.ndim(angle) == 0 else angle


def tilt(rotation: RotationLike) -> np.ndarray | float:
    """Return the angle (rad) by which rotations tilt the z axis: the ZYZ beta, 0 for a pure turn about z."""
    z = as_matrix(rotation)[..., 2, 2]
    angle = np.arccos(np.clip(z, -1.0, 1.0))
    return float(angle) if np.ndim(angle) == 0 else angle


def within_tilt(matrix: np.ndarray, max_tilt: float | None) -> bool:
    """Return whether R (3x3) tilts z by at most max_tilt (rad; None: any tilt): R_zz >= cos(max_tilt)."""
    return max_tilt is None or float(matrix[2, 2]) >= float(np.cos(max_tilt)) - 1e-12


def yaw(rotation: RotationLike) -> np.ndarray | float:
    """Return the angle (rad, in [-pi, pi]) of rotations' twist about +z: the ZYZ alpha + gamma, the turn a tilt
    disturbs least (a rotation Ta^-1 Rz(psi) Tb between cameras tilted by Ta and Tb gives psi to second order)."""
    r = as_matrix(rotation)
    angle = np.arctan2(r[..., 1, 0] - r[..., 0, 1], r[..., 0, 0] + r[..., 1, 1])
    return float(angle) if np.ndim(angle) == 0 else angle


def relative_rotation(snapshot_orientation: RotationLike, current_orientation: RotationLike) -> np.ndarray:
    """Return the compass rotations Q_s^-1 Q_c (..., 3, 3) from orientations of camera_link in map: d_s = R d_c."""
    return np.swapaxes(as_matrix(snapshot_orientation), -1, -2) @ as_matrix(current_orientation)


def home_direction(
    snapshot_position: np.ndarray, current_position: np.ndarray, current_orientation: RotationLike
) -> np.ndarray:
    """Return unit vectors (..., 3) towards the snapshot's place in the current camera_link: Q_c^-1 (p_s - p_c)."""
    offset = np.asarray(snapshot_position, dtype=float) - np.asarray(current_position, dtype=float)
    vector = np.einsum('...ji,...j->...i', as_matrix(current_orientation), offset)
    return vector / np.linalg.norm(vector, axis=-1, keepdims=True)
