# SPDX-License-Identifier: Apache-2.0
"""Measure closed-loop route following in synthetic worlds: teach a long route, follow it later under clouds.

For each world style (--worlds) and seed (--seeds), a scripted operator teaches a planned free route of --length m
(turning both ways, over the terrain's bumps, which tilt the camera 10-20 degrees) at --teach-time while a Teach
goal records the map, as `skynav sim teach` does; the simulated mower then starts --offset m beside the route's
start, turned --turn degrees, at --time under --clouds, and the route node drives it along the route by a
FollowRoute goal and /cmd_vel only, as `skynav sim follow` does (skynav_sim.closed_loop; the controller never sees
ground truth). The route of a world and seed is the first planned route of that length the world has room for
(route seed 0, 1, ...). Each run's map and teach description (DIR/WORLD_seedN/teach.db, teach.yaml) stay in --out,
so `skynav sim follow DIR/WORLD_seedN/teach.yaml --map DIR/WORLD_seedN/teach.db` repeats one follow alone.

Per run and overall it reports success (the goal ended reached, within 1 m of the last snapshot), the cross-track
error (distance of the true path from the taught one, near where the robot is along it: median, 90th percentile,
largest, RMSE; skynav_sim.drive_eval), the driven length against the taught length, the time spent standing still,
and the camera's tilt; it plots each run (the routes from above, the cross-track error along the route) in --out.
Everything is synthetic.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'closed-loop route following over synthetic worlds and seeds: teach, then follow at another time'
ROUTE_TRIES = 50  # planned routes (route seeds) tried per world before a world and seed are given up
DEFAULT_SEEDS = (2, 4)  # world seeds not used to tune the controller (garden seed 1 was); mineral 3 has no 50 m route


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav eval follow`."""
    from .options import add_closed_loop_arguments, add_start_argument

    add_closed_loop_arguments(parser, DEFAULT_SEEDS, 'follow')
    add_start_argument(parser)
    parser.add_argument('--length', type=float, default=50.0, metavar='M', help='route length (default 50 m)')
    parser.add_argument(
        '--offset', type=float, default=0.3, metavar='M', help="start this far left of the route's start (0.3)"
    )
    parser.add_argument(
        '--turn', type=float, default=20.0, metavar='DEG', help='start turned this far left of the route (20)'
    )
    parser.add_argument(
        '--bump-tilt', type=float, default=0.0, metavar='DEG', help='every followed view tilted up to DEG more (0)'
    )
    parser.add_argument(
        '--out', type=Path, default=Path('eval_follow'), metavar='DIR', help='folder for maps and plots (eval_follow)'
    )


def check_arguments(args: argparse.Namespace) -> tuple[float, float]:
    """Raise CliError for a malformed choice; return the teach's and the follow's time of day (h)."""
    from skynav_core.cli import CliError

    from .options import check_closed_loop_arguments

    hours = check_closed_loop_arguments(args)
    if not 2.0 <= args.length <= 200.0:
        raise CliError('--length must be within 2..200 m', exit_code=2)
    if not 0 <= args.bump_tilt <= 90:
        raise CliError('--bump-tilt must be within 0..90 degrees', exit_code=2)
    return hours


def run(args: argparse.Namespace) -> int:
    """Teach and follow every world and seed; print the table; return the exit code."""
    import time

    from tqdm import tqdm

    from skynav_core.evaluation import plots_folder

    from ..closed_loop import FRAME_PERIOD, SPEED, TELEOP_SPEED
    from . import options

    teach_hours, hours = check_arguments(args)
    camera = options.closed_loop_camera(args)
    base = options.base(args)
    plots_folder(args.out)
    pairs = [(world, seed) for world in args.worlds for seed in args.seeds]
    frames = args.length / (TELEOP_SPEED * FRAME_PERIOD) + args.length / (SPEED * FRAME_PERIOD)
    print(
        f'route following (synthetic): {len(pairs)} runs of {args.length:g} m routes, taught at {teach_hours:.1f} h '
        f'clear, followed at {hours:.1f} h with cloud cover {args.clouds:g}, from {args.offset:+.2f} m beside the '
        f'start turned {args.turn:+.0f} deg'
        + (', placed by localization' if args.start_index < 0 else '')
        + (', without wheel odometry (no /odom)' if args.no_odom else '')
        + options.describe_mount(base),
        flush=True,
    )
    began = time.monotonic()
    results = []
    with tqdm(total=int(len(pairs) * frames), unit='frame', file=sys.stderr, disable=None) as bar:
        for world, seed in pairs:
            bar.set_description(f'{world} seed {seed}')
            outcome = evaluate_route(args, world, seed, camera, teach_hours, hours, bar.update)
            if isinstance(outcome, str):
                tqdm.write(f'{world} seed {seed}: {outcome}', file=sys.stderr)
            else:
                results.append(outcome)
    print(report(results, len(pairs)))
    print(f'plots in {args.out}/; {time.monotonic() - began:.0f} s of wall time')
    return 0


