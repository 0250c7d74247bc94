# SPDX-License-Identifier: Apache-2.0
"""Measure homing on a recorded grid: the home vector of every view towards a snapshot, by each method.

Every frame of the recording goes through the skyline and SH nodes (as in `skynav run`). The
snapshot is the recording's frame labelled 'snapshot' (else its first frame), or with --map
snapshot --index of that map (it needs a ground-truth pose). Each other frame with a ground-truth
pose is homed to it, and the estimate is compared with the true home direction
Q_c^-1 (p_s - p_c) in the current camera_link. Methods:

  3d-warping             the compass estimate starts the 3D-warping search (as the nodes run)
  3d-warping-no-compass  3D-warping from its own rotational pre-alignment
  2d-warping             planar baseline on panoramas unwrapped from the skyline masks
  min-warping            planar baseline on the same panoramas

The planar baselines need the snapshot's skyline mask, so they run only when the snapshot is a
frame of the recording (a map snapshot built from it counts). Prints, per method, the median and
90th percentile of the angular error by distance (0.5-1, 1-2, 2-4 m) and by the current camera's
tilt, and the CPU time per estimate (preparing the current view and estimating; the snapshot's
preparation spread over all estimates); saves a quiver plot of true and estimated home vectors
over the grid in --plots.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from skynav_core.cli import add_skip_damaged
from skynav_core.evaluation import add_methods_argument, add_plots_argument

from ..eval.methods import METHODS

HELP = 'angular error of home vectors (3D-, 2D-, min-warping) against ground truth'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav eval homing`."""
    parser.add_argument('bag', metavar='BAG', help='homing grid recording with /ground_truth/pose')
    add_skip_damaged(parser)
    parser.add_argument(
        '--map',
        type=Path,
        metavar='MAP.db',
        help="home to a snapshot of this map (default: the recording's snapshot frame)",
    )
    parser.add_argument('--index', type=int, default=0, metavar='I', help='the map snapshot to home to (default 0)')
    add_methods_argument(parser, list(METHODS))
    add_plots_argument(parser, 'homing_eval', 'the quiver plot')
    parser.add_argument('--params', type=Path, metavar='FILE', help='node parameters (skyline, sh)')


def run(args: argparse.Namespace) -> int:
    """Evaluate; return the exit code."""
    from tqdm import tqdm

    from skynav_core.cli import CliError, graph_arguments, open_map
    from skynav_core.evaluation import check_methods, check_not_negative, check_recordings, plots_folder
    from skynav_core.recording.bag import open_bag
    from skynav_core.views import recording_views

    from ..eval.homing_eval import HomingEvalError, evaluate_homing, map_snapshot

    check_methods(args.methods, METHODS)
    check_not_negative(args.index, '--index')
    check_recordings([args.bag])
    store = None if args.map is None else open_map(args.map)
    try:
        if store is not None:
            map_snapshot(store, args.index)  # fail before the nodes run
        with open_bag(args.bag) as bag:
            inputs = sum(t.count for name, t in bag.topics.items() if name.startswith('/camera/'))
        plots_folder(args.plots)
        with tqdm(total=inputs, unit='msg', desc='skyline + SH', file=sys.stderr, disable=None) as bar:
            recording = recording_views(
                args.bag, graph_arguments(args.params, None), images=False, masks=True, progress=bar.update
            )
        if not recording.views:
            raise CliError(f'{args.bag}: the nodes produced no SH coefficients (see the messages above)')
        snapshot = None if store is None else map_snapshot(store, args.index, recording)
        with tqdm(unit='estimate', desc='homing', file=sys.stderr, disable=None) as bar:
            evaluation = evaluate_homing(recording, args.methods, snapshot, progress=bar.update)
    except HomingEvalError as exc:
        raise CliError(str(exc)) from None
    finally:
        if store is not None:
            store.close()

    stem = Path(args.bag).stem
    kind = 'synthetic ' if evaluation.synthetic else ''
    d, tilt = evaluation.distances, evaluation.tilts
    print(
        f'\n{Path(args.bag).name}: {len(d)} {kind}views homing to {evaluation.snapshot.name}, '
        f'{d.min():.2f}-{d.max():.2f} m away, camera tilt {tilt.min():.1f}-{tilt.max():.1f} deg'
    )
    if evaluation.left_out:
        views = 'view' if evaluation.left_out == 1 else 'views'
        print(f'({evaluation.left_out} {views} within 5 cm of the snapshot left out: no home direction)')
    print(
        'angular error of the home vector (degrees): median / 90th percentile; ms/estimate: CPU time '
        '(all threads) from SH coefficients or masks'
    )
    print(evaluation.table())
    for method, why in evaluation.skipped.items():
        print(f'{method} skipped: it {why}')
    if evaluation.results:
        path = args.plots / f'{stem}_quiver.png'
        evaluation.quiver(path, f'{stem}: home vectors to {evaluation.snapshot.name}')
        print(f'plot: {path}')
    return 0
