# SPDX-License-Identifier: Apache-2.0
"""Teaching a route live: which views of a drive become snapshots of a new map, and how far the robot went.

While a Teach goal runs (docs/interfaces.md, "Driving: teach, follow, home"), every usable view (/skyline/sh) is
offered to a RouteTeacher. It keeps one as a snapshot

- every `spacing` m of travel by odometry (/odom, path length of base_link in `odom`), when an odometry sample lies
  within `odometry_tolerance` of the view's stamp: the first view past each multiple of `spacing` from the first
  snapshot (so that the mean spacing is `spacing` whatever the camera's rate), and at least half a spacing apart;
- every TURN_SNAPSHOT_ANGLE of turn by odometry, so that a point turn (the robot turning where it stands, as a mower
  does at a lane's end) is stored where it happens and the route's shape has its corner;
- otherwise when the view's amplitude descriptor moved `spacing` x `change_per_metre` from the last snapshot's.
  VIEW_CHANGE_PER_METRE is calibrated on the bundled synthetic teach drives so that the two give similar spacing
  (README, "Teach a route");
- always for the first view, and for the view at which the odometry says `max_length` m were driven (the goal's
  last snapshot).

Each snapshot is one transaction of the map (skynav_core.maps): a process killed while teaching leaves a readable
map with every snapshot stored so far. With it the teacher stores the odometry pose of base_link in `odom` as the
per-snapshot descriptor ODOM_POSE (NaN when there was none), and as COMMAND_POSE the pose by dead reckoning from
the velocity commands the robot was driven with (/cmd_vel, CommandedMotion): the route's shape for a robot without
wheel odometry (the route node reads ODOM_POSE first). Spacing stays by the view's change there, as the Teach action
says. The map's pose columns stay empty (they hold ground truth, which no node reads). The map is created with the
first view (its SH degree is the view's). Logic only (no rclpy).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from skynav_core.errors import SkynavError
from skynav_core.maps import COMMAND_POSE, ODOM_POSE, MapError, MapStore
from skynav_core.motion import arc, ground_pose
from skynav_core.rotations import wrap_angle, yaw

from .descriptors import describe
from .mapping import DEFAULT_MIN_TRAVEL, create_map

DEFAULT_SPACING = DEFAULT_MIN_TRAVEL  # m between snapshots, as `skynav map build --min-travel`
#: Amplitude-descriptor distance (dimensionless) per metre of travel. A threshold of spacing x this on the bundled
#: synthetic teach drives (garden, mineral; 0.1 m between frames) gives median spacings of 0.20 m for 0.2 m and
#: 0.50 m for 0.5 m; the drives' per-frame change is 0.042-0.050 per metre (median).
VIEW_CHANGE_PER_METRE = 0.04
DEFAULT_ODOMETRY_TOLERANCE_NS = 250_000_000  # the odometry sample nearest a view pairs with it within 0.25 s
ODOMETRY_CAPACITY = 256  # odometry samples kept for pairing with views (about 5 s at 50 Hz)
NO_POSE = np.full(7, np.nan)
COMMAND_HOLD_NS = 500_000_000  # a velocity command moves the robot for at most 0.5 s (a base's usual command timeout)
COMMAND_CAPACITY = 256  # commands kept for looking up views' poses (about 10 s at 25 Hz)
TURN_SNAPSHOT_ANGLE = math.radians(30.0)  # rad of turn by odometry since the last snapshot that store another


class TeachError(SkynavError):
    """A teach goal that cannot go on; `code` names the Teach.Result constant it ends with."""

    code = 'MAP_WRITE_FAILED'


class MapExists(TeachError):
    """The map file exists and the goal does not allow overwriting it."""

    code = 'MAP_EXISTS'


class MapWriteFailed(TeachError):
    """The map cannot be created, or a snapshot cannot be written."""

    code = 'MAP_WRITE_FAILED'


class NoInput(TeachError):
    """No usable view arrived for the input timeout."""

    code = 'NO_INPUT'


class BadGoal(TeachError):
    """A goal field that cannot be used (an empty path, a non-finite number)."""

    code = 'BAD_GOAL'


def check_target(path: str, overwrite: bool) -> Path:
    """Return the map path of a goal if a map can be created there; MapExists or MapWriteFailed otherwise."""
    if not path:
        raise BadGoal('map_path is empty: name the map file to create')
    target = Path(path)
    if target.is_dir():
        raise MapWriteFailed(f'{target}: is a directory, not a map file')
    if target.exists() and not overwrite:
        raise MapExists(f'{target}: exists already; choose another name or set overwrite')
    if not target.parent.is_dir():
        raise MapWriteFailed(f'{target}: no such directory {target.parent}')
    if not os.access(target.parent, os.W_OK):
        raise MapWriteFailed(f'{target}: directory {target.parent} is not writable')
    return target


class OdometryTrack:
    """The latest odometry samples of a drive with the path length driven up to each (m), looked up by stamp."""

    def __init__(self, capacity: int = ODOMETRY_CAPACITY) -> None:
        self.capacity = capacity
        self._stamps: list[int] = []
        self._travelled: list[float] = []
        self._poses: list[np.ndarray] = []

    def add(self, stamp_ns: int, pose: np.ndarray) -> bool:
        """Take one sample (stamp in ns, (x, y, z, qx, qy, qz, qw) in odom); False (ignored) if not newer or finite."""
        pose = np.asarray(pose, dtype=float)
        if pose.shape != (7,) or not np.all(np.isfinite(pose)):
            return False
        if self._stamps and stamp_ns <= self._stamps[-1]:
            return False
        step = float(np.linalg.norm(pose[:3] - self._poses[-1][:3])) if self._poses else 0.0
        self._stamps.append(int(stamp_ns))
        self._travelled.append((self._travelled[-1] if self._travelled else 0.0) + step)
        self._poses.append(pose)
        if len(self._stamps) > self.capacity:
            del self._stamps[0], self._travelled[0], self._poses[0]
        return True

    def at(self, stamp_ns: int, tolerance_ns: int) -> tuple[np.ndarray, float] | None:
        """Return (pose, path length driven in m) at `stamp_ns`, None without a sample within the tolerance.

        Between samples the position and path length are interpolated linearly; past the newest sample (a view
        often arrives before the odometry of its instant) they are extrapolated at the last samples' velocity.
        The orientation is the nearest sample's.
        """
        if not self._stamps:
            return None
        stamps = np.asarray(self._stamps, dtype=np.int64)
        stamp = int(stamp_ns)
        nearest = int(np.argmin(np.abs(stamps - stamp)))
        if abs(int(stamps[nearest]) - stamp) > tolerance_ns:
            return None
        after = int(np.searchsorted(stamps, stamp))
        if stamps.size < 2 or after == 0 or (after < stamps.size and stamps[after] == stamp):
            return self._poses[nearest], self._travelled[nearest]
        a, b = (after - 1, after) if after < stamps.size else (stamps.size - 2, stamps.size - 1)
        weight = (stamp - int(stamps[a])) / (int(stamps[b]) - int(stamps[a]))
        pose = self._poses[nearest].copy()
        pose[:3] = self._poses[a][:3] + weight * (self._poses[b][:3] - self._poses[a][:3])
        travelled = self._travelled[a] + weight * (self._travelled[b] - self._travelled[a])
        return pose, float(travelled)


class CommandedMotion:
    """Dead reckoning from velocity commands: where base_link is if it obeyed each command exactly (held until the
    next one, at most COMMAND_HOLD), in the frame where it stood before the first (origin, heading 0; m, rad)."""

    def __init__(self, hold_ns: int = COMMAND_HOLD_NS, capacity: int = COMMAND_CAPACITY) -> None:
        self.hold_ns, self.capacity = int(hold_ns), capacity
        self._stamps: list[int] = []  # ns, each command's stamp
        self._states: list[tuple[tuple[float, float, float], float, float, float]] = []  # pose, path length, v, w

    def add(self, stamp_ns: int, linear: float, angular: float) -> bool:
        """Take one command (stamp in ns, m/s forward, rad/s left); False (ignored) if not newer or finite."""
        if not (math.isfinite(linear) and math.isfinite(angular)) or (self._stamps and stamp_ns <= self._stamps[-1]):
            return False
        pose, travelled = self._state_at(stamp_ns)
        self._stamps.append(int(stamp_ns))
        self._states.append((pose, travelled, float(linear), float(angular)))
        if len(self._stamps) > self.capacity:
            del self._stamps[0], self._states[0]
        return True

    def at(self, stamp_ns: int) -> tuple[np.ndarray, float] | None:
        """Return (pose (x, y, z, qx, qy, qz, qw), path length in m) at `stamp_ns`; None if older than the commands
        kept. Before the first command the robot stands at the origin."""
        if self._stamps and stamp_ns < self._stamps[0] and len(self._stamps) == self.capacity:
            return None
        pose, travelled = self._state_at(stamp_ns)
        return ground_pose(*pose), travelled

    def _state_at(self, stamp_ns: int) -> tuple[tuple[float, float, float], float]:
        """Return the planar pose (x, y, heading) and path length (m) at `stamp_ns`, from the last command before it."""
        last = int(np.searchsorted(np.asarray(self._stamps, dtype=np.int64), stamp_ns, side='right')) - 1
        if last < 0:
            return (0.0, 0.0, 0.0), 0.0
        pose, travelled, linear, angular = self._states[last]
        seconds = min(stamp_ns - self._stamps[last], self.hold_ns) * 1e-9
        return arc(*pose, linear * seconds, angular * seconds), travelled + abs(linear) * seconds


class RouteTeacher:
    """One teach run: the views offered become snapshots of a new map at `path` (see the module notes)."""

    def __init__(
        self,
        path: str | os.PathLike,
        name: str = '',
        *,
        spacing: float = DEFAULT_SPACING,
        max_length: float = 0.0,
        overwrite: bool = False,
        change_per_metre: float = VIEW_CHANGE_PER_METRE,
        odometry_tolerance_ns: int = DEFAULT_ODOMETRY_TOLERANCE_NS,
        created_from: str = 'teach',
    ) -> None:
        """Check the goal (TeachError if it cannot be taught); spacing, max_length in m (max_length <= 0: no limit)."""
        if not (math.isfinite(spacing) and math.isfinite(max_length) and spacing > 0):
            raise BadGoal(f'spacing must be positive and max_length finite, got {spacing} and {max_length}')
        if not change_per_metre > 0:
            raise BadGoal(f'change_per_metre must be positive, got {change_per_metre}')
        self.path = check_target(os.fspath(path), overwrite)
        self.name = name or self.path.stem
        self.spacing = float(spacing)
        self.max_length = float(max_length)
        self.overwrite = overwrite
        self.change_per_metre = float(change_per_metre)
        self.odometry_tolerance_ns = int(odometry_tolerance_ns)
        self.created_from = created_from
        self.odometry = OdometryTrack()
        self.commanded = CommandedMotion()
        self.store: MapStore | None = None
        self.finished = False  # max_length reached: the goal ends
        self._descriptor: np.ndarray | None = None  # the last snapshot's amplitude descriptor
        self._travelled: float | None = None  # path length (m, by odometry) at the last snapshot; None without
        self._heading: float | None = None  # heading (rad, by odometry) at the last snapshot; None without
        self._start: float | None = None  # path length at the first snapshot with odometry
        self._end: float | None = None  # path length at the last snapshot with odometry
        self._commanded: tuple[float, float] | None = None  # commanded path length at the first and last snapshot

    @property
    def snapshots(self) -> int:
        """Return the number of snapshots stored so far."""
        return 0 if self.store is None else len(self.store)

    @property
    def route_length(self) -> float:
        """Return the path length (m) from the first to the last snapshot by odometry (between snapshots that had
        it), else by the velocity commands; 0 unknown."""
        if self._start is not None and self._end is not None:
            return self._end - self._start
        return 0.0 if self._commanded is None else self._commanded[1] - self._commanded[0]

    @property
    def length_source(self) -> str:
        """Return what a route_length above 0 is measured by: 'odometry' or 'commands'."""
        return 'odometry' if self._start is not None else 'commands'

    def add_odometry(self, stamp_ns: int, pose: np.ndarray) -> bool:
        """Take one odometry sample of base_link in odom (stamp in ns, x y z qx qy qz qw); False if ignored."""
        return self.odometry.add(stamp_ns, pose)

    def add_command(self, stamp_ns: int, linear: float, angular: float) -> bool:
        """Take one velocity command the robot is driven with (stamp in ns, m/s, rad/s); False if ignored."""
        return self.commanded.add(stamp_ns, linear, angular)

    def offer(self, stamp_ns: int, coefficients: np.ndarray) -> bool:
        """Offer one view's SH coefficients (stamp in ns); return whether it was stored as a snapshot.

        ValueError for coefficients of a lower degree than the map's; MapWriteFailed when the map cannot be written.
        """
        if self.finished:
            return False
        coefficients = np.asarray(coefficients, dtype=float)
        degree = round(math.sqrt(coefficients.size)) - 1
        if (degree + 1) ** 2 != coefficients.size:
            raise ValueError(f'{coefficients.size} coefficients are not (L+1)^2 for any degree L')
        if self.store is not None:
            if degree < self.store.max_degree:
                raise ValueError(f'coefficients of degree {degree}; the map being taught has {self.store.max_degree}')
            degree = self.store.max_degree
            coefficients = coefficients[: (degree + 1) ** 2]
        descriptor = describe('amplitude', coefficients, degree)
        odometry = self.odometry.at(stamp_ns, self.odometry_tolerance_ns)
        travelled = None if odometry is None else odometry[1]
        heading = None if odometry is None else float(yaw(odometry[0][3:]))
        if not self._keep(descriptor, travelled, heading):
            return False
        commanded = self.commanded.at(stamp_ns)
        self._store(
            stamp_ns,
            coefficients,
            {
                ODOM_POSE: NO_POSE if odometry is None else odometry[0],
                COMMAND_POSE: NO_POSE if commanded is None else commanded[0],
            },
        )
        self._descriptor = descriptor
        if commanded is not None:
            self._commanded = (commanded[1] if self._commanded is None else self._commanded[0], commanded[1])
        if travelled is not None:
            self._travelled, self._heading = travelled, heading
            self._start = travelled if self._start is None else self._start
            self._end = travelled
        if self.max_length > 0 and self.route_length >= self.max_length:
            self.finished = True
        return True

    def _keep(self, descriptor: np.ndarray, travelled: float | None, heading: float | None) -> bool:
        """Return whether a view (amplitude descriptor; path length (m) and heading (rad) by odometry, or None)
        becomes a snapshot."""
        if self._descriptor is None:
            return True
        if travelled is not None:
            if self._start is None:  # the first view beat the first /odom sample: count from that sample on
                return travelled >= self.spacing
            assert self._travelled is not None
            if self.max_length > 0 and travelled - self._start >= self.max_length:
                return True
            if heading is not None and self._heading is not None:
                if abs(wrap_angle(heading - self._heading)) >= TURN_SNAPSHOT_ANGLE:
                    return True
            due = self._start + (math.floor((self._travelled - self._start) / self.spacing) + 1) * self.spacing
            return travelled >= due and travelled - self._travelled >= self.spacing / 2
        change = float(np.linalg.norm(descriptor - self._descriptor))
        return change >= self.spacing * self.change_per_metre

    def _store(self, stamp_ns: int, coefficients: np.ndarray, poses: dict[str, np.ndarray]) -> None:
        """Commit one snapshot (creating the map with the first); MapWriteFailed if it cannot be written."""
        try:
            if self.store is None:
                self.store = create_map(
                    self.path,
                    self.name,
                    round(math.sqrt(coefficients.size)) - 1,
                    created_from=self.created_from,
                    metadata={'taught': 'live', 'spacing_m': self.spacing},
                    overwrite=self.overwrite,
                )
            self.store.add_snapshot(coefficients, stamp_ns, None, poses)
        except MapError as exc:
            raise MapWriteFailed(str(exc)) from None

    def finish(self) -> Path | None:
        """Close the map into one self-contained file and return its path (None if no view was ever stored)."""
        if self.store is None:
            return None
        try:
            self.store.close()
        except MapError as exc:
            raise MapWriteFailed(str(exc)) from None
        return self.path
