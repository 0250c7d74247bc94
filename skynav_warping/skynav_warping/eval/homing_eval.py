# SPDX-License-Identifier: Apache-2.0
"""Homing on a recorded grid, measured as the node graph runs: every method's home vectors against ground truth.

The input is a recording's views as the skyline and SH nodes produce them (skynav_core.views.recording_views, with
the skyline node's masks): SH coefficients of the skyline mask (fill 'zero'), the mask itself and the ground-truth
pose of camera_link in map. The snapshot is the recording's frame labelled 'snapshot' (else its first frame) or a
map snapshot with a ground-truth pose. Methods:

- '3d-warping': the compass (skynav_compass, as its node runs) estimates the rotation, and 3D-warping starts its
  search there, as the warping node does with use_compass;
- '3d-warping-no-compass': 3D-warping with its own rotational pre-alignment;
- '2d-warping', 'min-warping': the planar baselines on panoramic bands unwrapped from the skyline node's masks;
  they need the snapshot's mask, so they run only when the snapshot is a frame of the recording.

3D-warping's direction is the optimum's (best_direction), also when it is not confident; the node publishes only the
confident ones (the others' direction the views do not determine). The table's `confident` column is the share the
node would publish, `off >30 deg` how many of those are off by more than MISS_DEG, and of how many.
Times are CPU seconds (time.process_time, all threads of the process) of
one estimate from the node's input: preparing the current view and estimating, plus the snapshot's preparation
spread over all estimates; tables built once per process (compass grid, warping tables, panorama remaps) and the
skyline and SH nodes are not counted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from skynav_compass import Compass, CompassView
from skynav_core.evaluation import Column, text_table, unknown_methods
from skynav_warping.errors import WarpingError
from skynav_warping.eval.evaluation import (
    DISTANCE_BINS,
    angular_errors,
    binned_statistics,
    home_vectors_in_map,
    quiver_plot,
    tilt_angles,
    true_home_directions,
)
from skynav_warping.eval.methods import METHODS, PANORAMA_METHODS
from skynav_warping.eval.panorama import PanoramaUnwrapper
from skynav_warping.eval.planar import min_warping, warping_2d
from skynav_warping.homing import estimate_home_vector
from skynav_warping.views import view_from_coefficients
from skynav_warping.warping3d import WarpingSettings

EVAL_TILT_BINS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0))  # degrees
MIN_DISTANCE = 0.05  # m: views nearer the snapshot than this have no defined home direction and are left out
MISS_DEG = 30.0  # deg: a home vector off by more than this is a miss (the table counts those the node publishes)


class HomingEvalError(WarpingError):
    """Input the evaluation cannot use (no ground truth, no snapshot, an unknown method); one line of message."""


@dataclass(frozen=True)
class HomingSnapshot:
    """The snapshot homed to: its SH coefficients, ground-truth pose and, when it is a recorded frame, its mask."""

    coefficients: np.ndarray  # real SH of the skyline mask, fill 'zero'
    pose: np.ndarray  # (x, y, z, qx, qy, qz, qw) of camera_link in map
    mask: np.ndarray | None  # the skyline node's mask (uint8, 255 sky); None for a map snapshot not in the recording
    name: str  # e.g. "frame 0 ('snapshot')" or "map 'park' snapshot 0"
    stamp: int | None = None  # ns; the recording frame of that stamp is not a current view


@dataclass(frozen=True)
class HomingResult:
    """One homing method's home vectors (current camera_link) over the evaluated views and its CPU time per estimate."""

    name: str
    directions: np.ndarray  # (N, 3) unit vectors
    seconds: float  # CPU s per estimate
    confident: np.ndarray | None = None  # (N,) bool, 3D-warping only


