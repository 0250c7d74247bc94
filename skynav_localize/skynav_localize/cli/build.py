"""Build a map from a teach drive: skyline -> SH for every frame, a snapshot every so often, into SQLite.

The skyline and SH nodes run over the recording in this process (the same code and parameters as
`skynav run`). A frame becomes a snapshot after --min-travel metres of travel (ground-truth pose,
when the recording has one) or when its amplitude spectrum changed by --min-change. Each snapshot
stores its SH coefficients, descriptors for skynav's methods and for the baselines (down-sampled
UV image, ORB features), and its ground-truth pose. The file is written under a temporary name
and renamed when complete; if the build is killed, that partial file still holds every snapshot
written so far.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'build a map from a teach drive'
CAMERA_TOPICS = ('/camera/uv/image_raw', '/camera/green/image_raw', '/camera/uv/camera_info')


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav map build`."""
    parser.add_argument('bag', metavar='BAG', help='teach drive (camera topics; /ground_truth/pose if any)')
    parser.add_argument('--out', required=True, type=Path, metavar='MAP.db', help='map file to write')
    parser.add_argument('--name', help='map name (default: the file name)')
    parser.add_argument('--min-travel', type=float, default=0.1, metavar='M', help='metres between snapshots (0.1)')
    parser.add_argument('--min-change', type=float, default=0.05, metavar='D',
                        help='amplitude-spectrum change that also makes a snapshot (0.05)')
    parser.add_argument('--params', type=Path, metavar='FILE', help='node parameters (skyline, sh)')
    parser.add_argument('--overwrite', action='store_true', help='replace an existing map')


def run(args: argparse.Namespace) -> int:
    """Build the map; return the exit code."""
    import json

    from tqdm import tqdm

    from skynav_bringup.bag import open_bag
    from skynav_bringup.cli import CliError
    from skynav_bringup.cli.run import ros_arguments
    from skynav_sh.views import recording_views

    from ..baselines import train_bow
    from ..mapping import SnapshotSelector, build_map, snapshot_descriptors
    from ..store import MapError, Snapshot

    if args.out.exists() and not args.overwrite:
        raise CliError(f'{args.out} exists already; choose another name or pass --overwrite')
    if not args.out.parent.is_dir():
        raise CliError(f'{args.out.parent}: no such directory')
    if args.min_travel <= 0 or args.min_change <= 0:
        raise CliError('--min-travel and --min-change must be positive', exit_code=2)
    with open_bag(args.bag) as bag:
        inputs = sum(bag.topics[t].count for t in CAMERA_TOPICS if t in bag.topics)
    with tqdm(total=inputs, unit='msg', desc='skyline + SH', file=sys.stderr, disable=None) as bar:
        recording = recording_views(args.bag, ros_arguments(args.params, None), progress=bar.update)
    if not recording.views:
        raise CliError(f'{args.bag}: the nodes produced no SH coefficients (see the messages above)')
    degree = recording.views[0].max_degree
    circle = recording.camera.image_circle()
    selector = SnapshotSelector(args.min_travel, args.min_change)

    def snapshots():
        index = 0
        for view in tqdm(recording.views, unit='frame', desc='snapshots', file=sys.stderr, disable=None):
            descriptors = snapshot_descriptors(view.coefficients, degree, view.uv, circle)
            position = None if view.pose is None else view.pose[:3]
            if selector.keep(descriptors['amplitude'], position):
                yield Snapshot(index, view.stamp, view.coefficients, view.pose, descriptors)
                index += 1

    camera_info = {name: getattr(recording.camera, name) for name in ('width', 'height', 'fx', 'fy', 'cx', 'cy')}
    camera_info['k'] = list(recording.camera.k)
    try:
        store = build_map(args.out, args.name or args.out.stem, degree, snapshots(), created_from=str(args.bag),
                          metadata={'camera': json.dumps(camera_info), 'synthetic': str(recording.synthetic)},
                          overwrite=args.overwrite, finish=train_bow)
    except MapError as exc:
        raise CliError(str(exc)) from None
    info = store.info()
    route = f', route {info["route_length_m"]:.1f} m' if 'route_length_m' in info else ''
    print(f'skynav map build: {len(store)} snapshots of {len(recording.views)} frames (degree {degree}{route}) '
          f'-> {args.out} ({info["file_bytes"] / 2**20:.1f} MiB)', file=sys.stderr)
    store.close()
    return 0
