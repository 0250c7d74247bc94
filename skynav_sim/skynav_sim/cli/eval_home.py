# SPDX-License-Identifier: Apache-2.0
"""Measure closed-loop homing in synthetic worlds: a snapshot, then Home goals from starts 0.5-4 m away, later.

For each world style (--worlds) and seed (--seeds) a snapshot is taken at the world's home place at --teach-time
(`skynav sim home` takes the same); the simulated mower then starts --starts times at random free places
--min-distance to --max-distance away, facing anywhere, at --time under --clouds, and the route node drives it home
by a Home goal and /cmd_vel only (skynav_sim.closed_loop; the controller never sees ground truth). A run succeeds
when it ends within 0.3 m of home. Reports each world and seed and each world's rate, the distance at the end,
the driven path against the straight line and the time standing still, and plots the paths in --out. A start may
have an object between it and home: the controller does not drive around objects (obstacle avoidance is out of
its scope), so each world's rate is also given over the starts with a clear straight line to home. Everything
is synthetic.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'closed-loop homing over synthetic worlds and seeds from starts 0.5-4 m away, at another time'
DEFAULT_SEEDS = (2, 4)  # world seeds not used to tune the homing (park seed 3 was, park seed 5 was looked at)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav eval home`."""
    from .options import add_closed_loop_arguments

    add_closed_loop_arguments(parser, DEFAULT_SEEDS, 'homing')
    parser.add_argument('--starts', type=int, default=10, help='random starts per world and seed (default 10)')
    parser.add_argument('--min-distance', type=float, default=0.5, metavar='M', help='nearest start (0.5 m)')
    parser.add_argument('--max-distance', type=float, default=4.0, metavar='M', help='farthest start (4 m)')
    parser.add_argument(
        '--max-frames', type=int, default=150, help='camera frames (0.2 s each) before a run is given up (150)'
    )
    parser.add_argument(
        '--out', type=Path, default=Path('eval_home'), metavar='DIR', help='folder for maps and plots (eval_home)'
    )


def check_arguments(args: argparse.Namespace) -> tuple[float, float]:
    """Raise CliError for a malformed choice; return the snapshot's and the homing's time of day (h)."""
    from skynav_core.cli import CliError

    from .options import check_closed_loop_arguments

    hours = check_closed_loop_arguments(args)
    if args.starts < 1 or args.max_frames < 1:
        raise CliError('--starts and --max-frames must be at least 1', exit_code=2)
    if not 0 < args.min_distance < args.max_distance:
        raise CliError('need 0 < --min-distance < --max-distance', exit_code=2)
    return hours


def run(args: argparse.Namespace) -> int:
    """Home from every start of every world and seed; print the tables; return the exit code."""
    import time

    import numpy as np
    from tqdm import tqdm

    from skynav_core.evaluation import plots_folder

    from ..closed_loop import clear_line, home_runs, random_starts, snapshot_map
    from ..scenarios import ScenarioParameters, snapshot_place
    from ..world import generate
    from . import options
    from .home import draw_paths

    teach_hours, hours = check_arguments(args)
    camera = options.closed_loop_camera(args)
    base = options.base(args)
    plots_folder(args.out)
    pairs = [(world, seed) for world in args.worlds for seed in args.seeds]
    print(
        f'homing (synthetic): {args.starts} starts {args.min_distance:g}-{args.max_distance:g} m from home in each '
        f'of {len(pairs)} worlds, snapshot at {teach_hours:.1f} h clear, homing at {hours:.1f} h with cloud cover '
        f'{args.clouds:g}'
        + (', without wheel odometry (no /odom)' if args.no_odom else '')
        + options.describe_mount(base),
        flush=True,
    )
    began = time.monotonic()
    results = []
    with tqdm(total=len(pairs) * args.starts, unit='run', file=sys.stderr, disable=None) as bar:
        for style, seed in pairs:
            bar.set_description(f'{style} seed {seed}')
            world = generate(style, seed)
            goal = snapshot_place(world, ScenarioParameters())
            map_path = args.out / f'{style}_seed{seed}_home.db'
            snapshot_map(world, camera, goal, 0.0, teach_hours, seed, map_path, mount=base.mount, output=base.camera)
            starts = random_starts(
                world, goal, args.starts, args.min_distance, args.max_distance, np.random.default_rng(seed)
            )
            if len(starts) < args.starts:
                tqdm.write(f'{style} seed {seed}: only {len(starts)} free start places', file=sys.stderr)
            runs = home_runs(
                world,
                camera,
                goal,
                starts,
                map_path,
                hours,
                seed,
                args.max_frames,
                progress=lambda _: bar.update(),
                clouds=args.clouds,
                base=base,
            )
            clear = [clear_line(world, start, goal) for start, _ in starts]
            results.append((style, seed, runs, clear))
            title = f'SYNTHETIC closed-loop homing: {style} world, seed {seed}, at {hours:.1f} h'
            draw_paths(args.out / f'{style}_seed{seed}.png', world, runs, title)
    print(report(results, args))
    print(f'plots in {args.out}/; {time.monotonic() - began:.0f} s of wall time')
    return 0


def report(results: list, args: argparse.Namespace) -> str:
    """Return the table per world and seed and the rate per world."""
    import numpy as np

    from skynav_core.evaluation import Column, text_table

    from ..closed_loop import FRAME_PERIOD, SUCCESS_RADIUS
    from ..drive_eval import share, time_stopped

    columns = [
        Column('world', 8, align='<'),
        Column('seed', 4),
        Column(f'within {SUCCESS_RADIUS:g} m', 15, align='<'),
        Column('end median', 10, '.2f'),
        Column('end max', 7, '.2f'),
        Column('path/line', 9, '.2f'),
        Column('stopped s', 9, '.1f'),
        Column('clear line', 13, align='<'),
        Column('ended', 30, align='<'),
    ]
    rows = []
    for style, seed, runs, clear in results:
        ends = [r.final_error for r in runs]
        stopped = [time_stopped(np.column_stack([r.path, r.headings]), FRAME_PERIOD) for r in runs]
        outcomes = {name: sum(r.stopped == name for r in runs) for name in dict.fromkeys(r.stopped for r in runs)}
        rows.append(
            [
                style,
                seed,
                share(sum(r.success for r in runs), len(runs)),
                float(np.median(ends)),
                float(np.max(ends)),
                float(np.median([r.path_ratio for r in runs])),
                float(np.mean(stopped)),
                share(sum(r.success for r, c in zip(runs, clear) if c), sum(clear)),
                ', '.join(f'{n} {name}' for name, n in outcomes.items()),
            ]
        )
    lines = [
        "end: distance (m) from home at the end; path/line: driven length over the start's distance (median); "
        'stopped: mean time standing still per run; clear line: within the radius of the starts with no object on '
        'the straight line to home',
        text_table(columns, rows),
    ]
    for style in dict.fromkeys(style for style, _, _, _ in results):
        runs = [r for s, _, rs, _ in results if s == style for r in rs]
        clear = [r for s, _, rs, cs in results if s == style for r, c in zip(rs, cs) if c]
        lines.append(
            f'{style}: {share(sum(r.success for r in runs), len(runs))} of starts '
            f'{args.min_distance:g}-{args.max_distance:g} m away ended within {SUCCESS_RADIUS:g} m of home; '
            f'{share(sum(r.success for r in clear), len(clear))} of those with a clear straight line to home'
        )
    return '\n'.join(lines)