@dataclass(frozen=True)
class HomingEvaluation:
    """Home vectors of every method against the true ones, with what is needed for tables and plots."""

    snapshot: HomingSnapshot
    positions: np.ndarray  # (N, 3) current camera_link in map
    quaternions: np.ndarray  # (N, 4) (x, y, z, w)
    true_directions: np.ndarray  # (N, 3) in the current camera_link
    distances: np.ndarray  # (N,) m to the snapshot's place
    tilts: np.ndarray  # (N,) degrees of the current camera_link from the vertical
    results: dict[str, HomingResult]
    skipped: dict[str, str] = field(default_factory=dict)  # method -> why it did not run
    left_out: int = 0  # views with a pose nearer the snapshot than MIN_DISTANCE
    synthetic: bool = False

    def errors(self, method: str) -> np.ndarray:
        """Return the angular errors (degrees) of one method's home vectors, (N,)."""
        return angular_errors(self.results[method].directions, self.true_directions)

    def statistics(self, method: str) -> dict[str, tuple[int, float, float]]:
        """Return {bin label: (count, median, p90)} of a method's errors (degrees) per distance bin, all, tilt bin.

        Tilt bins without views are left out.
        """
        errors = self.errors(method)
        out = {}
        for s in binned_statistics(errors, self.distances, DISTANCE_BINS):
            out[f'{s.low:g}-{s.high:g} m'] = (s.count, s.median, s.p90)
        s = binned_statistics(errors, np.zeros(len(errors)), [(-1.0, 1.0)])[0]
        out['all'] = (s.count, s.median, s.p90)
        for s in binned_statistics(errors, self.tilts, EVAL_TILT_BINS):
            if np.any((self.tilts >= s.low) & (self.tilts < s.high)):
                out[f'tilt {s.low:g}-{s.high:g} deg'] = (s.count, s.median, s.p90)
        return out

    def median(self, method: str, low: float = 0.5, high: float = 4.0) -> float:
        """Return a method's median error (degrees) over views from low to high metres away."""
        chosen = (self.distances >= low) & (self.distances < high)
        return float(np.nanmedian(self.errors(method)[chosen])) if np.any(chosen) else float('nan')

    def table(self) -> str:
        """Return the text table: per method, median / p90 error per distance and tilt bin, ms per estimate."""
        if not self.results:
            return '(no method ran)'
        first = self.statistics(next(iter(self.results)))
        labels = list(first)
        width = 15
        columns = (
            Column('method', max(22, max(len(m) for m in self.results) + 2), align='<'),
            *(Column(label, width) for label in labels),
            Column('ms/estimate', width - 1, '.1f'),
            Column('confident', 11),
            Column(f'off >{MISS_DEG:g} deg', 15),
        )
        rows: list[list] = [['', *(f'(n={first[label][0]})' for label in labels)]]
        for method, result in self.results.items():
            cells = [self.statistics(method)[label] for label in labels]
            confident = '-' if result.confident is None else f'{100.0 * np.mean(result.confident):.0f} %'
            published = np.ones(len(result.directions), bool) if result.confident is None else result.confident
            missed = int(np.count_nonzero(self.errors(method)[published] > MISS_DEG))
            rows.append(
                [
                    method,
                    *(f'{median:.1f} / {p90:.1f}' if np.isfinite(median) else '-' for _, median, p90 in cells),
                    1e3 * result.seconds,
                    confident,
                    f'{missed} of {int(np.count_nonzero(published))}',
                ]
            )
        return text_table(columns, rows, gap='', rule=False)

    def quiver(self, path, title: str) -> str:
        """Save the quiver plot (true and estimated home vectors, map x-y) as PNG at path; return its title."""
        estimates = {m: home_vectors_in_map(r.directions, self.quaternions) for m, r in self.results.items()}
        return quiver_plot(
            str(path),
            self.positions,
            self.snapshot.pose[:3],
            home_vectors_in_map(self.true_directions, self.quaternions),
            estimates,
            title,
            synthetic=self.synthetic,
        )


