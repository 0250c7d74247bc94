# SPDX-License-Identifier: Apache-2.0
"""Teach a route on the running graph: a Teach goal (/skynav/teach) that stores snapshots while the robot is driven.

Start the graph first (`skynav launch`, on the robot or over a replay), then drive the route (by hand, joystick,
any controller) while this command runs: it shows the snapshots stored and the length driven (by /odom; 0 without
it). Ctrl-C ends teaching, the usual end: the map is finished, the nodes switch to it at once, and its summary is
printed. --max-length ends it after so many metres (by /odom). Exit 0 when the map is finished, 1 with the error
code's name (MAP_EXISTS, MAP_WRITE_FAILED, NO_INPUT, ...) otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from skynav_core.cli import add_namespace

HELP = 'teach a route: store snapshots of the live views into a new map while the robot is driven'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav teach`."""
    parser.add_argument('map', type=Path, metavar='MAP.db', help='map file to create')
    parser.add_argument('--name', default='', help='map name (default: the file name)')
    parser.add_argument(
        '--spacing', type=float, default=0.0, metavar='M', help="metres between snapshots (default: the node's)"
    )
    parser.add_argument(
        '--max-length', type=float, default=0.0, metavar='M', help='end after this many metres by /odom (no limit)'
    )
    parser.add_argument('--overwrite', action='store_true', help='replace an existing map')
    parser.add_argument(
        '--wait', type=float, default=10.0, metavar='SECONDS', help='how long to wait for the graph (default 10)'
    )
    add_namespace(parser)


def progress_line(snapshots: int, route_length: float) -> str:
    """Return the progress line of a teach goal."""
    driven = f', {route_length:.2f} m' if route_length > 0 else ''
    return f'teaching: {snapshots} snapshots{driven} (Ctrl-C finishes the map)'


def run(args: argparse.Namespace) -> int:
    """Teach until the goal ends; return the exit code."""
    import math

    from skynav_core.cli import CliError, open_map
    from skynav_core.goals import RESULT_AFTER_CANCEL, ProgressLine, goal_result, send_goal
    from skynav_core.names import TEACH_ACTION
    from skynav_core.namespaces import namespaced
    from skynav_msgs.action import Teach

    for option, value in (('--spacing', args.spacing), ('--max-length', args.max_length)):
        if not math.isfinite(value):
            raise CliError(f'{option} must be a number of metres', exit_code=2)
    path = args.map.expanduser().resolve()  # the server runs elsewhere: it needs the whole path
    goal = Teach.Goal(
        map_path=str(path),
        map_name=args.name,
        spacing=args.spacing,
        max_length=args.max_length,
        overwrite=args.overwrite,
    )
    line = ProgressLine(sys.stderr, period=0.0)  # a line per snapshot stored

    def show(feedback: Teach.Feedback) -> None:
        if feedback.snapshots == 0:  # the server's first feedback: the map can be taught
            print(f'skynav teach: teaching {args.map}: drive the route; Ctrl-C finishes the map', file=sys.stderr)
            return
        line.show(progress_line(feedback.snapshots, feedback.route_length))

    try:
        outcome = send_goal(
            Teach, namespaced(TEACH_ACTION, args.namespace), goal, show, args.wait, 'skynav_teach', RESULT_AFTER_CANCEL
        )
    finally:
        line.end()
    result = goal_result(outcome, cancel_finishes=True, detail=lambda result: f'{result.snapshots} snapshots kept')
    assert outcome is not None  # goal_result raised otherwise
    if not path.exists():  # canceled before teaching began
        raise CliError(result.error_msg or f'the server wrote no map at {path}')
    with open_map(path) as store:
        info = store.info()
        odometry = store.odometry_poses()
    source = 'odometry' if odometry is not None and np.isfinite(odometry).any() else 'the velocity commands'
    driven = f', {result.route_length:.2f} m by {source}' if result.route_length > 0 else ''
    print(
        f'skynav teach: {outcome.status_name}: {info["snapshots"]} snapshots{driven} -> {args.map} '
        f'({info["file_bytes"] / 1e3:.0f} kB)',
        file=sys.stderr,
    )
    return 0
