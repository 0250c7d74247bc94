# SPDX-License-Identifier: Apache-2.0
"""The result of every compass method: rotation R with d_snapshot = R d_current (camera_link), residual, hypotheses."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from skynav_core.rotations import as_quaternion, zyz_angles


@dataclass(frozen=True)
class Hypothesis:
    """One candidate rotation (3x3 matrix, d_snapshot = R d_current) with its cost (the method's units)."""

    matrix: np.ndarray
    cost: float

    @property
    def rotation(self):  # -> scipy.spatial.transform.Rotation
        """Return R as a scipy Rotation."""

        return Rotation.from_matrix(self.matrix)


@dataclass(frozen=True)
class CompassEstimate:
    """A compass result: R (d_snapshot = R d_current), residual (cost at R), other hypotheses, confidence."""

    matrix: np.ndarray  # 3x3 rotation R
    residual: float  # cost at R in the method's units (see `units`)
    hypotheses: tuple[Hypothesis, ...] = ()  # distinct local optima, best first (the first is R)
    margin: float = float('inf')  # cost of the second hypothesis minus the residual (inf if there is none)
    confident: bool = True  # residual small enough and margin large enough (thresholds of the method)
    method: str = ''
    units: str = ''
    details: dict = field(default_factory=dict)  # method-specific figures (iterations, inliers, ...)
    relative_margin: float = 1.0  # margin over the depth of the cost landscape (mean grid cost - residual), 0..1
    confidence: float = float('nan')  # 0..1, ranks estimates (higher: more likely right); NaN if the method has none

    @property
    def rotation(self):  # -> scipy.spatial.transform.Rotation
        """Return R as a scipy Rotation (d_snapshot = R d_current)."""

        return Rotation.from_matrix(self.matrix)

    @property
    def quaternion(self) -> np.ndarray:
        """Return R as a unit quaternion (x, y, z, w) with w >= 0 (ROS and scipy order)."""
        return as_quaternion(self.matrix)

    @property
    def euler_zyz(self) -> tuple[float, float, float]:
        """Return (alpha, beta, gamma) in rad with R = Rz(alpha) Ry(beta) Rz(gamma); beta is the relative tilt."""
        alpha, beta, gamma = zyz_angles(self.matrix)  # floats for one rotation
        return float(alpha), float(beta), float(gamma)