def recording_snapshot(recording) -> HomingSnapshot:
    """Return the recording's frame labelled 'snapshot' (else its first frame with a pose) as the snapshot."""
    posed = [(k, v) for k, v in enumerate(recording.views) if v.pose is not None]
    if not posed:
        raise HomingEvalError(f'{recording.path}: no ground-truth poses (/ground_truth/pose) to evaluate against')
    labelled = [(k, v) for k, v in posed if v.label == 'snapshot']
    k, view = (labelled or posed)[0]
    name = f"frame {k} ('snapshot')" if labelled else f'frame {k} (the first; no frame is labelled snapshot)'
    return HomingSnapshot(
        np.asarray(view.coefficients, float), np.asarray(view.pose, float), view.mask, name, view.stamp
    )


def map_snapshot(store, index: int, recording=None) -> HomingSnapshot:
    """Return snapshot `index` of an open MapStore; its mask when the recording holds the frame of its stamp."""
    if not 0 <= index < len(store):
        raise HomingEvalError(f'{store.path}: no snapshot {index} (the map has {len(store)})')
    snapshot = store.snapshot(index)
    if snapshot.pose is None:
        raise HomingEvalError(
            f'{store.path}: snapshot {index} has no ground-truth pose, so the true home direction is unknown'
        )
    mask = None
    if recording is not None:
        same = [v for v in recording.views if v.stamp == snapshot.stamp_ns]
        mask = same[0].mask if same else None
    return HomingSnapshot(
        np.asarray(snapshot.coefficients, float),
        np.asarray(snapshot.pose, float),
        mask,
        f'map {store.name!r} snapshot {index}',
        snapshot.stamp_ns,
    )


def _timed(function, *args):
    """Return (function(*args), CPU seconds it took)."""
    start = time.process_time()
    value = function(*args)
    return value, time.process_time() - start


def _prepared(function, snapshot_item, items):
    """Return (snapshot's prepared view, current ones, CPU seconds for all of them)."""
    prepared_snapshot, seconds = _timed(function, snapshot_item)
    current, spent = _timed_runs(function, items)
    return prepared_snapshot, current, seconds + spent


