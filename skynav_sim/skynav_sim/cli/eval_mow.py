# SPDX-License-Identifier: Apache-2.0
"""Measure mowing a lawn in synthetic worlds: teach parallel lanes with point turns, repeat them later, resume once.

For each world style (--worlds) and seed (--seeds), a lawn of --lanes lanes, --length m long and --gap m apart, is
placed on free ground of the world (trees, bushes and houses around it; skynav_sim.lawn). A scripted operator
teaches it through a Teach goal at --teach-time, driving each lane straight and turning in place at its ends
(`skynav sim teach` as a user would, with /odom). The simulated mower then starts --offset m beside the first lane,
turned --turn degrees, at --time under --clouds, and repeats the lawn by FollowRoute goals and /cmd_vel only
(skynav_sim.closed_loop). Once it passes --interrupt of the route's snapshots the goal is canceled, as a user
stopping for rain would; a second goal resumes from where the route node recorded the first one ended
(MAP.progress.yaml, as `skynav follow MAP --resume` does), from where the mower stands.

Per lawn it reports whether the repeat reached the end of the last lane, the share of the taught lawn it cut again
(each drive's path widened to --cut m, against the teach's), the widest strip of the taught lawn left uncut, the
cross-track error along the route (median, 90th percentile, largest), and the time; it plots both swaths and the
strips left in --out. Everything is synthetic.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

HELP = 'mow a lawn in synthetic worlds: teach lanes with point turns, repeat them with one interruption, coverage'
DEFAULT_SEEDS = (5,)  # park seed 5 has room for 13 lanes of 8 m; no lawn was used to tune the controller


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav eval mow`."""
    from ..lawn import CUT_WIDTH, LANE_GAP
    from .options import add_closed_loop_arguments

    add_closed_loop_arguments(parser, DEFAULT_SEEDS, 'repeat')
    parser.set_defaults(worlds=['park'])
    parser.add_argument('--lanes', type=int, default=13, metavar='N', help='lanes of the lawn (default 13)')
    parser.add_argument('--length', type=float, default=8.0, metavar='M', help='length of a lane (default 8 m)')
    parser.add_argument(
        '--gap', type=float, default=LANE_GAP, metavar='M', help=f'between lanes (default {LANE_GAP:g} m)'
    )
    parser.add_argument(
        '--cut', type=float, default=CUT_WIDTH, metavar='M', help=f'cutting width (default {CUT_WIDTH:g} m)'
    )
    parser.add_argument(
        '--interrupt',
        type=float,
        default=0.5,
        metavar='SHARE',
        help='cancel the repeat once it passes this share of the snapshots, then resume (0: never; default 0.5)',
    )
    parser.add_argument(
        '--offset', type=float, default=0.2, metavar='M', help="start this far left of the first lane's start (0.2)"
    )
    parser.add_argument('--turn', type=float, default=10.0, metavar='DEG', help='start turned this far left (10)')
    parser.add_argument(
        '--out', type=Path, default=Path('eval_mow'), metavar='DIR', help='folder for maps and plots (eval_mow)'
    )


def check_arguments(args: argparse.Namespace) -> tuple[float, float]:
    """Raise CliError for a malformed choice; return the teach's and the repeat's time of day (h)."""
    from skynav_core.cli import CliError

    from .options import check_closed_loop_arguments

    hours = check_closed_loop_arguments(args)
    if not 1 <= args.lanes <= 60:
        raise CliError('--lanes must be within 1..60', exit_code=2)
    if not 1.0 <= args.length <= 30.0:
        raise CliError('--length must be within 1..30 m', exit_code=2)
    if not 0.1 <= args.gap <= 2.0 or not 0.1 <= args.cut <= 2.0:
        raise CliError('--gap and --cut must be within 0.1..2 m', exit_code=2)
    if not 0.0 <= args.interrupt < 1.0:
        raise CliError('--interrupt must be a share within 0..1 (0: no interruption)', exit_code=2)
    return hours


@dataclass
class MowScore:
    """One lawn taught and repeated."""

    world: str
    seed: int
    lanes: int
    gap: float
    taught: float  # m of the teach's path
    snapshots: int
    reached: bool
    ended: str  # how the last goal ended
    interrupted: int  # snapshot the first goal was canceled at (-1: not interrupted)
    resumed: int  # snapshot the second goal started from (-1: none)
    share: float  # of the taught swath cut again
    widest_uncut: float  # m
    error: Any  # cross-track error (m) per repeat position
    duration: float  # s of both goals


