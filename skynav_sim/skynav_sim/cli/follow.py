# SPDX-License-Identifier: Apache-2.0
"""Closed-loop route following in the synthetic world of a teach drive: the graph drives the simulated mower.

The map (`skynav map build TEACH.mcap`, or `skynav sim teach`) holds the snapshots of a synthetic teach drive; the
world, its seed and the camera are read back from the teach recording (or from the description `skynav sim teach`
wrote, TEACH.yaml, which also holds the true poses a taught map lacks, for scoring). The simulated mower starts
beside the route's first snapshot, off by --offset metres to the left and turned by --turn degrees. The graph
(skyline, SH, localize, compass, warping and the route node) runs in this process; a FollowRoute goal goes to the
route node's action server, and the mower obeys its /cmd_vel, one command per camera frame, on sim time
(skynav_sim.closed_loop), until the goal's result. Reports how far the true path stayed from the taught route and
plots both. Everything is synthetic.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from skynav_core.names import COLOUR_CAMERA_INFO, UV_CAMERA_INFO

HELP = 'closed-loop route following of a simulated robot along a taught (synthetic) route'
END_RADIUS = 1.0  # m: stopping this close to the last snapshot reaches the end (a correct place match's tolerance)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav sim follow`."""
    from . import options

    parser.add_argument(
        'teach',
        type=Path,
        metavar='TEACH.mcap|TEACH.yaml',
        help='the synthetic teach drive of the map: its recording, or the description `skynav sim teach` wrote',
    )
    parser.add_argument('--map', type=Path, required=True, metavar='MAP.db', help='its map (`skynav map build`)')
    parser.add_argument(
        '--offset',
        type=float,
        default=0.3,
        metavar='M',
        help="start this far left of the route's first snapshot (negative: right; default 0.3)",
    )
    parser.add_argument(
        '--turn',
        type=float,
        default=20.0,
        metavar='DEG',
        help="start turned this far left of the route's direction (default 20)",
    )
    parser.add_argument('--time', default='morning', help='time of day of the run (default morning)')
    options.add_start_argument(parser)
    parser.add_argument(
        '--max-frames',
        type=int,
        default=0,
        metavar='N',
        help='camera frames before the run is given up (default: three times the route length at full speed)',
    )
    options.add_base_arguments(parser)
    parser.add_argument(
        '--bump-tilt', type=float, default=0.0, metavar='DEG', help='bumpy ground: views tilted up to DEG more'
    )
    parser.add_argument(
        '--out', type=Path, default=Path('sim_follow'), metavar='DIR', help='folder for the plot (default sim_follow)'
    )


def teach_world(teach: Path):
    """Return (world, seed, camera, truth) of a synthetic teach drive; CliError when it is not one.

    `teach` is a teach recording (`skynav sim bag teach`: its map holds the true poses; truth None) or the
    description `skynav sim teach` wrote (truth: the stamps in ns and true (x, y, heading) of its frames).
    """
    import numpy as np
    import yaml
    from sensor_msgs.msg import CameraInfo

    from skynav_core.camera import EquidistantCamera
    from skynav_core.cli import CliError
    from skynav_core.recording.bag import BagError, open_bag

    from ..world import STYLES, generate

    truth = None
    try:
        if teach.suffix in ('.yaml', '.yml'):
            description = yaml.safe_load(teach.read_text()) or {}
            info = CameraInfo(**description['camera_info'])
            truth = (
                np.asarray(description['truth']['stamps'], dtype=np.int64),
                np.asarray(description['truth']['poses'], dtype=float),
            )
        else:
            with open_bag(teach) as bag:
                description = yaml.safe_load(bag.custom_data.get('skynav_sim', '')) or {}
                # the UV/green pair's camera info, or a colour camera's
                infos = bag.messages([t for t in (UV_CAMERA_INFO, COLOUR_CAMERA_INFO) if t in bag.topics])
                info = next((bag.deserialize(raw) for raw in infos), None)
    except BagError as exc:
        raise CliError(str(exc)) from None
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError, AssertionError, ValueError) as exc:
        raise CliError(f'{teach}: not a description written by `skynav sim teach` ({exc})') from None
    if description.get('scenario') != 'teach' or description.get('world') not in STYLES or info is None:
        raise CliError(f'{teach}: not a synthetic teach drive of skynav_sim (its world is needed to drive in)')
    seed = int(description['seed'])
    try:
        camera = EquidistantCamera.from_camera_info(info)
    except ValueError as exc:
        raise CliError(f'{teach}: {exc}') from None
    return generate(description['world'], int(description.get('world_seed', seed))), seed, camera, truth


def teach_mount(teach: Path) -> tuple[float, float, float]:
    """Return the camera's mount (roll, pitch, yaw in degrees) of a teach drive: what `skynav sim teach` wrote in its
    description; a teach recording's camera is on the base's axes."""
    import yaml

    if teach.suffix not in ('.yaml', '.yml'):
        return (0.0, 0.0, 0.0)
    roll, pitch, yaw = (yaml.safe_load(teach.read_text()) or {}).get('mount_rpy_deg', [0.0, 0.0, 0.0])
    return float(roll), float(pitch), float(yaw)


