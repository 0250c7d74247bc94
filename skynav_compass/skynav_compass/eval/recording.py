# SPDX-License-Identifier: Apache-2.0
"""The compass measured on a recording as the node graph sees it: the skyline and SH nodes' output, ground truth.

`evaluate_recording` runs the installed skyline and SH nodes over a recording in this process (skynav_core.views,
the same code and parameters as `skynav run`), turns each /skyline/sh output into a CompassView
(CompassView.from_sh_message with the SH node's fill and field of view), and compares every view against one
snapshot with each method. The snapshot is the recording's frame labelled 'reference' (else its first frame with a
ground-truth pose) or given from outside (a map snapshot's coefficients and pose). The true rotation of a view is
Q_s^-1 Q_c from the ground-truth orientations of camera_link (docs/interfaces.md), its translation the distance between
the two positions. Views split into pure rotations and moved views: by the synthetic recording's frame labels when
the snapshot is its reference frame, otherwise by the true translation (under / from MOVED_FROM_M on).

Methods: the SH ones run on the node's coefficients (every view prepared once; the fft-* and exhaustive-* compasses
also prepare the snapshot once, as the compass node compares many views against one snapshot); the image peers
(yaw-only panorama of the skyline node's mask, SIFT / ORB on the UV image) need the snapshot's images, so they run
only against the recording's own reference frame. Times are CPU time per estimate.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from skynav_compass.errors import CompassError
from skynav_compass.eval.dataset import true_rotation
from skynav_compass.eval.evaluation import (
    CONFIDENT_COLUMNS,
    RIGHT_DEG,
    STATISTICS_COLUMNS,
    CompassResult,
    ErrorStatistics,
    confident_cells,
    error_statistics,
    relative_tilt,
    share_cell,
    summary_rows,
)
from skynav_compass.eval.methods import DEFAULT_METHODS, METHODS, NODE_METHODS
from skynav_compass.eval.runner import Method, NodeViews, build_method, compass_result, timed_estimates
from skynav_core.evaluation import Column, text_table, unknown_methods
from skynav_core.rotations import MAX_TILT
from skynav_core.views import recording_views

GROUPS = ('rotation', 'moved')  # pure rotations, views moved against the snapshot
GROUP_TITLES = {'rotation': 'pure rotations', 'moved': 'moved views'}
MOVED_FROM_M = 0.05  # without frame labels, a view this far (m) or farther from the snapshot counts as moved


class EvaluationError(CompassError):
    """A recording, snapshot or method choice the evaluation cannot use; the message says why in one line."""


@dataclass(frozen=True)
class ExternalSnapshot:
    """A snapshot from outside the recording (a map's): SH coefficients as the SH node made them, and its pose."""

    coefficients: np.ndarray  # real SH, (L+1)^2
    pose: np.ndarray  # (x, y, z, qx, qy, qz, qw) of camera_link in map
    name: str  # how the output names it, e.g. "snapshot 0 of map 'garden'"


@dataclass
class RecordingEvaluation:
    """Every method's angular errors against ground truth on the views of one recording, and how they were got."""

    path: Path
    synthetic: bool
    max_degree: int  # SH degree L of the compasses
    snapshot: str  # what the views were compared against
    stamps: np.ndarray  # (Q,) ns of the compared views
    tilts: np.ndarray  # (Q,) deg, true relative tilt against the snapshot
    translations: np.ndarray  # (Q,) m, true distance from the snapshot
    groups: dict[str, np.ndarray]  # 'rotation', 'moved' -> (Q,) bool
    grouped_by: str  # 'labels' or 'translation'
    results: list[CompassResult]  # errors (deg) and CPU seconds per estimate, per method
    skipped: dict[str, str] = field(default_factory=dict)  # method -> why it did not run
    snapshot_seconds: dict[str, float] = field(default_factory=dict)  # method -> preparing the snapshot once (s)

    def rows(self) -> list[dict]:
        """Return one summary row per method and group (see evaluation.summary_rows)."""
        return summary_rows(self.results, self.groups)

    def result(self, method: str) -> CompassResult:
        """Return one method's result (KeyError if it did not run)."""
        for result in self.results:
            if result.method == method:
                return result
        raise KeyError(method)

    def statistics(self, method: str, group: str) -> ErrorStatistics:
        """Return the error statistics (deg) of one method on one group of views ('rotation' or 'moved')."""
        return error_statistics(self.result(method).errors[self.groups[group]])

    def milliseconds(self, method: str, group: str | None = None) -> float:
        """Return the median CPU time per estimate (ms) of one method, on one group or on all views."""
        seconds = self.result(method).seconds
        selected = seconds if group is None else seconds[self.groups[group]]
        return 1e3 * float(np.median(selected)) if selected.size else float('nan')


def check_node_methods(names: Sequence[str]) -> None:
    """Raise EvaluationError naming every method the SH node's views cannot serve (methods.NODE_METHODS)."""
    if problem := unknown_methods(names, NODE_METHODS):
        raise EvaluationError(problem)


def recording_methods(
    camera,
    max_degree: int,
    field_of_view: float,
    fill: str = 'zero',
    names: Sequence[str] = DEFAULT_METHODS,
    max_tilt: float | None = MAX_TILT,
) -> list[Method]:
    """Return the named methods for views of the SH node (skynav_core.views.View): prepare(view) -> its input.

    field_of_view (rad) and fill: as the SH node made the coefficients (its ShCoefficients fields); max_tilt (rad):
    the tilt bound of the fft-masked and fft-zero compasses (the compass node's `max_tilt_deg`).
    """
    check_node_methods(names)
    views = NodeViews(max_degree, field_of_view, fill)
    return [build_method(METHODS[name], views, max_degree, camera, max_tilt) for name in names]


def evaluate_views(
    recording,
    methods: Sequence[str] = DEFAULT_METHODS,
    snapshot: ExternalSnapshot | None = None,
    fill: str = 'zero',
    field_of_view: float | None = None,
    clock: Callable[[], float] = time.process_time,
    repeats: int = 1,
    max_tilt: float | None = MAX_TILT,
) -> RecordingEvaluation:
    """Return every method's errors on the views of a recording (skynav_core.views.RecordingViews) against a snapshot.

    snapshot None: the recording's frame labelled 'reference' (else its first frame with a pose). fill and
    field_of_view (rad; default the camera's): how the SH node made the coefficients. max_tilt (rad): the tilt bound
    of the fft-masked and fft-zero compasses.
    """
    check_node_methods(methods)
    if not methods:
        raise EvaluationError('no method to evaluate')
    path = Path(recording.path)
    views = [v for v in recording.views if v.pose is not None]
    if not recording.views:
        raise EvaluationError(f'{path}: the skyline and SH nodes produced no SH coefficients')
    if not views:
        raise EvaluationError(f'{path}: no /ground_truth/pose to evaluate against')
    camera = recording.camera
    if field_of_view is None or field_of_view <= 0:
        field_of_view = camera.field_of_view
    field_of_view = min(float(field_of_view), camera.field_of_view)
    camera = camera.with_fov_limit(field_of_view)
    node_degree = min(v.max_degree for v in views)
    skipped: dict[str, str] = {}
    if snapshot is None:
        labelled = [k for k, v in enumerate(views) if v.label == 'reference']
        reference = labelled[0] if labelled else 0
        snapshot_view = views[reference]
        queries = [v for k, v in enumerate(views) if k != reference]
        degree = node_degree
        snapshot_pose = snapshot_view.pose
        name = (
            f"the recording's reference frame ({reference})"
            if labelled
            else "the recording's first frame (it labels none 'reference')"
        )
        by_labels = all(v.label in ('rotation', 'translation') for v in queries)
    else:
        coefficients = np.asarray(snapshot.coefficients, dtype=float)
        map_degree = int(round(np.sqrt(coefficients.size))) - 1
        if (map_degree + 1) ** 2 != coefficients.size:
            raise EvaluationError(f'{snapshot.name}: {coefficients.size} SH coefficients are no (L+1)^2')
        degree = min(node_degree, map_degree)
        snapshot_view = _SnapshotView(coefficients)
        snapshot_pose = np.asarray(snapshot.pose, dtype=float)
        queries = views
        name = snapshot.name
        by_labels = False
        for method in (m for m in methods if METHODS[m].needs_images):
            skipped[method] = "needs the snapshot's images; runs only against the recording's reference frame"
        methods = [m for m in methods if not METHODS[m].needs_images]
        if not methods:
            raise EvaluationError(
                f"every chosen method needs the snapshot's images, which {snapshot.name} lacks; "
                'choose an SH method (or no map)'
            )
    if not queries:
        raise EvaluationError(f'{path}: no view with ground truth to compare against {name}')
    compared = {METHODS[m].view for m in methods}
    if 'image' in compared and any(v.uv is None for v in [snapshot_view, *queries]):
        raise EvaluationError(f'{path}: the image methods need the UV images of the recording')
    if 'mask' in compared and any(v.mask is None for v in [snapshot_view, *queries]):
        raise EvaluationError(f'{path}: the panorama compass needs the skyline masks of the recording')

    truth = true_rotation(snapshot_pose[3:], np.array([v.pose[3:] for v in queries]))
    tilts = relative_tilt(truth)
    translations = np.linalg.norm(np.array([v.pose[:3] for v in queries]) - snapshot_pose[:3], axis=1)
    if by_labels:
        rotation = np.array([v.label == 'rotation' for v in queries])
    else:
        rotation = translations < MOVED_FROM_M
    chosen = recording_methods(camera, degree, field_of_view, fill, methods, max_tilt)
    prepared = [[method.prepare(v) for v in [snapshot_view, *queries]] for method in chosen]
    estimates, seconds, snapshot_seconds = timed_estimates(
        chosen, [p[0] for p in prepared], [p[1:] for p in prepared], clock, repeats
    )
    results = [compass_result(method.name, estimates[k], truth, seconds[k]) for k, method in enumerate(chosen)]
    return RecordingEvaluation(
        path,
        bool(recording.synthetic),
        degree,
        name,
        np.array([v.stamp for v in queries]),
        tilts,
        translations,
        {'rotation': rotation, 'moved': ~rotation},
        'labels' if by_labels else 'translation',
        results,
        skipped,
        {m.name: float(s) for m, s in zip(chosen, snapshot_seconds) if m.prepare_snapshot},
    )


@dataclass(frozen=True)
class _SnapshotView:
    """A snapshot known only by its SH coefficients (a map's): the fields of skynav_core.views.View methods read."""

    coefficients: np.ndarray
    uv: Any = None
    mask: Any = None


def evaluate_recording(
    path: str | Path,
    methods: Sequence[str] = DEFAULT_METHODS,
    snapshot: ExternalSnapshot | None = None,
    ros_args: list[str] | None = None,
    clock: Callable[[], float] = time.process_time,
    repeats: int = 1,
    max_tilt: float | None = MAX_TILT,
) -> RecordingEvaluation:
    """Run the skyline and SH nodes over a recording (node parameters from ros_args) and evaluate the compass on it.

    See evaluate_views; the SH node's fill and field of view come from the parameter files in ros_args.
    """

    check_node_methods(methods)
    images = snapshot is None and any(METHODS[m].needs_images for m in methods)
    masks = snapshot is None and any(METHODS[m].view == 'mask' for m in methods)
    recording = recording_views(path, ros_args, images=images, masks=masks)
    settings = sh_node_settings(ros_args)
    fill = str(settings.get('fill', 'zero'))
    field_of_view = np.radians(float(settings.get('field_of_view_deg', 0.0) or 0.0))
    return evaluate_views(recording, methods, snapshot, fill, field_of_view or None, clock, repeats, max_tilt)


def sh_node_settings(ros_args: Sequence[str] | None) -> dict:
    """Return the SH node's parameters set in the --params-file files of ROS arguments (later files win)."""

    settings: dict = {}
    args = list(ros_args or [])
    files = [args[k + 1] for k, arg in enumerate(args[:-1]) if arg == '--params-file']
    for name in files:
        try:
            document = yaml.safe_load(Path(name).read_text()) or {}
        except (OSError, yaml.YAMLError):
            continue  # the graph itself reports unreadable parameter files
        if not isinstance(document, dict):
            continue
        for key in ('/**', '**', 'sh', '/sh'):
            section = document.get(key)
            if isinstance(section, dict) and isinstance(section.get('ros__parameters'), dict):
                settings.update(section['ros__parameters'])
    return settings


def format_report(evaluation: RecordingEvaluation) -> str:
    """Return the evaluation as text: what was compared, then one table per group of views, then skipped methods."""
    e = evaluation
    kind = ' (synthetic)' if e.synthetic else ''
    prepared = [m for m in e.snapshot_seconds]
    lines = [
        f'{e.path.name}{kind}: {len(e.stamps)} views from the skyline and SH nodes (SH degree {e.max_degree}) '
        f'against {e.snapshot}',
        'error: 3D rotation error against ground truth (deg); ms: CPU time per estimate'
        + (f' (snapshot prepared once for {", ".join(prepared)})' if prepared else ''),
        'sure: the share of estimates marked confident; s.med, s.max: the median and worst error among those '
        '(deg; -: none)',
    ]
    columns: tuple[Column, ...] = (
        Column('method', 26, align='<'),
        *STATISTICS_COLUMNS,
        Column('<2deg', 6),
        *CONFIDENT_COLUMNS,
        Column('ms', 8, '.2f'),
    )
    for group in GROUPS:
        selection = e.groups[group]
        count = int(np.sum(selection))
        how = (
            'frame labels'
            if e.grouped_by == 'labels'
            else (
                f'under {MOVED_FROM_M:g} m from the snapshot'
                if group == 'rotation'
                else f'{MOVED_FROM_M:g} m or more from the snapshot'
            )
        )
        lines.append('')
        if not count:
            lines.append(f'{GROUP_TITLES[group]}: none ({how})')
            continue
        lines.append(
            f'{GROUP_TITLES[group]}: {count} views ({how}); tilt {e.tilts[selection].min():.0f}-'
            f'{e.tilts[selection].max():.0f} deg, translation {e.translations[selection].min():.2f}-'
            f'{e.translations[selection].max():.2f} m'
        )
        rows: list[tuple[Any, ...]] = []  # one per method: its name, then the columns' values
        for result in e.results:
            s = e.statistics(result.method, group)
            rows.append(
                (
                    result.method,
                    s.count,
                    s.median,
                    s.p90,
                    s.max,
                    share_cell(s.share_under),
                    *confident_cells(result.confident_statistics(selection)),
                    e.milliseconds(result.method, group),
                )
            )
        lines.append(text_table(columns, rows))
    lines += [
        '',
        f'all {len(e.stamps)} views; AUC: how well the confidence ranks estimates under {RIGHT_DEG:g} deg of '
        'error above the others (1: perfectly, 0.5: by chance, -: all on one side;',
        'without a confidence: by the residual); tilt: the most any estimate tilts the views apart (deg)',
    ]
    columns = (
        Column('method', 26, align='<'),
        *STATISTICS_COLUMNS,
        Column(f'<{RIGHT_DEG:g}deg', 6),
        *CONFIDENT_COLUMNS,
        Column('AUC', 6, '.3f'),
        Column('tilt', 6, '.1f'),
    )
    rows = []
    for result in e.results:
        s = error_statistics(result.errors)
        share = float(np.mean(np.where(np.isfinite(result.errors), result.errors, 180.0) < RIGHT_DEG))
        auc = result.separation()
        tilt = float(np.max(result.tilts)) if result.tilts is not None and result.tilts.size else float('nan')
        rows.append(
            (
                result.method,
                s.count,
                s.median,
                s.p90,
                s.max,
                share_cell(share),
                *confident_cells(result.confident_statistics()),
                '-' if np.isnan(auc) else auc,
                tilt,
            )
        )
    lines.append(text_table(columns, rows))
    for method, reason in e.skipped.items():
        lines.append(f'skipped {method}: {reason}')
    return '\n'.join(lines)
