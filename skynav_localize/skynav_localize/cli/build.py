# SPDX-License-Identifier: Apache-2.0
"""Build a map from a teach drive: skyline -> SH for every frame, a snapshot every so often, into SQLite.

The skyline and SH nodes run over the recording in this process (the same code and parameters as
`skynav run`). A frame becomes a snapshot after --min-travel metres of travel (ground-truth pose,
when the recording has one) or when its amplitude spectrum changed by --min-change. Each snapshot
stores what the product uses: its SH coefficients (skynav's descriptors are derived from them when
the map is loaded) and its ground-truth pose. With --baselines it also stores the baselines'
descriptors (down-sampled UV image, ORB features and their vocabulary), which the evaluations
compare against; a baseline that cannot be trained on the drive (no ORB feature anywhere) says so
in one line and is left out. The file is written under a temporary name (.MAP.db.partial, beside
it) and renamed when complete; if the build is stopped (Ctrl-C, SIGTERM) or killed (kill -9), that
partial file is kept and holds every snapshot written so far: `skynav map info` and every other
command open it as a map.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from skynav_core.camera_input import CAMERA_TOPICS
from skynav_core.cli import add_skip_damaged

HELP = 'build a map from a teach drive'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav map build`."""
    parser.add_argument('bag', metavar='BAG', help='teach drive (camera topics; /ground_truth/pose if any)')
    add_skip_damaged(parser)
    parser.add_argument('--out', required=True, type=Path, metavar='MAP.db', help='map file to write')
    parser.add_argument('--name', help='map name (default: the file name)')
    parser.add_argument('--min-travel', type=float, default=0.1, metavar='M', help='metres between snapshots (0.1)')
    parser.add_argument(
        '--min-change',
        type=float,
        default=0.05,
        metavar='D',
        help='amplitude-spectrum change that also makes a snapshot (0.05)',
    )
    parser.add_argument('--params', type=Path, metavar='FILE', help='node parameters (skyline, sh)')
    parser.add_argument(
        '--baselines',
        action='store_true',
        help="also store the baselines' descriptors (raw UV, ORB), for `skynav eval localization`",
    )
    parser.add_argument('--overwrite', action='store_true', help='replace an existing map')


def run(args: argparse.Namespace) -> int:
    """Build the map; return the exit code. SIGTERM stops the build as Ctrl-C does (the partial map is kept)."""
    import signal

    previous = signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        return build(args)
    finally:
        signal.signal(signal.SIGTERM, previous)


def build(args: argparse.Namespace) -> int:
    """Build the map (skyline -> SH -> snapshots -> file); return the exit code."""
    import json

    from tqdm import tqdm

    from skynav_core.cli import CliError, graph_arguments
    from skynav_core.maps import MapError, Snapshot, partial_path
    from skynav_core.recording.bag import open_bag
    from skynav_core.views import recording_views

    from ..descriptors import describe
    from ..eval.baselines import baseline_descriptors, finish_baselines
    from ..mapping import SnapshotSelector, build_map

    if args.out.exists() and not args.overwrite:
        raise CliError(f'{args.out} exists already; choose another name or pass --overwrite')
    if not args.out.parent.is_dir():
        raise CliError(f'{args.out.parent}: no such directory')
    if args.min_travel <= 0 or args.min_change <= 0:
        raise CliError('--min-travel and --min-change must be positive', exit_code=2)
    with open_bag(args.bag) as bag:
        inputs = sum(bag.topics[t].count for t in CAMERA_TOPICS if t in bag.topics)
    with tqdm(total=inputs, unit='msg', desc='skyline + SH', file=sys.stderr, disable=None) as bar:
        recording = recording_views(
            args.bag, graph_arguments(args.params, None), images=args.baselines, progress=bar.update
        )
    if not recording.views:
        raise CliError(f'{args.bag}: the nodes produced no SH coefficients (see the messages above)')
    degree = recording.views[0].max_degree
    camera = recording.camera
    assert camera is not None  # the nodes made views, so the recording has camera info
    circle = camera.image_circle()
    selector = SnapshotSelector(args.min_travel, args.min_change)

    def snapshots():
        index = 0
        for view in tqdm(recording.views, unit='frame', desc='snapshots', file=sys.stderr, disable=None):
            position = None if view.pose is None else view.pose[:3]
            if selector.keep(describe('amplitude', view.coefficients, degree), position):
                descriptors = baseline_descriptors(view.uv, circle) if args.baselines else {}
                yield Snapshot(index, view.stamp, view.coefficients, view.pose, descriptors)
                index += 1

    left_out: list[str] = []

    def finish(store) -> None:
        left_out.extend(finish_baselines(store))

    camera_info = {name: getattr(camera, name) for name in ('width', 'height', 'fx', 'fy', 'cx', 'cy')}
    camera_info['k'] = list(camera.k)
    try:
        store = build_map(
            args.out,
            args.name or args.out.stem,
            degree,
            snapshots(),
            created_from=str(args.bag),
            metadata={'camera': json.dumps(camera_info), 'synthetic': str(recording.synthetic)},
            overwrite=args.overwrite,
            finish=finish if args.baselines else None,
        )
    except MapError as exc:
        raise CliError(str(exc)) from None
    except KeyboardInterrupt:
        raise CliError(stopped(partial_path(args.out)), exit_code=130) from None
    for line in left_out:
        print(f'skynav map build: {line}', file=sys.stderr)
    info = store.info()
    route = f', route {info["route_length_m"]:.1f} m' if 'route_length_m' in info else ''
    held = ', with baseline descriptors' if args.baselines else ''
    print(
        f'skynav map build: {len(store)} snapshots of {len(recording.views)} frames (degree {degree}{route}) '
        f'-> {args.out} ({info["file_bytes"] / 1e3:.0f} kB, {info["file_bytes"] / len(store):.0f} bytes per '
        f'snapshot{held})',
        file=sys.stderr,
    )
    store.close()
    return 0


def stopped(partial: Path) -> str:
    """Return the line that says how many snapshots the partial map of a stopped build keeps."""
    from skynav_core.maps import MapError, MapStore

    try:
        with MapStore.open(partial) as store:
            return f'stopped: the {len(store)} snapshots written so far are kept in {partial}'
    except MapError as exc:
        return f'stopped: no usable partial map ({exc})'