def run(args: argparse.Namespace) -> int:
    """Follow the route once; return the exit code."""
    import dataclasses

    import numpy as np

    from skynav_core.cli import CliError
    from skynav_core.maps import MapError, MapStore

    from ..closed_loop import FRAME_PERIOD, SPEED, follow_route, route_deviation, truth_at
    from ..robot import base_positions
    from ..sky import parse_time
    from . import options

    try:
        hours = parse_time(args.time)
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None
    if args.max_frames < 0:
        raise CliError('--max-frames must not be negative', exit_code=2)
    if not (0 <= args.slip < 1 and 0 <= args.odometry_noise < 1 and 0 <= args.bump_tilt <= 90):
        raise CliError('--slip and --odometry-noise must be within 0..1, --bump-tilt within 0..90', exit_code=2)
    world, seed, camera, truth = teach_world(args.teach)
    base = options.base(args)
    if args.mount_rpy is None:  # the robot of the teach: its camera mounted as it was then
        base = dataclasses.replace(base, mount_rpy_deg=teach_mount(args.teach))
    try:
        with MapStore.open(args.map) as store:
            poses, stamps = store.poses(), store.stamps()
            count = len(store)
    except MapError as exc:
        raise CliError(str(exc)) from None
    # a taught map has no true poses: those of its snapshots' frames come from the teach drive's description
    if truth is None:  # the base's places under the recording's true camera poses
        route = base_positions(poses, base.mount) if np.all(np.isfinite(poses)) else poses[:, :2]
    else:
        route = truth_at(np.asarray(stamps, dtype=np.int64), *truth)[:, :2]
    if count < 2 or not np.all(np.isfinite(route)):
        raise CliError(
            f'{args.map}: route following needs a map of at least 2 snapshots with true poses ({args.teach})'
        )
    forward = route[min(3, count - 1)] - route[0]
    route_heading = float(np.arctan2(forward[1], forward[0]))
    left = np.array([-np.sin(route_heading), np.cos(route_heading)])
    start = route[0] + args.offset * left
    length = float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))
    max_frames = args.max_frames or int(3 * length / (SPEED * FRAME_PERIOD)) + 50
    print(
        f'following the {length:.1f} m route of {args.map.name} ({count} snapshots) in the synthetic '
        f'{world.style} world (seed {seed}) at {hours:.1f} h, from {args.offset:+.2f} m beside its start, '
        f'turned {args.turn:+.0f} deg{options.describe_mount(base)}',
        flush=True,
    )
    run, route = follow_route(
        world,
        camera,
        args.map,
        start,
        route_heading + np.radians(args.turn),
        hours,
        seed,
        max_frames,
        base=base,
        bump_tilt=args.bump_tilt,
        route=route,
        start_index=args.start_index,
    )
    deviation = route_deviation(run, route)
    end = float(np.linalg.norm(run.path[-1] - route[-1]))
    reached = run.stopped == 'reached' and end <= END_RADIUS
    print(
        f'{len(run.path) - 1} frames ({(len(run.path) - 1) * FRAME_PERIOD:.1f} s sim time, '
        f'{run.stopped_frames} standing still); goal ended: {run.stopped}; {end:.2f} m from the last snapshot '
        f'({"reached the end" if reached else "did NOT reach the end"})'
    )
    print(
        f'distance from the taught route: median {np.median(deviation):.2f} m, 90th percentile '
        f'{np.percentile(deviation, 90):.2f} m, largest {deviation.max():.2f} m, RMSE '
        f'{np.sqrt(np.mean(deviation**2)):.2f} m (at the start {deviation[0]:.2f} m); driven {run.driven:.1f} m '
        f'of the {length:.1f} m taught'
    )
    args.out.mkdir(parents=True, exist_ok=True)
    plot = args.out / 'route_following.png'
    draw_route(plot, world, route, run, f'SYNTHETIC closed-loop route following: {world.style} world, seed {seed}')
    print(f'plot: {plot}')
    return 0 if reached else 1


def draw_route(path: Path, world, route, run, title: str) -> None:
    """Plot the taught route and the driven path over a top view of the world."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    from ..preview import draw_world

    points = np.array(run.path)
    both = np.vstack([route, points])
    centre = (both.min(axis=0) + both.max(axis=0)) / 2
    half = float(np.max(both.max(axis=0) - both.min(axis=0))) / 2 + 1.5
    figure, axis = plt.subplots(figsize=(9, 8), layout='constrained')
    draw_world(figure, axis, world, 40.0)
    axis.plot(
        route[:, 0], route[:, 1], '.-', color='gold', markeredgecolor='k', linewidth=2, label='taught route (snapshots)'
    )
    axis.plot(points[:, 0], points[:, 1], 'o-', color='#1565c0', markersize=3, linewidth=1.5, label='driven path')
    axis.plot(*points[0], 's', color='#1565c0', markersize=8, label='start')
    axis.set_xlim(centre[0] - half, centre[0] + half)
    axis.set_ylim(centre[1] - half, centre[1] + half)
    axis.legend(loc='upper right')
    axis.set_title(title)
    figure.savefig(path, dpi=80)
    plt.close(figure)
