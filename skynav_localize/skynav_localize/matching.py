# SPDX-License-Identifier: Apache-2.0
"""Matching a query against a route's snapshots: nearest snapshot, SeqSLAM sequences, the acceptance test.

Everything works on distances from queries to snapshots, lower = more alike, whatever the descriptor, so the
place descriptors of skynav and the baselines share one code path.

- Single frame: the best snapshot is the nearest one; its *score* is the distance ratio best / runner-up, the
  runner-up being the nearest snapshot more than `exclusion` snapshots away from the best (a place resembles its
  neighbours on the route; a distinct place does not resemble the rest of it).
- Sequence (SeqSLAM's trajectory search): for the newest query and every snapshot j, straight trajectories ending
  at j are followed back over the last `length` queries at speeds min_speed..max_speed (snapshots per query
  frame); the *sequence distance* of j is the least mean distance along one of them (distance units). A trajectory
  that would start before the first snapshot stays on it. With window > 0, the trajectory is chosen on
  contrast-normalised rows instead (each query's distances as z-scores within +-window snapshots, as SeqSLAM
  does); the reported distance stays the sequence distance. The score is again a ratio: the best sequence
  distance over the best one ending more than exclusion + SequenceParams.extent() snapshots away (trajectories
  ending closer run through the same places). With no runner-up (a map shorter than the exclusion zone) the ratio
  is 0 and only the other tests can reject.
- The newest view in its place (`view_in_place`, skynav's sequence methods): the sequence chooses the place, the
  snapshots within `exclusion` of its best one; the newest view alone chooses the snapshot within it (its least
  distance there), and its single-frame ratio at that snapshot tells whether the view itself vouches for it. A
  sequence assumes that the last `length` views moved along the route; after a detour, a stop or a turn it lags
  or runs ahead of the robot for up to `length` views, and off the route a straight trajectory still finds the
  route's likeliest stretch. The newest view corrects the lag and is not fooled by the history.
- Acceptance: accepted when score <= max_score, the reported distance <= max_distance and, where a view test is
  set (max_view_score), the newest view's ratio at the matched snapshot <= max_view_score.
- Where the route looks alike (skynav's sequence methods): a view biased by the light or the tilt can land nearer
  another stretch of a route whose places hardly differ, and every test above then vouches for the wrong place. Two
  more tests guard against it. The map's own *self-similarity* at a snapshot is the route's step there (median
  distance between successive snapshots within `exclusion` of it) over the distance to its nearest look-alike (the
  nearest snapshot more than `exclusion` away): low on a route whose places stand out, near or above 1 where the
  route elsewhere looks as much like the place as its next snapshot does. The *motion* of the matches: the views
  whose own ratio passed (they vouched for their snapshots) name snapshots that a robot driving at least
  min_speed snapshots per view leaves behind in turn (motion_tests). A match is accepted only where it falls
  behind none of the snapshots the last views vouched for (within MOTION_SLACK; motion_window), and either its
  snapshot's self-similarity is at most max_self_similarity or at least three quarters of the sequence's views
  vouched for snapshots that advance steadily (least-squares slope within the speed range). The first alternative
  keeps a robot that rejoins a distinct route after a detour localized at once; the second refuses a sequence
  that stalls or jitters in place where the route looks alike, while a steady drive there still earns its matches.
- Against the map's own statistics (skynav's sequence methods, outside tracking): how near a view must be to its
  place differs from route to route (the skyline of a real landscape 40 m away changes about five times less over a
  metre of route than a synthetic garden's), so two more bounds are measured on the map itself. The *view change* at
  a snapshot is its mean distance to the snapshots `exclusion` before and after it (about a metre of route). A
  match's *relative distance* is the lesser of the sequence's distance at its place and the newest view's distance
  at its snapshot, each over the view change there; it is accepted only where that is at most
  max_relative_distance. A view 1.5 m beside the route lies about as far from its place as a view a third to a half
  of a metre along the route does, farther than a view on the route under another light and tilt (the lesser of
  the two: just after a detour the sequence still holds the views off the route, and the newest view back answers
  for itself). The *displaced ratio* of a snapshot is the ratio at it of its neighbours `exclusion` snapshots away
  (their distance to it over their least distance to a snapshot more than `exclusion` from both; the smaller side's):
  a view about a metre from the place under the teach's light. Above 1 the neighbourhood resembles places
  elsewhere more than the place itself: the place is told apart by something that changes abruptly along the route
  and recurs off it (on the real landscapes, the tilt of the terrain). Such a place counts as distinct (the
  self-similarity alternative above) only with a displaced ratio at most max_displaced_ratio; otherwise its match
  needs a steady drive.
- Tracking (while the robot follows the route it was taught): the question is no longer which stretch of the whole
  route the view shows but how far the robot has come along it since the last accepted match. The match is sought
  only in the tracking window (RouteTracker: with odometry of the drive and of the teach, around the place the
  odometry carries on and the accepted matches correct, and an accepted match then names that place's snapshot;
  without odometry, from MOTION_SLACK snapshots behind the last accepted match to max_speed snapshots per view
  ahead of it). The window stands in for the tests that tell the route from elsewhere (the ratios, the
  self-similarity): a look-alike elsewhere on the route cannot take the match, and only a featureless view is
  still refused. A robot that leaves the route is caught by its compass and home vector, not by its place match.
  Why: under another light than the teach's, a view's own ratio rises to the bound on the route too (on the
  synthetic follow runs, taught at 8.5 h, followed at 6.2 h under clouds: 0.45-0.7 within 4 m of the start, the
  views resembling snapshots 0.5 m behind them), and where the route comes back near its start the sequence's
  ratio does (0.57); a follower without tracking lost its place within 5 m on 4 of 6 routes of 50 m.
- The start: a robot that follows a route from its start (a FollowRoute goal naming start_index) is placed there
  (RouteTracker.start_at), as if a match had been accepted, until its first accepted match. Where the route ends
  near its start, a standing robot's views resemble both ends and every ratio test refuses them (synthetic garden
  seed 7: 11 of 11 views matched snapshot 396 of 428, none accepted, and the goal ended LOST at the start).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from skynav_localize.errors import LocalizeError

#: Snapshots either side of the best one that the runner-up may not come from (default; 1 m at 0.1 m spacing).
DEFAULT_EXCLUSION = 10
#: Candidates reported with each match (best first), for PlaceMatch.candidate_indices/distances.
DEFAULT_CANDIDATES = 5
#: Lower bound of a local standard deviation (distance units) in contrast normalisation: guards flat rows.
MIN_LOCAL_STD = 1e-12
#: Snapshots by which the newest view's choice within a place may lag a steady drive in the motion tests: on the
#: bundled repeat drives its choice jitters by 1-3 snapshots about the true one, and the robot covers 0.45-0.65
#: snapshots per view there, at the edge of the default speed range.
MOTION_SLACK = 3
#: Views after the last accepted match during which tracking keeps searching near it (2 s at the simulator's 5 Hz);
#: then the window is dropped and the place must be found on the whole route again.
TRACKING_VIEWS = 10
#: m either side of the place odometry expects that the tracking window keeps: the newest view's choice of snapshot
#: jitters by 1-3 snapshots (0.1-0.36 m at the taught 0.12 m spacing) about a steady drive.
TRACKING_SLACK = 0.4
#: share of the distance driven since the anchor added to the window either side: wheel slip, odometry drift and a
#: path beside the taught one (a corner cut or widened) make the distances along the two differ.
TRACKING_SLIP = 0.25
#: share of the odometry's step by which an accepted match may move the tracked place towards itself, either way:
#: under a tree's crown, whose sky the crown fills, the views of a synthetic park resembled places up to 1.5 m
#: behind them for 30 views, and a pull of 0.5 let them hold the place back that far.
TRACKING_PULL = 0.25


@dataclass(frozen=True)
class Acceptance:
    """Acceptance test of a match: distance ratio, distance and (sequences) the newest view's ratio at their bounds."""

    max_score: float  # best / runner-up distance ratio (single frames and sequences alike)
    max_distance: float = math.inf  # reported distance, descriptor units, above which nothing is accepted
    exclusion: int = DEFAULT_EXCLUSION  # snapshots either side of the best excluded from the runner-up
    # sequences: the newest view's single-frame ratio at the matched snapshot, which it chooses within the sequence's
    # place (view_in_place); None: the sequence's match as SeqSLAM gives it (the baselines)
    max_view_score: float | None = None
    # sequences: the motion tests (snapshots of slack; None: none, the match is judged without the earlier views)
    motion_slack: float | None = None
    # the matched snapshot's self-similarity, unless the sequence's views vouched for a steady drive; None: no bound
    max_self_similarity: float | None = None
    # sequences, outside tracking: the sequence distance over the map's own view change at the sequence's place
    # (view_change: across `exclusion` snapshots); None: no bound
    max_relative_distance: float | None = None
    # with the self-similarity: the displaced ratio of the matched snapshot (the ratio at it of its neighbours
    # `exclusion` snapshots away, views about a metre from it), unless the views vouched for a steady drive
    max_displaced_ratio: float | None = None

    def accepts(
        self, score: np.ndarray | float, distance: np.ndarray | float, view_score: np.ndarray | float | None = None
    ) -> np.ndarray | bool:
        """Return whether matches with these scores, distances and view scores pass (vectorised)."""
        passed = (np.asarray(score) <= self.max_score) & (np.asarray(distance) <= self.max_distance)
        if self.max_view_score is not None and view_score is not None:
            passed = passed & (np.asarray(view_score) <= self.max_view_score)
        return passed

    def vouches(self, score: np.ndarray | float, view_score: np.ndarray | float | None = None) -> np.ndarray | bool:
        """Return whether views vouch for their snapshots: their own ratio (view score, or score) passes."""
        if self.max_view_score is not None and view_score is not None:
            return np.asarray(view_score) <= self.max_view_score
        return np.asarray(score) <= self.max_score

    def passes_relative_distance(self, relative_distance: np.ndarray | float) -> np.ndarray | bool:
        """Return whether matches pass the bound on the distance relative to the map's view change (vectorised)."""
        if self.max_relative_distance is None:
            return np.ones(np.shape(relative_distance), dtype=bool)
        return np.asarray(relative_distance) <= self.max_relative_distance

    def passes_place_tests(
        self,
        consistent: np.ndarray,
        steady: np.ndarray,
        self_similarity: np.ndarray,
        displaced_ratio: np.ndarray | None = None,
    ) -> np.ndarray:
        """Return whether matches pass the tests of a route that looks alike (vectorised; see the module notes)."""
        distinct = (
            np.ones(np.shape(self_similarity), dtype=bool)
            if self.max_self_similarity is None
            else np.asarray(self_similarity) <= self.max_self_similarity
        )
        if self.max_displaced_ratio is not None and displaced_ratio is not None:
            distinct = distinct & (np.asarray(displaced_ratio) <= self.max_displaced_ratio)
        if self.motion_slack is None:
            return distinct
        return np.asarray(consistent, dtype=bool) & (distinct | np.asarray(steady, dtype=bool))


