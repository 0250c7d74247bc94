# SPDX-License-Identifier: Apache-2.0
"""The 3D scene of a camera frame: the taught route's snapshots, the matched one, the home vector, the route direction.

Snapshot places come from the map (docs/interfaces.md, "Maps"): the odometry poses of base_link in `odom` that
live teaching stored (the descriptor skynav_core.maps.ODOM_POSE) where the map has them, else the
ground-truth poses of camera_link in `map` of a map built from a recording. The snapshot's camera_link is oriented
as the ground-truth pose says, or as the odometry pose times the camera's mount M (camera_link in base_link,
skynav_core.mount).

The robot is drawn where localization places it: at the matched snapshot. The home vector (a direction in the
current camera_link) is turned into the route's frame through the snapshot it points to: with that snapshot's
camera orientation Q_t and the home vector's rotation R (d_snapshot = R d_current), the current camera orientation
is Q_t R, so the home vector is Q_t R d there. Logic only (no rclpy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_core.maps import MapStore
from skynav_core.names import MAP_FRAME, ODOM_FRAME
from skynav_core.rotations import as_matrix

IDENTITY = np.eye(3)  # the mount of a camera on the robot's axes
# state of a frame, as a plottable number (/skynav/viz/state)
NO_MAP, LOCALIZING, LOCALIZED = 0, 1, 2
STATE_NAMES = {NO_MAP: 'no map (no snapshot matched)', LOCALIZING: 'match not accepted', LOCALIZED: 'match accepted'}


@dataclass(frozen=True)
class Route:
    """The snapshots' poses in the route's frame: positions (N, 3) m and rotations (N, 3, 3); NaN where unknown."""

    frame_id: str  # 'odom' (taught live, odometry) or 'map' (built from a recording, ground truth)
    positions: np.ndarray
    rotations: np.ndarray

    def __len__(self) -> int:
        return len(self.positions)

    def known(self, index: int) -> bool:
        """Return whether snapshot `index` exists and has a pose."""
        return 0 <= index < len(self) and bool(np.all(np.isfinite(self.positions[index])))

    @property
    def drawn(self) -> np.ndarray:
        """Return the positions (M, 3) of the snapshots with a pose, in index order (m)."""
        return self.positions[np.all(np.isfinite(self.positions), axis=1)]


@dataclass(frozen=True)
class Arrow:
    """An arrow from `start` to `end` (3,) in the route's frame (m)."""

    start: np.ndarray
    end: np.ndarray


@dataclass(frozen=True)
class Scene:
    """What the markers of one frame show; None for what the frame lacks."""

    matched: int | None = None  # the matched snapshot's index (it has a pose)
    accepted: bool = False
    target: int | None = None  # the home vector's snapshot (it has a pose)
    home: Arrow | None = None  # from the matched snapshot along the home vector
    route: Arrow | None = None  # from the matched snapshot towards the next one along the route


def route_of(store: MapStore) -> Route | None:
    """Return the poses of a map's snapshots: odometry where taught live, else ground truth; None without either."""
    poses = store.odometry_poses()
    if poses is not None and poses.shape[1] == 7 and np.isfinite(poses).all(axis=1).any():
        return _route(ODOM_FRAME, poses)
    poses = store.poses()
    if np.isfinite(poses).all(axis=1).any():
        return _route(MAP_FRAME, poses)
    return None


def _route(frame_id: str, poses: np.ndarray) -> Route:
    """Return a Route of (x, y, z, qx, qy, qz, qw) rows; a row with any NaN (or a zero quaternion) has no pose."""
    known = np.isfinite(poses).all(axis=1) & (np.linalg.norm(np.nan_to_num(poses[:, 3:]), axis=1) > 0)
    positions = np.where(known[:, None], poses[:, :3], np.nan)
    rotations = np.full((len(poses), 3, 3), np.nan)
    if known.any():
        quaternions = poses[known, 3:] / np.linalg.norm(poses[known, 3:], axis=1, keepdims=True)
        rotations[known] = as_matrix(quaternions)
    return Route(frame_id, positions, rotations)


def route_arrow(route: Route, index: int, length: float) -> Arrow | None:
    """Return an arrow of `length` m at snapshot `index` towards the next snapshot (the last: from the one before)."""
    ahead = index + 1 if route.known(index + 1) else index
    behind = index if ahead != index else index - 1
    if not (route.known(ahead) and route.known(behind)) or ahead == behind:
        return None
    step = route.positions[ahead] - route.positions[behind]
    norm = float(np.linalg.norm(step))
    if norm == 0:
        return None
    start = route.positions[index]
    return Arrow(start, start + length * step / norm)


def home_arrow(
    route: Route,
    origin: int,
    target: int,
    direction: np.ndarray,
    rotation: np.ndarray,
    length: float,
    mount: np.ndarray = IDENTITY,
):
    """Return an arrow of `length` m at snapshot `origin` along a home vector towards snapshot `target`, or None.

    `direction` is the home vector in the current camera_link, `rotation` (3, 3) its rotation to the target's view,
    `mount` (3, 3) camera_link's rotation in base_link (the odometry poses are base_link's).
    """
    if not (route.known(origin) and route.known(target)):
        return None
    camera = route.rotations[target] @ mount if route.frame_id == ODOM_FRAME else route.rotations[target]
    vector = camera @ rotation @ np.asarray(direction, float)
    norm = float(np.linalg.norm(vector))
    if not np.isfinite(norm) or norm == 0:
        return None
    start = route.positions[origin]
    return Arrow(start, start + length * vector / norm)


def scene(
    route: Route,
    match_index: int,
    accepted: bool,
    home: tuple[int, np.ndarray, np.ndarray] | None,
    length: float,
    mount: np.ndarray = IDENTITY,
) -> Scene:
    """Return the scene of a frame from its place match and its home vector (target index, direction, rotation),
    with the camera mounted as `mount` (3, 3) says."""
    matched = match_index if route.known(match_index) else None
    target = home[0] if home is not None and route.known(home[0]) else None
    arrow = None
    if matched is not None and home is not None:
        arrow = home_arrow(route, matched, home[0], home[1], home[2], length, mount)
    direction = route_arrow(route, matched, length) if matched is not None else None
    return Scene(matched, bool(accepted) and matched is not None, target, arrow, direction)


def confidence(residual: float | None) -> float:
    """Return a frame's confidence 0..1: 1 - its home vector's residual (as the route controller weighs it), or 0."""
    if residual is None or not np.isfinite(residual):
        return 0.0
    return float(np.clip(1.0 - residual, 0.0, 1.0))


def state(match_index: int, accepted: bool) -> int:
    """Return a frame's state (NO_MAP, LOCALIZING, LOCALIZED) from its place match."""
    if match_index < 0:
        return NO_MAP
    return LOCALIZED if accepted else LOCALIZING
