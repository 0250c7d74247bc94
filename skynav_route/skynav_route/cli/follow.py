# SPDX-License-Identifier: Apache-2.0
"""Drive the robot along a taught route: send a FollowRoute goal to the running graph (`skynav launch`).

The route node localizes on the map's route and drives along it to --to (default: its last snapshot), one
velocity command per camera frame on /cmd_vel. The progress line shows the matched and target snapshots,
the progress from --from to --to, the confidence and the state (localizing, following, recovering,
stopping). Ctrl-C cancels the goal and the robot stops. Exit code 0 when the route's end was reached, 1 with
the error code's name (LOST, NO_MAP, STALE_INPUT, TIMEOUT, BAD_INDEX, ...) otherwise.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from skynav_core.cli import add_namespace
from skynav_core.names import FOLLOW_ROUTE_ACTION

HELP = 'drive along a taught route (FollowRoute goal to the running graph)'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav follow`."""
    parser.add_argument(
        'map', nargs='?', type=Path, metavar='MAP.db', help="the route's map (default: the map the nodes have)"
    )
    parser.add_argument(
        '--from',
        dest='start',
        type=int,
        default=-1,
        metavar='I',
        help="the snapshot the robot stands at (e.g. 0 at the route's start: its first views are sought there; "
        'default: wherever localization places the robot)',
    )
    parser.add_argument('--to', dest='end', type=int, default=-1, metavar='J', help='end snapshot (default: the last)')
    parser.add_argument('--max-speed', type=float, default=0.0, metavar='M/S', help="speed limit (default: the node's)")
    parser.add_argument('--wait', type=float, default=10.0, metavar='S', help='wait this long for the server (10 s)')
    add_namespace(parser)


def run(args: argparse.Namespace) -> int:
    """Send the goal and follow it to its end; return the exit code."""
    from skynav_core.cli import CliError
    from skynav_core.goals import ProgressLine, goal_result, send_goal
    from skynav_core.namespaces import namespaced
    from skynav_msgs.action import FollowRoute

    if args.start < -1 or args.end < -1:
        raise CliError('--from and --to must be snapshot indices (or -1)', exit_code=2)
    goal = FollowRoute.Goal(
        map_path=str(args.map.resolve()) if args.map else '',
        start_index=args.start,
        end_index=args.end,
        max_speed=args.max_speed,
    )

    line = ProgressLine()

    def show(feedback) -> None:
        line.show(
            f'snapshot {feedback.matched_index} -> {feedback.target_index}  progress {100 * feedback.progress:5.1f} %'
            f'  confidence {feedback.confidence:.2f}  {feedback.state}'
        )

    try:
        outcome = send_goal(FollowRoute, namespaced(FOLLOW_ROUTE_ACTION, args.namespace), goal, show, args.wait)
    finally:
        line.end()
    result = goal_result(outcome)
    print(f'reached the end: snapshot {result.reached_index}, driven {result.driven_length:.2f} m')
    return 0