@dataclass(frozen=True)
class SequenceParams:
    """SeqSLAM settings: sequence length (query frames), speed range (snapshots per frame), normalisation window."""

    length: int = 10  # query frames per sequence, newest included
    min_speed: float = 0.5  # snapshots per query frame
    max_speed: float = 2.0  # snapshots per query frame
    # snapshots either side in SeqSLAM's local contrast normalisation; 0 (off) by default: on the bundled routes
    # (60-80 snapshots, so +-10 spans a third of the route) it never helped and cost the raw-UV baseline 0.37 of
    # its recall at 100 % precision on the mineral pair
    window: int = 0

    def __post_init__(self) -> None:
        """Check the settings (ValueError)."""
        if self.length < 1:
            raise LocalizeError(f'sequence length must be >= 1, got {self.length}')
        if not 0 <= self.min_speed <= self.max_speed:
            raise LocalizeError(f'need 0 <= min_speed <= max_speed, got {self.min_speed}, {self.max_speed}')
        if self.window < 0:
            raise LocalizeError(f'normalisation window must be >= 0 snapshots (0: off), got {self.window}')

    def offsets(self) -> np.ndarray:
        """Return the snapshot offsets (S, length) of the trajectories: row s, step k back -> round(v_s k)."""
        steps = max(self.length - 1, 1)
        # one speed per whole number of snapshots covered over the sequence, within the speed range: every
        # distinct straight trajectory once (if the range holds no whole number: the one nearest its middle)
        low = math.ceil(self.min_speed * steps - 1e-9)
        high = math.floor(self.max_speed * steps + 1e-9)
        middle = math.floor(0.5 * (self.min_speed + self.max_speed) * steps + 0.5)
        ends = np.arange(low, high + 1) if high >= low else np.array([middle])
        speeds = ends / steps
        offsets = np.rint(speeds[:, None] * np.arange(self.length)[None, :]).astype(np.intp)
        return np.unique(offsets, axis=0)

    def extent(self) -> int:
        """Return the most snapshots a trajectory spans back from its end (max_speed x (length - 1), rounded)."""
        return int(self.offsets().max())