def run(args: argparse.Namespace) -> int:
    """Teach and repeat a lawn in every world and seed; print the table; return the exit code."""
    import time

    from tqdm import tqdm

    from skynav_core.evaluation import plots_folder

    from . import options

    teach_hours, hours = check_arguments(args)
    camera = options.closed_loop_camera(args)
    plots_folder(args.out)
    pairs = [(world, seed) for world in args.worlds for seed in args.seeds]
    print(
        f'mowing (synthetic): {len(pairs)} lawns of {args.lanes} lanes x {args.length:g} m, {args.gap:g} m apart, '
        f'cut {args.cut:g} m; taught at {teach_hours:.1f} h clear, repeated at {hours:.1f} h with cloud cover '
        f'{args.clouds:g} from {args.offset:+.2f} m beside the start turned {args.turn:+.0f} deg'
        + (f', interrupted at {100 * args.interrupt:.0f} % and resumed' if args.interrupt > 0 else ''),
        flush=True,
    )
    began = time.monotonic()
    scores = []
    with tqdm(total=len(pairs), unit='lawn', file=sys.stderr, disable=None) as bar:
        for world, seed in pairs:
            bar.set_description(f'{world} seed {seed}')
            outcome = mow(args, world, seed, camera, teach_hours, hours)
            if isinstance(outcome, str):
                tqdm.write(f'{world} seed {seed}: {outcome}', file=sys.stderr)
            else:
                scores.append(outcome)
            bar.update()
    print(report(scores, len(pairs), args.cut))
    print(f'plots in {args.out}/; {time.monotonic() - began:.0f} s of wall time')
    return 0


def mow(args, style: str, seed: int, camera, teach_hours: float, hours: float) -> MowScore | str:
    """Teach one lawn and repeat it (with an interruption); return its score, or one line saying why not."""
    import numpy as np

    from skynav_core.maps import MapStore
    from skynav_core.route_progress import read_progress

    from ..closed_loop import FRAME_PERIOD, SPEED, follow_route, teach_drive, truth_at
    from ..drive_eval import cross_track
    from ..lawn import LaneOperator, coverage, place_lawn
    from ..mower import Pose2D
    from ..world import generate
    from . import options

    world = generate(style, seed)
    lawn = place_lawn(world, args.lanes, args.length, args.gap, seed=seed)
    if lawn is None:
        return f'no free ground for {args.lanes} lanes of {args.length:g} m: left out'
    folder = args.out / f'{style}_seed{seed}'
    folder.mkdir(parents=True, exist_ok=True)
    map_path = (folder / 'lawn.db').resolve()
    base = options.base(args)
    operator = LaneOperator(lawn)
    corners = lawn.corners()
    first = Pose2D(float(corners[0][0]), float(corners[0][1]), lawn.heading)

    def drive(pose: Pose2D) -> tuple[float, float] | None:
        return None if operator.done else operator.command(pose.x, pose.y, pose.heading)

    frames = int(3 * lawn.path_length / (0.3 * FRAME_PERIOD)) + 40 * args.lanes
    try:
        teaching = teach_drive(world, camera, teach_hours, seed, map_path, first, drive, frames, base)
    except RuntimeError as exc:
        return f'the teach failed ({exc}): left out'
    taught_path = np.array(teaching.poses)[:, :2]
    with MapStore.open(map_path) as store:
        stamps = np.asarray(store.stamps(), dtype=np.int64)
    route = truth_at(stamps, np.array(teaching.stamps), np.array(teaching.poses))[:, :2]
    count = len(route)
    start = corners[0] + args.offset * np.array([-np.sin(lawn.heading), np.cos(lawn.heading)])
    budget = int(3 * lawn.path_length / (SPEED * FRAME_PERIOD)) + 60 * args.lanes
    cancel_at = int(args.interrupt * count) if args.interrupt > 0 else None
    runs, interrupted, resumed = [], -1, -1
    first_run, _ = follow_route(
        world, camera, map_path, start, lawn.heading + np.radians(args.turn), hours, seed, budget,
        base=base, route=route, clouds=args.clouds, start_index=0, cancel_at=cancel_at,
    )  # fmt: skip
    runs.append(first_run)
    if first_run.stopped == 'canceled':
        record = read_progress(map_path)  # what the route node wrote as the goal ended
        interrupted = record.reached_index if record is not None else -1
        resumed = record.resume_from() if record is not None else 0
        stand = first_run.path[-1]
        second, _ = follow_route(
            world, camera, map_path, stand, first_run.headings[-1], hours, seed + 1000, budget,
            base=base, route=route, clouds=args.clouds, start_index=resumed,
        )  # fmt: skip
        runs.append(second)
    last = runs[-1]
    paths = [np.array(r.path) for r in runs]
    cut = coverage(taught_path, paths, args.cut)
    # each goal's error against the route from where it started (a resumed goal from the snapshot it resumed at):
    # searched from the route's start, the resumed drive's first feet would lie on the lanes already mowed
    starts = [0, *([max(resumed - 5, 0)] if len(paths) > 1 else [])]
    error = np.concatenate([cross_track(p, route[first:])[0] for p, first in zip(paths, starts)])
    end = float(np.linalg.norm(paths[-1][-1] - route[-1]))
    score = MowScore(
        world=style,
        seed=seed,
        lanes=args.lanes,
        gap=args.gap,
        taught=float(np.sum(np.linalg.norm(np.diff(taught_path, axis=0), axis=1))),
        snapshots=count,
        reached=last.stopped == 'reached' and end <= 2 * args.gap,
        ended=last.stopped,
        interrupted=interrupted,
        resumed=resumed,
        share=cut.share,
        widest_uncut=cut.widest_uncut,
        error=error,
        duration=sum(len(r.path) - 1 for r in runs) * FRAME_PERIOD,
    )
    arrays = {'taught': np.array(teaching.poses), 'route': route}
    arrays.update({f'repeat{k}': np.column_stack([r.path, r.headings]) for k, r in enumerate(runs)})
    # x, y (m) and heading (rad) per frame, map frame; numpy's stubs take a **kwargs array for its allow_pickle flag
    np.savez(folder / 'paths.npz', **arrays)  # type: ignore[arg-type]
    draw_lawn(folder.parent / f'{style}_seed{seed}_mow.png', taught_path, paths, cut, score)
    return score


