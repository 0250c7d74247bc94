# SPDX-License-Identifier: Apache-2.0
"""Measure place recognition on repeat drives against a map: skynav's methods and the baselines, side by side.

Every query frame of each recording goes through the skyline and SH nodes (as in `skynav run`),
then every method matches it against the map. A match is correct when the matched snapshot lies
within --tolerance metres of the query's true position (ground truth of both). Prints, per method,
recall at 100 % precision, the area under the precision-recall curve and recall@1, and saves the
precision-recall curves and the matches along the route as plots in --plots. The baselines need
their descriptors in the map (`skynav map build --baselines`); on a map without them their rows
are left out, which one line says. A map taught live (`skynav teach`) holds no ground truth (no node reads
it): --map-poses names the recording of its teach drive, whose /ground_truth/pose at each snapshot's
stamp places the snapshots.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from skynav_core.cli import add_skip_damaged
from skynav_core.evaluation import add_methods_argument, add_plots_argument
from skynav_core.names import GROUND_TRUTH_POSE

HELP = 'precision-recall of localization methods against ground truth'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav eval localization`."""
    from ..eval.baselines import EVALUATED_METHODS as METHODS

    parser.add_argument('bags', nargs='+', metavar='BAG', help='repeat drives with /ground_truth/pose')
    add_skip_damaged(parser)
    parser.add_argument(
        '--map',
        required=True,
        type=Path,
        metavar='MAP.db',
        help='map of the teach drive (built with --baselines to compare with the baselines)',
    )
    parser.add_argument(
        '--map-poses',
        type=Path,
        metavar='BAG',
        help="for a map without ground truth (taught live): the teach drive's recording, with /ground_truth/pose",
    )
    add_methods_argument(parser, list(METHODS))
    parser.add_argument(
        '--tolerance',
        type=float,
        default=1.0,
        metavar='M',
        help='a match is correct within this distance (default 1 m)',
    )
    add_plots_argument(parser, 'localization_eval')
    parser.add_argument('--params', type=Path, metavar='FILE', help='node parameters (skyline, sh)')


def run(args: argparse.Namespace) -> int:
    """Evaluate; return the exit code."""
    from skynav_core.cli import CliError, graph_arguments, open_map
    from skynav_core.evaluation import check_methods, check_positive, check_recordings, plots_folder
    from skynav_core.maps import MapError

    from ..eval.baselines import EVALUATED_METHODS as METHODS
    from ..localizer import BASELINES_HINT, missing_descriptors

    check_methods(args.methods, METHODS)
    check_positive(args.tolerance, '--tolerance')
    check_recordings(args.bags)
    ros_args = graph_arguments(args.params, None)
    with open_map(args.map) as store:
        if store.has_poses:
            snapshots = store.positions()
        elif args.map_poses is not None:
            snapshots = positions_at(args.map_poses, store.stamps())
        else:
            raise CliError(
                f'{args.map}: the map has no ground-truth poses; evaluation needs them '
                "(for a map taught live, pass its teach drive's recording with --map-poses)"
            )
        try:
            lacking = {name: missing_descriptors(store, name) for name in args.methods}
        except MapError as exc:
            raise CliError(str(exc)) from None
        methods = [name for name in args.methods if not lacking[name]]
        if not methods:
            raise CliError(f'{args.map} holds no descriptors of {", ".join(args.methods)} ({BASELINES_HINT})')
        if skipped := [name for name in args.methods if lacking[name]]:
            print(
                f'skynav eval localization: {args.map} holds no descriptors of {", ".join(skipped)}: their rows '
                f'are left out ({BASELINES_HINT})',
                file=sys.stderr,
            )
        plots_folder(args.plots)
        for bag in args.bags:
            evaluate_bag(bag, store, snapshots, methods, args.tolerance, args.plots, ros_args)
    return 0


def positions_at(bag: Path, stamps):
    """Return the ground-truth positions (N, 3) of camera_link in map at the given stamps (ns) of a recording."""
    import numpy as np

    from skynav_core.cli import CliError
    from skynav_core.images import stamp_ns
    from skynav_core.recording.bag import open_bag

    truth = {}
    with open_bag(bag) as recording:
        for raw in recording.messages([GROUND_TRUTH_POSE]):
            message = recording.deserialize(raw)
            p = message.pose.position
            truth[stamp_ns(message.header)] = (p.x, p.y, p.z)
    missing = [int(stamp) for stamp in stamps if int(stamp) not in truth]
    if missing:
        raise CliError(
            f'{bag}: no /ground_truth/pose stamped {missing[0]} ({len(missing)} of the {len(stamps)} snapshots lack '
            'one): is it the recording the map was taught from?'
        )
    return np.array([truth[int(stamp)] for stamp in stamps], dtype=float).reshape(-1, 3)


def evaluate_bag(
    bag: str, store, snapshots, methods: list[str], tolerance: float, plots: Path, ros_args: list[str]
) -> None:
    """Match every view of one repeat drive against the map with each method; print the table, save the plots.

    snapshots: the true positions (N, 3) of the map's snapshots (m).
    """
    import numpy as np

    from skynav_core.cli import CliError
    from skynav_core.maps import MapError
    from skynav_core.views import recording_views

    from ..eval.baselines import EVALUATED_METHODS as METHODS
    from ..eval.evaluation import correct_matches, evaluate, format_table, plot_matches_along_route, plot_pr_curves
    from ..localizer import Localizer

    needs_images = any(METHODS[name].source == 'uv' for name in methods)
    recording = recording_views(bag, ros_args, images=needs_images)
    views = [v for v in recording.views if v.pose is not None]
    if not views:
        raise CliError(f'{bag}: no ground-truth poses to evaluate against')
    coefficients = np.stack([v.coefficients[: (store.max_degree + 1) ** 2] for v in views])
    uvs = np.stack([np.asarray(v.uv) for v in views]) if needs_images else None  # the images the views came from
    positions = np.stack([v.pose[:3] for v in views if v.pose is not None])  # all of them
    assert recording.camera is not None  # the nodes made views, so the recording has camera info
    circle = recording.camera.image_circle()
    results, all_matches = [], {}
    for name in methods:
        try:
            localizer = Localizer(store, name, circle=circle)
        except MapError as exc:
            raise CliError(str(exc)) from None
        matches = localizer.match_sequence(
            coefficients=coefficients, uvs=uvs, field_of_view=views[0].field_of_view, fill=views[0].fill
        )
        all_matches[name] = matches
        results.append(
            evaluate(
                METHODS[name].label,
                matches.index,
                matches.score,
                positions,
                snapshots,
                tolerance,
                accepted=matches.accepted,
            )
        )
    kind = 'synthetic ' if recording.synthetic else ''
    print(
        f'\n{Path(bag).name}: {len(views)} {kind}queries against map {store.name!r} '
        f'({len(store)} snapshots); a match is correct within {tolerance:g} m'
    )
    print(format_table(results))
    stem = Path(bag).stem
    title = f'{stem} against map {store.name}'
    plot_pr_curves(results, title, recording.synthetic, plots / f'{stem}_pr.png')
    shown = 'amplitude-seq' if 'amplitude-seq' in all_matches else methods[0]
    matches = all_matches[shown]
    plot_matches_along_route(
        snapshots,
        positions,
        matches.index,
        correct_matches(matches.index, positions, snapshots, tolerance),
        matches.accepted,
        f'{title}: {shown}',
        recording.synthetic,
        plots / f'{stem}_matches.png',
    )
    print(f'plots: {plots / (stem + "_pr.png")}, {plots / (stem + "_matches.png")} (matches of {shown})')