@dataclass(frozen=True)
class Match:
    """One query's match against a map (fields of skynav_msgs/PlaceMatch; index -1 when the map is empty)."""

    index: int
    distance: float  # best snapshot's distance (single frame) or sequence distance (sequence); lower = more alike
    score: float  # what the acceptance test thresholds: the best / runner-up ratio; lower = surer
    accepted: bool
    candidate_indices: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))  # best first
    candidate_distances: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def empty(cls) -> Match:
        """Return the match against an empty map: no index, infinite distance, not accepted."""
        return cls(-1, math.inf, math.inf, False)


# --- single frames ------------------------------------------------------------------------------------------------


def best_candidates(distances: np.ndarray, count: int = DEFAULT_CANDIDATES) -> tuple[np.ndarray, np.ndarray]:
    """Return the `count` snapshot indices of lowest distance (best first) and their distances, from a row (N,)."""
    distances = np.asarray(distances, dtype=float)
    count = min(int(count), distances.size)
    if count <= 0:
        return np.zeros(0, dtype=np.int32), np.zeros(0)
    part = np.argpartition(distances, count - 1)[:count] if count < distances.size else np.arange(distances.size)
    order = part[np.lexsort((part, distances[part]))]  # by distance, ties by index
    return order.astype(np.int32), distances[order]