def evaluate_homing(
    recording,
    methods=METHODS,
    snapshot: HomingSnapshot | None = None,
    settings: WarpingSettings = WarpingSettings(),
    progress=None,
) -> HomingEvaluation:
    """Return every method's home vectors for the recording's views (skynav_core.views.RecordingViews) to a snapshot.

    snapshot: None for the recording's own (recording_snapshot). The current views are all views with a ground-truth
    pose except the snapshot's frame and any nearer its place than MIN_DISTANCE. progress(k) is called per method
    and view, if given. HomingEvalError for input that cannot be evaluated.
    """

    if problem := unknown_methods(methods, METHODS):
        raise HomingEvalError(problem)
    methods = [m for m in METHODS if m in methods]
    snapshot = recording_snapshot(recording) if snapshot is None else snapshot
    if recording.camera is None:
        raise HomingEvalError(f'{recording.path}: no camera info')
    candidates = [v for v in recording.views if v.pose is not None and v.stamp != snapshot.stamp]
    if not candidates:
        raise HomingEvalError(f'{recording.path}: no views with a ground-truth pose besides the snapshot')
    poses = np.array([v.pose for v in candidates], dtype=float)
    distances = np.linalg.norm(poses[:, :3] - snapshot.pose[:3], axis=1)
    keep = distances >= MIN_DISTANCE
    views = [v for v, k in zip(candidates, keep) if k]
    if not views:
        raise HomingEvalError(f'{recording.path}: every view lies within {MIN_DISTANCE} m of the snapshot')
    poses, distances = poses[keep], distances[keep]
    degree = settings.degree
    low = [v for v in views if np.size(v.coefficients) < (degree + 1) ** 2]
    if low or np.size(snapshot.coefficients) < (degree + 1) ** 2:
        raise HomingEvalError(
            f'coefficients of degree below {degree}; the compass and warping nodes need {degree} '
            "(the sh node's max_degree)"
        )
    field_of_view = float(recording.camera.field_of_view)
    skipped = {}
    if snapshot.mask is None or any(v.mask is None for v in views):
        why = (
            'the snapshot is not a frame of this recording'
            if snapshot.mask is None
            else 'the skyline node gave no mask for some views'
        )
        skipped = {
            m: f"needs the snapshot's and the views' skyline masks; {why}" for m in methods if m in PANORAMA_METHODS
        }
        methods = [m for m in methods if m not in skipped]

    results: dict[str, HomingResult] = {}
    n = len(views)
    if any(m.startswith('3d-warping') for m in methods):

        def warp_view(coefficients):
            return view_from_coefficients(coefficients, field_of_view, degree)

        warp_snapshot, warp_views, warp_seconds = _prepared(
            warp_view, snapshot.coefficients, [v.coefficients for v in views]
        )
    if '3d-warping' in methods:
        compass = Compass(degree)  # tables built here, as the node does at start

        def compass_view(coefficients):
            return CompassView.from_sh_message(coefficients, field_of_view, 'zero', degree)

        compass_snapshot, compass_views, compass_seconds = _prepared(
            compass_view, snapshot.coefficients, [v.coefficients for v in views]
        )

        def with_compass(k):
            rotation = compass.estimate(compass_snapshot, compass_views[k]).quaternion
            return estimate_home_vector(warp_views[k], warp_snapshot, rotation, settings)

        results['3d-warping'] = _run_warping('3d-warping', with_compass, n, warp_seconds + compass_seconds, progress)
    if '3d-warping-no-compass' in methods:

        def without_compass(k):
            return estimate_home_vector(warp_views[k], warp_snapshot, None, settings)

        results['3d-warping-no-compass'] = _run_warping(
            '3d-warping-no-compass', without_compass, n, warp_seconds, progress
        )
    if any(m in PANORAMA_METHODS for m in methods):
        unwrapper = PanoramaUnwrapper(recording.camera)  # remap tables built once per camera
        band_snapshot, bands, band_seconds = _prepared(unwrapper, snapshot.mask, [v.mask for v in views])
        planar = {
            '2d-warping': lambda band: warping_2d(band_snapshot, band),
            'min-warping': lambda band: min_warping(band_snapshot, band, unwrapper.elevations),
        }
        for method in (m for m in methods if m in PANORAMA_METHODS):
            estimates, seconds = _timed_runs(planar[method], bands, progress)
            results[method] = HomingResult(
                method, np.array([e.direction for e in estimates]), (band_seconds + seconds) / n
            )
    return HomingEvaluation(
        snapshot=snapshot,
        positions=poses[:, :3],
        quaternions=poses[:, 3:],
        true_directions=true_home_directions(poses[:, :3], poses[:, 3:], snapshot.pose[:3]),
        distances=distances,
        tilts=tilt_angles(poses[:, 3:]),
        results=results,
        skipped=skipped,
        left_out=int(np.count_nonzero(~keep)),
        synthetic=bool(recording.synthetic),
    )


def _run_warping(name: str, estimate, n: int, preparation: float, progress) -> HomingResult:
    """Return a 3D-warping method's result over n views: estimate(k) -> HomeEstimate, after one untimed warm-up."""
    estimate(0)  # builds the warping tables (cached per settings), as the node's first view would
    estimates, seconds = _timed_runs(estimate, range(n), progress)
    return HomingResult(
        name,
        np.array([e.best_direction for e in estimates]),
        (preparation + seconds) / n,
        np.array([e.confident for e in estimates]),
    )


def _timed_runs(function, items, progress=None) -> tuple[list, float]:
    """Return function(item) of every item and the CPU seconds they took together; progress(1) after each."""
    values, seconds = [], 0.0
    for item in items:
        value, spent = _timed(function, item)
        values.append(value)
        seconds += spent
        if progress is not None:
            progress(1)
    return values, seconds
