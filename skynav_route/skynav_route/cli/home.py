# SPDX-License-Identifier: Apache-2.0
"""Drive the robot to the place of one snapshot: send a Home goal to the running graph (`skynav launch`).

The route node turns the home vectors to snapshot --index into velocity commands on /cmd_vel, one per camera
frame, until the views agree (arrived). The progress line shows the frames answered and the confidence of the
latest home vector. Ctrl-C cancels the goal and the robot stops. Exit code 0 on arrival, 1 with the error
code's name (LOST, NO_MAP, STALE_INPUT, TIMEOUT, BAD_INDEX, ...) otherwise.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from skynav_core.cli import add_namespace
from skynav_core.names import HOME_ACTION

HELP = 'drive to the place of one snapshot (Home goal to the running graph)'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav home`."""
    parser.add_argument('map', nargs='?', type=Path, metavar='MAP.db', help='the map (default: the map the nodes have)')
    parser.add_argument('--index', type=int, required=True, metavar='I', help='the snapshot to home to')
    parser.add_argument('--max-speed', type=float, default=0.0, metavar='M/S', help="speed limit (default: the node's)")
    parser.add_argument('--wait', type=float, default=10.0, metavar='S', help='wait this long for the server (10 s)')
    add_namespace(parser)


def run(args: argparse.Namespace) -> int:
    """Send the goal and follow it to its end; return the exit code."""
    from skynav_core.cli import CliError
    from skynav_core.goals import ProgressLine, goal_result, send_goal
    from skynav_core.namespaces import namespaced
    from skynav_msgs.action import Home

    if args.index < 0:
        raise CliError('--index must be a snapshot index (0 or more)', exit_code=2)
    goal = Home.Goal(map_path=str(args.map.resolve()) if args.map else '', index=args.index, max_speed=args.max_speed)

    line = ProgressLine()

    def show(feedback) -> None:
        line.show(f'homing to snapshot {args.index}: {feedback.steps} frames  confidence {feedback.confidence:.2f}')

    try:
        outcome = send_goal(Home, namespaced(HOME_ACTION, args.namespace), goal, show, args.wait)
    finally:
        line.end()
    result = goal_result(outcome)
    print(f'arrived at snapshot {args.index}: driven {result.driven_length:.2f} m')
    return 0