def evaluate_route(args, style: str, seed: int, camera, teach_hours: float, hours: float, progress):
    """Teach and follow one route; return its FollowScore, or one line saying why it could not run."""
    import numpy as np

    from skynav_core.goals import GoalOutcome, goal_result
    from skynav_core.maps import MapStore

    from ..closed_loop import FRAME_PERIOD, SPEED, follow_route, teach_route, truth_at
    from ..drive_eval import FollowScore, cross_track, path_length, time_stopped, turns
    from ..errors import SimError
    from ..scenarios import route as planned_route
    from ..world import generate
    from . import options
    from .follow import END_RADIUS
    from .teach import write_description

    world = generate(style, seed)
    for route_seed in range(ROUTE_TRIES):
        try:
            planned_route(world, route_seed, args.length)
            break
        except SimError:
            continue
    else:
        return f'no free route of {args.length:g} m in {ROUTE_TRIES} tries: left out'
    folder = args.out / f'{style}_seed{seed}'
    folder.mkdir(parents=True, exist_ok=True)
    map_path = (folder / 'teach.db').resolve()
    base = options.base(args)
    try:
        teaching = teach_route(
            world,
            camera,
            teach_hours,
            seed,
            args.length,
            map_path,
            base,
            route_seed=route_seed,
            progress=progress,
        )
    except RuntimeError as exc:
        return f'the teach failed ({exc}): left out'
    taught = goal_result(GoalOutcome(teaching.status, teaching.result, True), cancel_finishes=True)
    write_description(folder / 'teach.yaml', style, seed, teach_hours, camera, map_path, teaching, base.mount_rpy_deg)
    with MapStore.open(map_path) as store:
        stamps = np.asarray(store.stamps(), dtype=np.int64)
    route = truth_at(stamps, np.array(teaching.stamps), np.array(teaching.poses))[:, :2]
    forward = route[min(3, len(route) - 1)] - route[0]
    heading = float(np.arctan2(forward[1], forward[0]))
    start = route[0] + args.offset * np.array([-np.sin(heading), np.cos(heading)])
    length = path_length(route)
    run, _ = follow_route(
        world,
        camera,
        map_path,
        start,
        heading + np.radians(args.turn),
        hours,
        seed,
        int(3 * length / (SPEED * FRAME_PERIOD)) + 50,
        bump_tilt=args.bump_tilt,
        route=route,
        clouds=args.clouds,
        progress=progress,
        start_index=args.start_index,
        base=base,
    )
    path = np.array(run.path)
    error, along = cross_track(path, route)
    end = float(np.linalg.norm(path[-1] - route[-1]))
    poses = np.column_stack([path, run.headings])
    answered = run.feedback[1:]  # the first feedback comes before any frame; then one per frame, at path[k]
    frames = np.array(run.path[: len(answered)]).reshape(-1, 2)
    nearest = np.argmin(np.linalg.norm(frames[:, None] - route[None], axis=2), axis=1) if len(frames) else []
    score = FollowScore(
        world=style,
        seed=seed,
        route_seed=route_seed,
        snapshots=int(taught.snapshots),
        taught=length,
        turns=turns(route),
        driven=path_length(path),
        reached=run.stopped == 'reached' and end <= END_RADIUS,
        ended=run.stopped,
        end_distance=end,
        duration=(len(path) - 1) * FRAME_PERIOD,
        stopped=time_stopped(poses, FRAME_PERIOD),
        tilts=np.asarray(run.tilts),
        error=error,
        along=along,
        states=[str(f.state) for f in answered],
        matched=np.array([int(f.matched_index) for f in answered]),
        nearest=np.asarray(nearest, dtype=int),
    )
    draw_run(folder.parent / f'{style}_seed{seed}.png', world, route, path, score)
    return score


