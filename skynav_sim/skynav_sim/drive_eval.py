# SPDX-License-Identifier: Apache-2.0
"""Scores of closed-loop driving runs (`skynav eval follow|home`): cross-track error, driven length, time stopped.

Pure numpy on true planar paths in the world's map frame (x, y in m, headings in rad), one pose per camera frame
(skynav_sim.closed_loop.Run). The taught route is the polyline through its snapshots' true positions.

The cross-track error of a driven position is its distance to the nearest point of the route *near where the
robot is along it*: the search follows the robot's progress (from the route's start, at most TRACK_BACK behind and
TRACK_AHEAD beyond the previous position's foot point), so a long route that passes near itself does not make a
robot on a later stretch look on track. Everything here scores synthetic runs from ground truth; nothing of it
reaches the loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

TRACK_BACK = 1.0  # m: the cross-track foot point may fall back this far along the route between frames
TRACK_AHEAD = 3.0  # m: ...and move on at most this far (a frame drives 0.08 m at the simulator's speed)
STILL_DISTANCE = 0.005  # m: a frame that moved less than this...
STILL_TURN = np.radians(0.5)  # rad: ...and turned less than this stood still


def path_length(points: np.ndarray) -> float:
    """Return the length (m) of a polyline of (x, y) points."""
    points = np.asarray(points, float).reshape(-1, 2)
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))


def time_stopped(poses: np.ndarray, period: float) -> float:
    """Return the time (s) a robot stood still: frames `period` s apart whose pose (x, y, heading) barely changed."""
    poses = np.asarray(poses, float).reshape(-1, 3)
    moved = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
    turned = np.abs(np.angle(np.exp(1j * np.diff(poses[:, 2]))))
    return float(np.count_nonzero((moved < STILL_DISTANCE) & (turned < STILL_TURN)) * period)


def turns(route: np.ndarray, step: float = 0.5) -> tuple[float, float]:
    """Return how far (degrees) a route turns left and right in all, its heading sampled every `step` m."""
    route = np.asarray(route, float).reshape(-1, 2)
    arcs = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(route, axis=0), axis=1))])
    if arcs[-1] < 2 * step:
        return 0.0, 0.0
    samples = np.arange(0.0, arcs[-1], step)
    points = np.column_stack([np.interp(samples, arcs, route[:, 0]), np.interp(samples, arcs, route[:, 1])])
    ahead = np.diff(points, axis=0)
    change = np.degrees(np.diff(np.unwrap(np.arctan2(ahead[:, 1], ahead[:, 0]))))
    return float(change[change > 0].sum()), float(-change[change < 0].sum())


def _segments(route: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the route's segment starts, vectors and the arc length (m) at each start."""
    route = np.asarray(route, float).reshape(-1, 2)
    if len(route) < 2:
        raise ValueError('a route needs at least 2 points')
    a, ab = route[:-1], np.diff(route, axis=0)
    arcs = np.concatenate([[0.0], np.cumsum(np.linalg.norm(ab, axis=1))[:-1]])
    return a, ab, arcs


def cross_track(
    points: np.ndarray, route: np.ndarray, back: float = TRACK_BACK, ahead: float = TRACK_AHEAD
) -> tuple[np.ndarray, np.ndarray]:
    """Return each driven point's distance (m) to the route polyline and its foot point's arc length (m) on it.

    The nearest point is searched on the segments within `back` behind and `ahead` beyond the previous point's foot
    (the first point: from the route's start); np.inf for both searches the whole route.
    """
    points = np.asarray(points, float).reshape(-1, 2)
    a, ab, arcs = _segments(route)
    lengths = np.linalg.norm(ab, axis=1)
    t = np.clip(
        np.einsum('pij,ij->pi', points[:, None] - a, ab) / np.maximum(np.einsum('ij,ij->i', ab, ab), 1e-12), 0, 1
    )
    distances = np.linalg.norm(points[:, None] - (a + t[..., None] * ab), axis=2)  # (points, segments)
    feet = arcs + t * lengths
    error, along = np.empty(len(points)), np.empty(len(points))
    foot = 0.0
    for k in range(len(points)):  # the window follows the previous foot: one pass over the frames
        window = (arcs + lengths >= foot - back) & (arcs <= foot + ahead)
        if not window.any():
            window[:] = True
        row = np.where(window, distances[k], np.inf)
        best = int(np.argmin(row))
        error[k], along[k] = row[best], feet[k, best]
        foot = along[k]
    return error, along


@dataclass(frozen=True)
class ErrorSummary:
    """The cross-track errors of a run (or of many pooled): median, 90th percentile, largest and RMSE, in m."""

    median: float
    p90: float
    max: float
    rmse: float

    @classmethod
    def of(cls, errors: Sequence[float] | np.ndarray) -> ErrorSummary:
        """Return the summary of some errors (m); NaN everywhere for none."""
        e = np.asarray(errors, float).ravel()
        if e.size == 0:
            return cls(np.nan, np.nan, np.nan, np.nan)
        return cls(float(np.median(e)), float(np.percentile(e, 90)), float(e.max()), float(np.sqrt(np.mean(e**2))))


def share(successes: int, total: int) -> str:
    """Return 'k/n (p %)' for a success count."""
    return f'{successes}/{total} ({100 * successes / total:.0f} %)' if total else '0/0'


@dataclass
class FollowScore:
    """What one route-following run measured: lengths and distances in m, times in s, tilts in degrees."""

    world: str
    seed: int
    route_seed: int  # which planned route of the world was taught
    snapshots: int  # in the taught map
    taught: float  # length of the taught route (its snapshots' true positions)
    turns: tuple[float, float]  # degrees the taught route turns left and right in all
    driven: float  # length of the true driven path
    reached: bool  # the goal ended reached near the route's end
    ended: str  # how the goal ended: 'reached' or an error code's name
    end_distance: float  # from the last position to the last snapshot
    duration: float  # sim time of the run
    stopped: float  # sim time standing still
    tilts: np.ndarray  # camera tilt of each followed view
    error: np.ndarray  # cross-track error of each position
    along: np.ndarray  # the route's arc length at each position's foot point
    states: list[str]  # the goal's state on each answered frame (feedback: following, recovering, ...)
    matched: np.ndarray  # the snapshot the controller believed passed on each answered frame (-1: none yet)
    nearest: np.ndarray  # the snapshot truly nearest to the robot on each answered frame
