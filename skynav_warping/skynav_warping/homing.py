# SPDX-License-Identifier: Apache-2.0
"""The combined estimate: a compass rotation (optional) and 3D-warping give the home vector to a snapshot.

Output conventions are those of skynav_msgs/HomeVector (docs/interfaces.md): a unit direction towards the snapshot's
place in the current camera_link, the rotation R with d_snapshot = R d_current (quaternion x, y, z, w), and a
residual (the masked mean squared difference of the warped current view and the snapshot, view units^2).
When no translation explains the views better than a pure rotation (confidence below the threshold) the
direction is the zero vector: there is no confident home vector, which also means "at the snapshot's place or
too close to tell". A view or snapshot without a skyline (all sky or all ground in its field of view) holds nothing
a step could explain: its confidence is 0, whatever the search found.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from skynav_core.rotations import RotationLike, as_matrix, as_quaternion, within_tilt
from skynav_sh.product import seen_mean, shows_skyline
from skynav_warping.views import WarpView
from skynav_warping.warping3d import WarpingSettings, WarpResult, warp_home_vector


@dataclass(frozen=True)
class HomeEstimate:
    """Home vector, rotation and residual of one current view against one snapshot (current camera_link)."""

    direction: np.ndarray  # unit home vector, or zeros when not confident
    rotation: np.ndarray  # 3x3 R, d_snapshot = R d_current
    residual: float  # masked mean squared difference at the optimum (view units^2)
    confidence: float  # 1 - residual / residual of the best pure rotation, in [0, 1]
    confident: bool
    distance_ratio: float  # |t| / rho of the optimum (equal-distance model)
    best_direction: np.ndarray  # the optimum's direction, also when not confident (diagnostics)
    compass_used: bool  # True if a compass rotation started the search (one within the tilt bound)
    warp: WarpResult  # the full 3D-warping result

    @property
    def quaternion(self) -> np.ndarray:
        """Return the rotation as a unit quaternion (x, y, z, w) with w >= 0, as geometry_msgs/Quaternion orders it."""
        return as_quaternion(self.rotation)


def sky_share(view: WarpView) -> float:
    """Return the share of what a mask view sees that is sky (the rim taper weighting its edge)."""
    return float(seen_mean(view.terms[1], view.terms[0]))


def estimate_home_vector(
    current: WarpView,
    snapshot: WarpView,
    compass: RotationLike | None = None,
    settings: WarpingSettings = WarpingSettings(),
) -> HomeEstimate:
    """Return the home vector (current camera_link) from the current view to the snapshot's place.

    compass: the compass rotation R (d_snapshot = R d_current) as a 3x3 matrix, quaternion (x, y, z, w) or scipy
    Rotation, used as the start of the rotation search (refined there) unless it tilts the views further apart than
    settings.max_relative_tilt; None: a rotational pre-alignment over tilt and a whole turn of yaw starts it instead.
    """
    start = None if compass is None else as_matrix(compass)
    result = warp_home_vector(current, snapshot, start, settings)
    if not (shows_skyline(sky_share(current)) and shows_skyline(sky_share(snapshot))):
        result = replace(result, direction=np.zeros(3), confidence=0.0, confident=False)
    return HomeEstimate(
        direction=result.direction,
        rotation=result.rotation,
        residual=result.residual,
        confidence=result.confidence,
        confident=result.confident,
        distance_ratio=result.distance_ratio,
        best_direction=result.best_direction,
        compass_used=start is not None and within_tilt(start, settings.max_relative_tilt),
        warp=result,
    )
