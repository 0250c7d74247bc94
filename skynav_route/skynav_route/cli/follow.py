# SPDX-License-Identifier: Apache-2.0
"""Drive the robot along a taught route: send a FollowRoute goal to the running graph (`skynav launch`).

The route node localizes on the map's route and drives along it to --to (default: its last snapshot), one
velocity command per camera frame on /cmd_vel. The progress line shows the matched and target snapshots,
the progress from --from to --to, the confidence and the state (localizing, following, recovering,
stopping). Ctrl-C cancels the goal and the robot stops. Exit code 0 when the route's end was reached, 1 with
the error code's name (LOST, NO_MAP, STALE_INPUT, TIMEOUT, BAD_INDEX, ...) otherwise.

With --resume the goal carries on where the last follow goal on that map ended (canceled, LOST, an emergency stop,
...): from its last snapshot passed to its end, as the route node recorded beside the map (MAP.progress.yaml,
skynav_core.route_progress), so that lanes already mowed are not mowed again.
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
    parser.add_argument(
        '--resume',
        action='store_true',
        help='carry on from where the last follow goal on MAP ended (its record beside the map), to its end',
    )
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
    if args.resume:
        resumed = resume(args)
        if resumed is None:
            return 0
        args.start, args.end = resumed
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


def resume(args: argparse.Namespace) -> tuple[int, int] | None:
    """Return the (start, end) snapshots that carry on from the last follow goal on the map; None if it had reached
    its end (nothing to resume). CliError where there is nothing to resume from."""
    import time

    from skynav_core.cli import CliError
    from skynav_core.maps import MapError, MapStore
    from skynav_core.route_progress import ProgressError, progress_path, read_progress

    if args.map is None:
        raise CliError('--resume needs the map: skynav follow MAP.db --resume', exit_code=2)
    if args.start != -1:
        raise CliError('--resume starts where the last goal ended: leave out --from', exit_code=2)
    try:
        progress = read_progress(args.map)
    except ProgressError as exc:
        raise CliError(f'cannot resume: {exc}', exit_code=2) from None
    if progress is None:
        raise CliError(
            f'nothing to resume: no follow goal on {args.map} has ended yet ({progress_path(args.map).name} is '
            'missing); start one with --from',
            exit_code=2,
        )
    try:
        with MapStore.open(args.map) as store:
            count = len(store)
    except MapError as exc:
        raise CliError(str(exc), exit_code=2) from None
    if count != progress.snapshots:
        raise CliError(
            f'cannot resume: {args.map} has {count} snapshots, the last goal ran on {progress.snapshots} (the map was '
            'taught again since); start with --from',
            exit_code=2,
        )
    when = time.strftime('%Y-%m-%d %H:%M', time.localtime(progress.ended_at))
    end = progress.end_index if args.end < 0 else args.end
    if progress.finished and end <= progress.reached_index:
        print(f'nothing to resume: the last goal on {args.map.name} reached its end, snapshot {end} ({when})')
        return None
    start = progress.resume_from()
    if start > end:
        raise CliError(f'cannot resume: the last goal passed snapshot {start}, beyond --to {end}', exit_code=2)
    print(
        f'resuming: the last goal ended {progress.outcome} at snapshot {progress.reached_index} ({when}); '
        f'following snapshots {start}..{end}'
    )
    return start, end
