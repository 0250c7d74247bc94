# SPDX-License-Identifier: Apache-2.0
"""Measure the visual 3D compass on a recording against ground truth: skynav's compass and its peers, side by side.

Every frame of the recording goes through the skyline and SH nodes (as in `skynav run`); each method then
estimates the rotation of every view against one snapshot: by default the recording's frame labelled 'reference'
(the bundled compass sets, `skynav sim bag compass`), with --map the map snapshot --index. The error of an estimate
is the angle of the 3D rotation between it and the truth Q_s^-1 Q_c from the ground-truth orientations of
camera_link. Prints, per method, median, 90th percentile and maximum error, the share under 2 degrees and the
share of estimates the method marks confident with the median and worst error among those (sure, s.med, s.max),
separately for pure rotations and for moved views (by the frame labels of a synthetic compass set against its
reference frame, else by the true translation: under / from 0.05 m on), and the CPU time per estimate (views
prepared once; the fft-* and exhaustive-* compasses prepare the snapshot once, as the compass node does). Then, over
all views, how well each method's confidence (without one: its residual) ranks the estimates under 5 degrees of
error above the others (the area under the ROC curve) and the largest tilt between the views any estimate claims.
Saves a plot of error against tilt and against translation as DIR/<bag name>_errors.png.

Methods: fft-masked (the default compass: SO(3) correlation by FFT on the masked cost within the tilt bound
--max-tilt, hypotheses verified on samples of the two masks, then Newton refinement), fft-masked-any-tilt (the
whole of SO(3), unverified), fft-zero (plain cost on the zero-filled view), exhaustive-masked
and exhaustive-zero (the source method's coarse-to-fine ZYZ search), visual-compass-sh (yaw only, on the SH);
needing the snapshot's images, so run only against the recording's reference frame: visual-compass-panorama
(yaw only, rotational image difference of the skyline mask's panorama), features-sift and features-orb (UV image,
bearings, RANSAC rotation / essential matrix).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from skynav_core.cli import add_skip_damaged
from skynav_core.evaluation import add_methods_argument, add_plots_argument

from ..eval.methods import DEFAULT_METHODS, NODE_METHODS

HELP = 'compass error against ground truth, per method, for pure rotations and moved views'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav eval compass`."""
    parser.add_argument('bag', metavar='BAG', help='recording with camera topics and /ground_truth/pose')
    add_skip_damaged(parser)
    parser.add_argument(
        '--map',
        type=Path,
        metavar='MAP.db',
        help="compare against a snapshot of this map (default: the recording's reference frame)",
    )
    parser.add_argument('--index', type=int, default=0, metavar='I', help='the map snapshot to compare against (0)')
    add_methods_argument(parser, NODE_METHODS, DEFAULT_METHODS)
    add_plots_argument(parser, 'compass_eval', 'the plot')
    parser.add_argument(
        '--repeats', type=int, default=1, metavar='N', help='time every estimate N times, the least counts (default 1)'
    )
    parser.add_argument('--params', type=Path, metavar='FILE', help='node parameters (skyline, sh)')
    parser.add_argument(
        '--max-tilt',
        type=float,
        default=None,
        metavar='DEG',
        help='largest tilt between the two views the fft-masked and fft-zero compasses consider '
        "(default: the compass node's max_tilt_deg, 45)",
    )


def run(args: argparse.Namespace) -> int:
    """Evaluate; return the exit code."""
    from skynav_core.cli import CliError, graph_arguments
    from skynav_core.evaluation import check_at_least, check_methods, check_not_negative, check_recordings, plots_folder

    from ..eval.evaluation import plot_errors
    from ..eval.recording import EvaluationError, evaluate_recording, format_report

    check_methods(args.methods, NODE_METHODS)
    check_at_least(args.repeats, 1, '--repeats')
    check_not_negative(args.index, '--index')
    if args.max_tilt is not None and not 0 < args.max_tilt <= 180:
        raise CliError('--max-tilt must be more than 0 and at most 180 degrees', exit_code=2)
    check_recordings([args.bag])
    snapshot = None
    if args.map is not None:
        snapshot = map_snapshot(args.map, args.index)
    elif args.index:
        raise CliError('--index chooses a map snapshot; give the map with --map', exit_code=2)
    try:
        evaluation = evaluate_recording(
            args.bag,
            args.methods,
            snapshot,
            graph_arguments(args.params, None),
            repeats=args.repeats,
            max_tilt=max_tilt(args.max_tilt),
        )
    except EvaluationError as exc:
        raise CliError(str(exc)) from None
    print(format_report(evaluation))
    stem = Path(args.bag).stem
    path = plot_errors(
        evaluation.results,
        evaluation.tilts,
        evaluation.translations,
        plots_folder(args.plots) / f'{stem}_errors.png',
        evaluation.synthetic,
        f'{stem} against {evaluation.snapshot}',
    )
    print(f'plot: {path}')
    return 0


def max_tilt(degrees: float | None) -> float:
    """Return the tilt bound (rad) of --max-tilt (deg), by default the compass's."""
    import numpy as np

    from skynav_core.rotations import MAX_TILT

    return MAX_TILT if degrees is None else float(np.radians(degrees))


def map_snapshot(path: Path, index: int):
    """Return the map's snapshot `index` as an ExternalSnapshot (CliError if the map or its pose is unusable)."""
    from skynav_core.cli import CliError, open_map
    from skynav_core.maps import MapError

    from ..eval.recording import ExternalSnapshot

    with open_map(path) as store:
        try:
            if not 0 <= index < len(store):
                raise CliError(f'{path}: no snapshot {index} (the map has {len(store)})')
            snapshot, name = store.snapshot(index), store.name
        except MapError as exc:
            raise CliError(str(exc)) from None
    if snapshot.pose is None:
        raise CliError(f'{path}: snapshot {index} has no ground-truth pose, so the true rotation is unknown')
    return ExternalSnapshot(snapshot.coefficients, snapshot.pose, f'snapshot {index} of map {name!r}')
