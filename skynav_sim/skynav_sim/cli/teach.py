# SPDX-License-Identifier: Apache-2.0
"""Teach a route in a synthetic world by scripted teleoperation, as an operator would, with a Teach goal.

A scripted operator drives the simulated mower along a planned free route of about --length m (with turns) at
0.3 m/s, steering as with a joystick (the mower slips and its odometry drifts, skynav_sim.mower), while the graph
in this process (skyline, SH, localize, which serves /skynav/teach) stores a snapshot every `teach_spacing` m by
/odom into DIR/teach.db (with --no-odom, when the view has changed enough; the route's shape then comes from the
operator's /cmd_vel commands). At the route's end the operator cancels the goal, which finishes the map. DIR/teach.yaml
says which world, seed, camera and time of day it was and holds the true pose of every frame, for scoring only:
`skynav sim follow DIR/teach.yaml --map DIR/teach.db` then follows the route. Everything is synthetic.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = 'teach a route in a synthetic world by scripted teleoperation (a Teach goal records the map)'
DESCRIPTION_SOURCE = 'skynav sim teach (synthetic, scripted teleoperation)'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav sim teach`."""
    from ..names import STYLES
    from . import options
    from .options import DEFAULT_DISTORTION

    parser.add_argument('--world', choices=STYLES, default='garden', help='synthetic world style (default garden)')
    parser.add_argument('--seed', type=int, default=1, help='world seed (default 1)')
    parser.add_argument('--route-seed', type=int, default=0, help='which planned route of the world (default 0)')
    parser.add_argument('--length', type=float, default=10.0, metavar='M', help='route length (default 10 m)')
    parser.add_argument('--time', default='forenoon', help='time of day (default forenoon)')
    parser.add_argument('--size', default='320x240', metavar='WxH', help='camera image size (default 320x240)')
    parser.add_argument('--fov', type=float, default=200.0, metavar='DEG', help='field of view (default 200)')
    parser.add_argument('--distortion', default=DEFAULT_DISTORTION, metavar='K1,K2,K3,K4', help=argparse.SUPPRESS)
    options.add_base_arguments(parser)
    parser.add_argument(
        '--out', type=Path, default=Path('sim_teach'), metavar='DIR', help='folder for teach.db and teach.yaml'
    )


def run(args: argparse.Namespace) -> int:
    """Teach the route; return the exit code."""
    import numpy as np

    from skynav_core.cli import CliError
    from skynav_core.goals import GoalOutcome, goal_result

    from ..closed_loop import teach_route
    from ..sky import parse_time
    from ..world import generate
    from . import options

    if not 1.0 <= args.length <= 200.0:
        raise CliError('--length must be within 1..200 m', exit_code=2)
    if not (0 <= args.slip < 1 and 0 <= args.odometry_noise < 1):
        raise CliError('--slip and --odometry-noise must be within 0..1', exit_code=2)
    try:
        hours = parse_time(args.time)
        camera = options.camera(args)
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None
    base = options.base(args)
    args.out.mkdir(parents=True, exist_ok=True)
    world = generate(args.world, args.seed)
    map_path = (args.out / 'teach.db').resolve()
    print(
        f'teaching a {args.length:g} m route by scripted teleoperation in the synthetic {args.world} world '
        f'(seed {args.seed}) at {hours:.1f} h{options.describe_mount(base)}',
        flush=True,
    )
    try:
        teaching = teach_route(
            world,
            camera,
            hours,
            args.seed,
            args.length,
            map_path,
            base,
            route_seed=args.route_seed,
        )
    except RuntimeError as exc:
        raise CliError(str(exc)) from None
    # the operator's cancel is the usual end of teaching: a canceled goal with no error finished the map
    result = goal_result(GoalOutcome(teaching.status, teaching.result, True), cancel_finishes=True)
    poses = np.array(teaching.poses)
    driven = float(np.sum(np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)))
    description_path = args.out / 'teach.yaml'
    write_description(description_path, args.world, args.seed, hours, camera, map_path, teaching, base.mount_rpy_deg)
    source = 'the velocity commands' if args.no_odom else 'odometry'
    print(
        f'taught {result.snapshots} snapshots over {result.route_length:.2f} m by {source} ({driven:.2f} m truly '
        f'driven, {len(poses)} frames)'
    )
    print(f'map: {map_path}\ndescription (with the true poses, for scoring): {description_path}')
    return 0


def write_description(
    path: Path,
    world: str,
    seed: int,
    hours: float,
    camera,
    map_path: Path,
    teaching,
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> None:
    """Write what `skynav sim follow` needs of a teach drive: world, seed, camera (and its mount on the mower: roll,
    pitch, yaw in degrees), time and every frame's true pose."""
    import numpy as np
    import yaml

    poses = np.array(teaching.poses)
    description = {
        'scenario': 'teach',
        'source': DESCRIPTION_SOURCE,
        'world': world,
        'world_seed': seed,
        'seed': seed,
        'hours': hours,
        'camera_info': {
            key: (list(value) if isinstance(value, (list, tuple)) else value)
            for key, value in camera.camera_info_fields().items()
        },
        'mount_rpy_deg': [float(v) for v in mount_rpy_deg],
        'map': str(map_path),
        'truth': {'stamps': [int(s) for s in teaching.stamps], 'poses': poses.round(5).tolist()},
    }
    path.write_text(yaml.safe_dump(description, sort_keys=False))