def runner_up(distances: np.ndarray, best: np.ndarray, exclusion: int) -> np.ndarray:
    """Return per row of distances (Q, N) the least one more than `exclusion` snapshots from best (Q,); inf if none."""
    distances = np.atleast_2d(distances)
    best = np.atleast_1d(best)
    if distances.shape[0] == 1:  # one query (the online path): two slices, no mask
        low, high = int(best[0]) - exclusion, int(best[0]) + exclusion + 1
        row = distances[0]
        return np.array([min(np.min(row[: max(low, 0)], initial=np.inf), np.min(row[high:], initial=np.inf))])
    far = np.abs(np.arange(distances.shape[1])[None, :] - best[:, None]) > exclusion
    return np.min(np.where(far, distances, np.inf), axis=1, initial=np.inf)


def distance_ratio(best: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Return best / runner-up (0 when there is no runner-up, 1 when both are 0: ambiguous)."""
    best, second = np.broadcast_arrays(np.asarray(best, dtype=float), np.asarray(second, dtype=float))
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = np.where(second > 0, best / second, 1.0)
    return np.where(np.isinf(second), 0.0, ratio)


def single_frame(distances: np.ndarray, exclusion: int = DEFAULT_EXCLUSION) -> tuple[np.ndarray, ...]:
    """Return (best index, best distance, ratio score), each (Q,), of distance rows (Q, N) to the snapshots."""
    distances = np.atleast_2d(np.asarray(distances, dtype=float))
    best = np.argmin(distances, axis=1)
    best_distance = distances[np.arange(distances.shape[0]), best]
    return best, best_distance, distance_ratio(best_distance, runner_up(distances, best, exclusion))


# --- SeqSLAM ------------------------------------------------------------------------------------------------------


def contrast_normalise(distances: np.ndarray, window: int) -> np.ndarray:
    """Return distances (..., N) as z-scores against the snapshots of a (2 window + 1)-wide window (std units)."""
    # the window keeps its full width at the ends of the route (it shifts inward), so the first and last snapshots
    # are compared with as many neighbours as any other; a row flat within a window is guarded by MIN_LOCAL_STD
    distances = np.asarray(distances, dtype=float)
    n = distances.shape[-1]
    centred = distances - np.mean(distances, axis=-1, keepdims=True)  # keeps the running sums well conditioned
    zeros = np.zeros(distances.shape[:-1] + (1,))
    sums = np.concatenate([zeros, np.cumsum(centred, axis=-1)], axis=-1)
    squares = np.concatenate([zeros, np.cumsum(centred * centred, axis=-1)], axis=-1)
    width = min(2 * int(window) + 1, n)
    low = np.clip(np.arange(n) - int(window), 0, n - width)
    high = low + width
    mean = (sums[..., high] - sums[..., low]) / width
    variance = (squares[..., high] - squares[..., low]) / width - mean * mean
    std = np.sqrt(np.maximum(variance, 0.0))
    return (centred - mean) / np.maximum(std, MIN_LOCAL_STD)


def _padded(rows: np.ndarray, pad: int) -> np.ndarray:
    """Return rows (..., N) with `pad` copies of their first value in front (trajectories before snapshot 0)."""
    front = np.repeat(rows[..., :1], pad, axis=-1)
    return np.concatenate([front, rows], axis=-1)


def trajectory_scores(values: np.ndarray, params: SequenceParams) -> np.ndarray:
    """Return per query (as the newest) and end snapshot the best mean of values (Q, N) along a trajectory, (Q, N)."""
    values = np.atleast_2d(np.asarray(values, dtype=float))
    queries, n = values.shape
    offsets = params.offsets()
    pad = int(offsets.max())
    padded = _padded(values, pad)
    steps = np.minimum(np.arange(queries) + 1, params.length).astype(float)  # frames available per query
    best = np.full((queries, n), np.inf)
    total = np.empty((queries, n))
    for row in offsets:  # speeds x steps slice additions, each over all queries and snapshots at once
        total[:] = 0.0
        for k, offset in enumerate(row[:queries]):
            total[k:] += padded[: queries - k, pad - offset : pad - offset + n]
        np.minimum(best, total / steps[:, None], out=best)
    return best


def sequence_scores(distances: np.ndarray, params: SequenceParams) -> tuple[np.ndarray, np.ndarray]:
    """Return (sequence distances, choice values), each (Q, N), of distance rows (Q, N) for every query as the newest.

    The sequence distance of snapshot j is the least mean distance along a trajectory ending at j (distance units);
    the choice values are the same over contrast-normalised rows (std units) when params.window > 0, else the
    sequence distances themselves.
    """
    raw = trajectory_scores(distances, params)
    if params.window <= 0:
        return raw, raw
    return raw, trajectory_scores(contrast_normalise(distances, params.window), params)


class SequenceBuffer:
    """The last `length` distance rows of one map (raw and contrast-normalised), for online SeqSLAM (newest last)."""

    def __init__(self, params: SequenceParams) -> None:
        """Start with no queries."""
        self.params = params
        self._offsets = params.offsets()
        self._pad = int(self._offsets.max())
        self._raw: deque[np.ndarray] = deque(maxlen=params.length)
        self._normalised: deque[np.ndarray] = deque(maxlen=params.length)

    def __len__(self) -> int:
        """Return the number of query rows kept (at most the sequence length)."""
        return len(self._raw)

    def clear(self) -> None:
        """Forget every query (after a map switch or a jump)."""
        self._raw.clear()
        self._normalised.clear()

    def _scores(self, rows: deque[np.ndarray], n: int) -> np.ndarray:
        """Return the best mean over the trajectories ending at each snapshot of the kept padded rows, (N,)."""
        newest_first = list(reversed(rows))
        best = np.full(n, np.inf)
        total = np.empty(n)
        pad = self._pad
        for row in self._offsets:  # speeds x kept rows slice additions over all snapshots
            total[:] = 0.0
            for offset, padded in zip(row, newest_first):
                total += padded[pad - offset : pad - offset + n]
            np.minimum(best, total, out=best)
        best /= len(newest_first)
        return best

    def push(self, distances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add the newest query's distance row (N,); return (sequence distances, choice values), each (N,)."""
        distances = np.asarray(distances, dtype=float)
        n = distances.size
        if self._raw and self._raw[-1].size != n + self._pad:
            self.clear()  # the map changed size: old rows no longer line up
        self._raw.append(_padded(distances, self._pad))
        raw = self._scores(self._raw, n)
        if self.params.window <= 0:
            return raw, raw
        self._normalised.append(_padded(contrast_normalise(distances, self.params.window), self._pad))
        return raw, self._scores(self._normalised, n)


def sequence_match(
    distances: np.ndarray, choice: np.ndarray | None = None, exclusion: int = DEFAULT_EXCLUSION
) -> tuple[np.ndarray, ...]:
    """Return (best index, its sequence distance, ratio score), each (Q,), from sequence distances (Q, N).

    The best index minimises `choice` (default: the distances themselves); the ratio is its sequence distance over
    the least sequence distance more than `exclusion` snapshots away. Trajectories ending near the best one run
    through the same places, so callers pass the exclusion widened by SequenceParams.extent().
    """
    distances = np.atleast_2d(np.asarray(distances, dtype=float))
    choice = distances if choice is None else np.atleast_2d(np.asarray(choice, dtype=float))
    best = np.argmin(choice, axis=1)
    best_distance = distances[np.arange(distances.shape[0]), best]
    return best, best_distance, distance_ratio(best_distance, runner_up(distances, best, exclusion))


def view_in_place(
    distances: np.ndarray, place: np.ndarray, exclusion: int = DEFAULT_EXCLUSION
) -> tuple[np.ndarray, ...]:
    """Return the newest views' snapshots within `exclusion` of the places (Q,) their sequences chose, from their own
    distance rows (Q, N): (index, distance, single-frame ratio), each (Q,), and their rows with every snapshot
    outside the place at +inf (Q, N), for the candidates."""
    distances = np.atleast_2d(np.asarray(distances, dtype=float))
    place = np.atleast_1d(place)
    inside = np.abs(np.arange(distances.shape[1])[None, :] - place[:, None]) <= exclusion
    rows = np.where(inside, distances, np.inf)
    index = np.argmin(rows, axis=1)
    distance = distances[np.arange(distances.shape[0]), index]
    return index, distance, distance_ratio(distance, runner_up(distances, index, exclusion)), rows


# --- where the route looks alike ----------------------------------------------------------------------------------


def local_steps(steps: np.ndarray, exclusion: int) -> np.ndarray:
    """Return per snapshot (N,) the route's step there: the median of the distances `steps` (N - 1,) between
    successive snapshots within `exclusion` snapshots of it (distance units; 0 for a map of one snapshot)."""
    steps = np.asarray(steps, dtype=float)
    n = steps.size + 1
    if steps.size == 0:
        return np.zeros(n)
    pad = max(int(exclusion), 1)
    padded = np.concatenate([np.full(pad, np.nan), steps, np.full(pad, np.nan)])
    width = 2 * pad
    windows = np.lib.stride_tricks.sliding_window_view(padded, width)[:n]  # steps j - exclusion .. j + exclusion - 1
    return np.nanmedian(windows, axis=1)


def self_similarity(local_step: np.ndarray, look_alike: np.ndarray) -> np.ndarray:
    """Return the route's step over the distance to the nearest look-alike (snapshots, (N,)): 0 with none, 1 when
    both are 0; lower = a place that stands out."""
    return distance_ratio(local_step, look_alike)


def view_change(rows: np.ndarray, indices: np.ndarray, exclusion: int) -> np.ndarray:
    """Return per snapshot (K,) of the map the view change across `exclusion` snapshots there: the mean distance from
    it to the snapshots `exclusion` before and after it (the one that exists at the route's ends; 0 on a map of at
    most `exclusion` snapshots), from its distance rows (K, N) to every snapshot."""
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    indices = np.atleast_1d(np.asarray(indices, dtype=np.intp))
    n = rows.shape[1]
    total, count = np.zeros(indices.size), np.zeros(indices.size)
    for other in (indices - exclusion, indices + exclusion):
        inside = (other >= 0) & (other < n)
        total[inside] += rows[np.flatnonzero(inside), other[inside]]
        count += inside
    with np.errstate(invalid='ignore'):
        return np.where(count > 0, total / np.maximum(count, 1), 0.0)


def displaced_ratios(rows: np.ndarray, places: np.ndarray, neighbours: np.ndarray, exclusion: int) -> np.ndarray:
    """Return the ratios (K,) at snapshots `places` of their `neighbours` (K,), from the neighbours' distance rows
    (K, N) to every snapshot: the distance to the place over the least distance to a snapshot more than `exclusion`
    from both (0 with none, as distance_ratio)."""
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    places, neighbours = np.atleast_1d(places), np.atleast_1d(neighbours)
    snapshots = np.arange(rows.shape[1])[None, :]
    far = (np.abs(snapshots - places[:, None]) > exclusion) & (np.abs(snapshots - neighbours[:, None]) > exclusion)
    second = np.min(np.where(far, rows, np.inf), axis=1, initial=np.inf)
    return distance_ratio(rows[np.arange(rows.shape[0]), places], second)


class RouteTracker:
    """Where along the route a robot that follows it is, for tracking's window (see the module notes).

    With the route's odometry (the snapshots' distances along it by the teach's odometry, m) and the drive's, the
    *tracked place* (m along the route) is carried on by each view's odometry and pulled towards each accepted match
    by at most TRACKING_PULL of that step: the matches correct the odometry's drift, while a match that stalls (a
    view that keeps resembling a place behind) cannot hold the place back. The window holds the snapshots within
    TRACKING_SLACK + TRACKING_SLIP x the distance driven since the last accepted match of the place. Without
    odometry the window runs from MOTION_SLACK snapshots behind the last accepted match to max_speed snapshots per
    view ahead of it. Either lasts TRACKING_VIEWS views without an accepted match.
    """

    def __init__(self, params: SequenceParams, route: np.ndarray | None, slack: float = MOTION_SLACK) -> None:
        """Track along a route of snapshots at distances `route` (N,) (m; None: no odometry of the teach)."""
        self.params, self.route, self.slack = params, route, slack
        self.reset()

    def reset(self) -> None:
        """Forget where the robot is: the next window is the whole route."""
        self.anchor = -1  # the last accepted snapshot
        self.views = 0  # views since
        self.since = 0.0  # m of odometry since
        self.place: float | None = None  # the tracked place, m along the route
        self.travelled: float | None = None  # the drive's odometry path length at the previous view, m

    def start_at(self, index: int) -> None:
        """Place the robot at snapshot `index` (where a FollowRoute goal starts) as if a match there had been accepted:
        the first window is near it."""
        self.reset()
        self.anchor = index
        self.place = None if self.route is None else float(self.route[index])

    def _step(self, travelled: float | None) -> float | None:
        """Return the odometry's step (m) from the previous view to this one; None without odometry."""
        if travelled is None or self.travelled is None:
            return None
        return max(travelled - self.travelled, 0.0)

    def window(self, travelled: float | None) -> tuple[int, int] | None:
        """Return the snapshots (first, last) to seek a view in (odometry path length then, m); None: everywhere."""
        if self.anchor < 0 or self.views >= TRACKING_VIEWS:
            return None
        step = self._step(travelled)
        if self.route is None or self.place is None or step is None:
            return self.anchor - math.ceil(self.slack), self.anchor + math.ceil(
                self.params.max_speed * (self.views + 1) + self.slack
            )
        expected = self.place + step
        reach = TRACKING_SLACK + TRACKING_SLIP * (self.since + step)
        last_snapshot = self.route.size - 1
        first = min(int(np.searchsorted(self.route, expected - reach, side='left')), last_snapshot)
        last = int(np.searchsorted(self.route, expected + reach, side='right')) - 1
        return first, max(last, first)

    def update(self, index: int, accepted: bool, travelled: float | None) -> None:
        """Take the view's match (snapshot index, whether accepted) and odometry path length (m, None without)."""
        step = self._step(travelled)
        expected = None if self.place is None or step is None else self.place + step
        if accepted:
            if expected is None or self.route is None or step is None:
                self.place = None if self.route is None or travelled is None else float(self.route[index])
            else:
                pull = TRACKING_PULL * step
                self.place = expected + float(np.clip(self.route[index] - expected, -pull, pull))
            self.anchor, self.views, self.since = index, 0, 0.0
        else:
            self.place = expected
            self.views += 1
            self.since += step or 0.0
        self.travelled = travelled

    def nearest(self) -> int | None:
        """Return the snapshot nearest the tracked place; None without one (no odometry, nothing accepted)."""
        if self.place is None or self.route is None:
            return None
        return int(np.argmin(np.abs(self.route - self.place)))


def motion_window(params: SequenceParams, slack: float = MOTION_SLACK) -> int:
    """Return how many views back the motion tests look: a sequence's, and at least twice the views over which the
    slack hides a robot that stands still (2 slack / min_speed)."""
    back = params.length - 1
    if params.min_speed <= 0:
        return back
    return max(back, math.ceil(2.0 * slack / params.min_speed - 1e-9))


def motion_tests(
    indices: np.ndarray, vouched: np.ndarray, params: SequenceParams, slack: float = MOTION_SLACK
) -> tuple[np.ndarray, np.ndarray]:
    """Return per view (Q,), from the matched snapshot indices (Q,) and which views vouched for theirs, in order:
    (consistent, steady), each bool (Q,).

    consistent: the view's index lies at least min_speed k - slack snapshots ahead of the index of each vouched
    view k = 1 .. motion_window() views before it (no upper bound: a robot may drive faster than a sequence
    assumes, and the view's choice within a place follows it). steady: with the length - 1 views before it, at
    least three quarters of a sequence's views vouched, and the least-squares slope of their indices over time lies
    within min_speed..max_speed (snapshots per view). A view with fewer views before it is consistent with what
    there is, and not steady.
    """
    indices = np.asarray(indices, dtype=float)
    vouched = np.asarray(vouched, dtype=bool)
    count = indices.size
    consistent = np.ones(count, dtype=bool)
    for k in range(1, min(motion_window(params, slack), count - 1) + 1):  # each lag over all views at once
        step = indices[k:] - indices[:-k]
        consistent[k:] &= (step >= params.min_speed * k - slack) | ~vouched[:-k]
    back = params.length - 1
    steady = np.zeros(count, dtype=bool)
    if back >= 1 and count > back:
        # each window: the views of a sequence ending at one view; the slope fitted to its vouched ones
        weights = np.lib.stride_tricks.sliding_window_view(vouched, back + 1).astype(float)
        values = np.lib.stride_tricks.sliding_window_view(indices, back + 1)
        frames = np.arange(back + 1, dtype=float)
        total = weights.sum(axis=1)
        with np.errstate(divide='ignore', invalid='ignore'):
            centred = frames[None, :] - ((weights @ frames) / total)[:, None]
            slope = np.sum(weights * centred * values, axis=1) / np.sum(weights * centred * centred, axis=1)
        enough = 4 * total >= 3 * (back + 1)
        steady[back:] = enough & (slope >= params.min_speed) & (slope <= params.max_speed)
    return consistent, steady