def report(scores: list[MowScore], planned: int, cut: float) -> str:
    """Return the per-lawn table and the overall line."""
    from skynav_core.evaluation import Column, text_table

    from ..drive_eval import ErrorSummary

    columns = [
        Column('world', 8, align='<'),
        Column('seed', 4),
        Column('lanes', 5),
        Column('gap m', 5, '.2f'),
        Column('taught m', 8, '.1f'),
        Column('snaps', 5),
        Column('reached', 7, align='<'),
        Column('cut %', 6, '.1f'),
        Column('uncut m', 7, '.2f'),
        Column('xte med', 7, '.2f'),
        Column('p90', 5, '.2f'),
        Column('max', 5, '.2f'),
        Column('stop/resume', 11),
        Column('time s', 6, '.0f'),
    ]
    rows = []
    for s in scores:
        e = ErrorSummary.of(s.error)
        rows.append(
            [
                s.world, s.seed, s.lanes, s.gap, s.taught, s.snapshots,
                'yes' if s.reached else f'NO {s.ended}',
                100 * s.share, s.widest_uncut, e.median, e.p90, e.max,
                f'{s.interrupted}/{s.resumed}' if s.interrupted >= 0 else '-', s.duration,
            ]
        )  # fmt: skip
    lines = [
        f'cut %: share of the taught lawn (its path widened to {cut:g} m) the repeat cut again; uncut m: the widest '
        'strip of it left uncut; xte: cross-track error (m) of the repeat from the taught route;\n'
        'stop/resume: the snapshot the first goal was canceled at and the one the resumed goal started from',
        text_table(columns, rows),
    ]
    if scores:
        lines.append(
            f'overall: {sum(s.reached for s in scores)} of {len(scores)} lawns mowed to the end of the last lane'
            + (f' ({planned - len(scores)} left out)' if planned > len(scores) else '')
            + f'; cut {100 * min(s.share for s in scores):.1f} % at worst; widest uncut strip '
            f'{max(s.widest_uncut for s in scores):.2f} m'
        )
    else:
        lines.append('overall: no lawn could be mowed')
    return '\n'.join(lines)


def draw_lawn(path: Path, taught, paths, cut, score: MowScore) -> None:
    """Plot one lawn from above: the taught swath, the repeat's, the strips left uncut, and the paths."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    grid = cut.grid
    image = np.ones(grid.shape + (3,))
    image[cut.repeated] = (0.75, 0.82, 1.0)  # cut by the repeat only
    image[cut.taught & cut.repeated] = (0.55, 0.85, 0.55)  # cut by both
    image[cut.uncut] = (0.85, 0.1, 0.1)  # taught, left uncut
    extent = (
        grid.origin[0] - grid.cell / 2,
        grid.origin[0] + (grid.shape[1] - 0.5) * grid.cell,
        grid.origin[1] - grid.cell / 2,
        grid.origin[1] + (grid.shape[0] - 0.5) * grid.cell,
    )
    figure, axes = plt.subplots(figsize=(11, 9), layout='constrained')
    axes.imshow(image, origin='lower', extent=extent, interpolation='nearest')
    axes.plot(*taught.T, '-', color='k', linewidth=0.8, label='taught path')
    for k, driven in enumerate(paths):
        label = 'repeat' if len(paths) == 1 else ('repeat, until interrupted' if k == 0 else 'repeat, resumed')
        axes.plot(*driven.T, '-', color=('#1565c0', '#6a1b9a')[k % 2], linewidth=1.0, label=label)
    axes.plot(*taught[0], 's', color='k', markersize=7, label='taught start')
    axes.plot(*taught[-1], '*', color='gold', markeredgecolor='k', markersize=14, label='taught end')
    axes.plot(*paths[0][0], 's', color='#1565c0', markersize=7, label='repeat start')
    if len(paths) > 1:
        axes.plot(*paths[1][0], 'o', color='#6a1b9a', markersize=7, label='resumed here')
    axes.set_aspect('equal')
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0))  # beside the lawn: it hides no start or end
    reached = 'reached the end' if score.reached else f'did NOT reach the end ({score.ended})'
    axes.set_title(
        f'SYNTHETIC {score.world} world, seed {score.seed}: {score.lanes} lanes {score.gap:g} m apart, {reached}\n'
        f'green: cut again ({100 * score.share:.1f} %), red: taught but left uncut (widest '
        f'{score.widest_uncut:.2f} m), blue: cut by the repeat only'
    )
    figure.savefig(path, dpi=80)
    plt.close(figure)