def report(scores: list, planned: int) -> str:
    """Return the per-run table and the overall line."""
    import numpy as np

    from skynav_core.evaluation import Column, text_table

    from ..drive_eval import ErrorSummary, share

    columns = [
        Column('world', 8, align='<'),
        Column('seed', 4),
        Column('route', 5),
        Column('taught m', 8, '.1f'),
        Column('turns L/R', 9),
        Column('reached', 7, align='<'),
        Column('end m', 5, '.2f'),
        Column('median', 6, '.2f'),
        Column('p90', 5, '.2f'),
        Column('max', 5, '.2f'),
        Column('RMSE', 5, '.2f'),
        Column('driven m', 8, '.1f'),
        Column('drv/tgt', 7, '.2f'),
        Column('stopped s', 9, '.1f'),
        Column('recov', 5),
        Column('time s', 6, '.0f'),
        Column('tilt p90/max', 12),
    ]
    rows = []
    for s in scores:
        e = ErrorSummary.of(s.error)
        rows.append(
            [
                s.world,
                s.seed,
                s.route_seed,
                s.taught,
                f'{s.turns[0]:.0f}/{s.turns[1]:.0f}',
                'yes' if s.reached else f'NO {s.ended}',
                s.end_distance,
                e.median,
                e.p90,
                e.max,
                e.rmse,
                s.driven,
                s.driven / s.taught,
                s.stopped,
                s.states.count('recovering'),
                s.duration,
                f'{np.percentile(s.tilts, 90):.0f}/{s.tilts.max():.0f} deg',
            ]
        )
    lines = [
        'cross-track error (m) of the true path from the taught route; route: the planned route seed; '
        'turns L/R: degrees the route turns left/right;\nend m: from the last snapshot; '
        'recov: frames recovering (no accepted match or compass estimate)',
        text_table(columns, rows),
    ]
    if scores:
        pooled = ErrorSummary.of(np.concatenate([s.error for s in scores]))
        lines.append(
            f'overall: reached the end in {share(sum(s.reached for s in scores), len(scores))} runs'
            + (f' ({planned - len(scores)} left out)' if planned > len(scores) else '')
            + f'; cross-track error over all {sum(len(s.error) for s in scores)} frames: median {pooled.median:.2f} m, '
            f'90th percentile {pooled.p90:.2f} m, largest {pooled.max:.2f} m, RMSE {pooled.rmse:.2f} m; driven '
            f'{sum(s.driven for s in scores):.0f} m of {sum(s.taught for s in scores):.0f} m taught, '
            f'{sum(s.stopped for s in scores):.0f} s of {sum(s.duration for s in scores):.0f} s standing still'
        )
    else:
        lines.append('overall: no run could be made')
    return '\n'.join(lines)


def draw_run(path: Path, world, route, driven, score) -> None:
    """Plot one run: taught and driven paths from above, and the cross-track error along the route."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    from ..preview import draw_world

    figure, axes = plt.subplot_mosaic(
        [['top', 'error'], ['top', 'places']], figsize=(16, 8), layout='constrained', width_ratios=[1.2, 1]
    )
    top, graph, places = axes['top'], axes['error'], axes['places']
    both = np.vstack([route, driven])
    centre = (both.min(axis=0) + both.max(axis=0)) / 2
    half = float(np.max(both.max(axis=0) - both.min(axis=0))) / 2 + 1.5
    draw_world(figure, top, world, 40.0)
    top.plot(route[:, 0], route[:, 1], '-', color='gold', linewidth=3, label='taught route (snapshots)')
    top.plot(driven[:, 0], driven[:, 1], '-', color='#1565c0', linewidth=1.2, label='driven path')
    top.plot(*driven[0], 's', color='#1565c0', markersize=8, label='start')
    top.plot(*route[-1], '*', color='gold', markeredgecolor='k', markersize=14, label='route end')
    top.set_xlim(centre[0] - half, centre[0] + half)
    top.set_ylim(centre[1] - half, centre[1] + half)
    top.legend(loc='upper right')
    top.set_title(f'SYNTHETIC {score.world} world, seed {score.seed}: taught vs driven')
    graph.plot(score.along, score.error, '-', color='#1565c0', linewidth=1)
    graph.axhline(np.median(score.error), color='k', linestyle='--', linewidth=0.8, label='median')
    graph.set_xlabel('distance along the taught route (m)')
    graph.set_ylabel('cross-track error (m)')
    graph.set_ylim(bottom=0)
    graph.legend(loc='upper right')
    reached = 'reached the end' if score.reached else f'did NOT reach the end ({score.ended})'
    graph.set_title(f'cross-track error along the route ({reached})')
    recovering = np.array([state == 'recovering' for state in score.states], bool)
    frames = np.arange(len(score.states))
    places.plot(frames, score.nearest, '-', color='k', linewidth=1, label='truly nearest snapshot')
    places.plot(frames, score.matched, '-', color='#1565c0', linewidth=1, label='believed passed (controller)')
    places.plot(frames[recovering], score.matched[recovering], 'x', color='#c62828', label='recovering')
    places.set_xlabel('frame')
    places.set_ylabel('snapshot index')
    places.legend(loc='lower right')
    top.plot(*driven[: len(frames)][recovering].T, 'x', color='#c62828', markersize=5, label='recovering')
    figure.savefig(path, dpi=70)
    plt.close(figure)
