# SPDX-License-Identifier: Apache-2.0
"""Closed-loop homing in a synthetic world: the graph drives the simulated mower home.

A snapshot is taken at a home place; the simulated mower then starts at random free places up to
--max-distance away. The graph (skyline, SH, compass, warping and the route node) runs in this process; a
Home goal goes to the route node's action server and the mower obeys its /cmd_vel, one command per camera
frame, on sim time (skynav_sim.closed_loop). A run ends with the goal's result (arrived: the home vector stays
unsure; or an error) or after --max-frames. Reports the share of runs that end within 0.3 m of home and the
driven path length relative to the straight line, and plots the paths. Everything is synthetic.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'closed-loop homing of a simulated robot with the skynav nodes'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav sim home`."""
    from ..names import STYLES
    from .options import add_camera_argument, add_mount_arguments

    parser.add_argument('--world', choices=STYLES, default='park', help='world style (default park)')
    parser.add_argument('--seed', type=int, default=3, help='world seed (default 3)')
    parser.add_argument('--starts', type=int, default=20, help='runs from random start places (default 20)')
    parser.add_argument('--min-distance', type=float, default=0.5, metavar='M', help='nearest start (0.5 m)')
    parser.add_argument('--max-distance', type=float, default=4.0, metavar='M', help='farthest start (4 m)')
    parser.add_argument(
        '--max-frames', type=int, default=150, help='camera frames (0.2 s each) before a run is given up (150)'
    )
    parser.add_argument('--time', default='forenoon', help='time of day (default forenoon)')
    parser.add_argument(
        '--bump-tilt',
        type=float,
        default=0.0,
        metavar='DEG',
        help='bumpy ground: every view (the snapshot too) tilted up to DEG more (default 0)',
    )
    parser.add_argument('--size', default='320x240', metavar='WxH', help='camera image size (default 320x240)')
    parser.add_argument('--fov', type=float, default=200.0, metavar='DEG', help='field of view (200)')
    add_mount_arguments(parser)
    add_camera_argument(parser)
    parser.add_argument(
        '--out',
        type=Path,
        default=Path('sim_home'),
        metavar='DIR',
        help='folder for the plot and the snapshot map (default sim_home)',
    )


def run(args: argparse.Namespace) -> int:
    """Run the homing trials; return the exit code."""
    import numpy as np
    from tqdm import tqdm

    from skynav_core.cli import CliError

    from ..closed_loop import home_runs, random_starts, snapshot_map
    from ..scenarios import ScenarioParameters, snapshot_place
    from ..sky import parse_time
    from ..world import generate
    from . import options

    if args.starts < 1 or args.max_frames < 1 or not 0 < args.min_distance < args.max_distance:
        raise CliError('need --starts >= 1, --max-frames >= 1 and 0 < --min-distance < --max-distance', exit_code=2)
    if not 0 <= args.bump_tilt <= 90:
        raise CliError('--bump-tilt must be between 0 and 90 degrees', exit_code=2)
    try:
        hours = parse_time(args.time)
        camera = options.camera(argparse.Namespace(size=args.size, fov=args.fov, distortion=options.DEFAULT_DISTORTION))
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None
    base = options.base(args)
    args.out.mkdir(parents=True, exist_ok=True)
    world = generate(args.world, args.seed)
    goal = snapshot_place(world, ScenarioParameters())
    map_path = args.out / 'home.db'
    snapshot_map(
        world,
        camera,
        goal,
        0.0,
        hours,
        args.seed,
        map_path,
        bump_tilt=args.bump_tilt,
        mount=base.mount,
        output=base.camera,
    )
    starts = random_starts(
        world, goal, args.starts, args.min_distance, args.max_distance, np.random.default_rng(args.seed)
    )
    if len(starts) < args.starts:
        print(f'skynav sim home: only {len(starts)} free start places found', file=sys.stderr)
    with tqdm(total=len(starts), unit='run', desc='homing (synthetic)', file=sys.stderr, disable=None) as bar:
        runs = home_runs(
            world,
            camera,
            goal,
            starts,
            map_path,
            hours,
            args.seed,
            args.max_frames,
            progress=lambda _: bar.update(),
            bump_tilt=args.bump_tilt,
            base=base,
        )
    print(report(runs, args))
    plot = args.out / 'homing_paths.png'
    ground = f', bumps up to {args.bump_tilt:g} deg' if args.bump_tilt else ''
    draw_paths(plot, world, runs, f'SYNTHETIC closed-loop homing: {args.world} world, seed {args.seed}{ground}')
    print(f'plot: {plot}')
    return 0


def report(runs, args) -> str:
    """Return the table of runs and the summary as text."""
    import numpy as np

    from ..closed_loop import SUCCESS_RADIUS

    lines = [f'{"run":>4s} {"start (m)":>10s} {"end (m)":>8s} {"frames":>6s} {"path / line":>12s}  stopped']
    for k, r in enumerate(runs):
        lines.append(
            f'{k:4d} {np.linalg.norm(r.start - r.goal):10.2f} {r.final_error:8.2f} {len(r.path) - 1:6d} '
            f'{r.path_ratio:12.2f}  {r.stopped}{"" if r.success else "  (missed)"}'
        )
    successes = [r for r in runs if r.success]
    ratios = [r.path_ratio for r in successes]
    lines.append(
        f'\n{len(successes)} of {len(runs)} runs ({100 * len(successes) / max(len(runs), 1):.0f} %) ended '
        f'within {SUCCESS_RADIUS} m of home, from starts {args.min_distance}-{args.max_distance} m away; '
        + (
            f'their paths were {np.median(ratios):.2f} times the straight line (median), {max(ratios):.2f} at most'
            if ratios
            else 'none succeeded'
        )
    )
    return '\n'.join(lines)


def draw_paths(path, world, runs, title: str) -> None:
    """Plot the runs' paths over a top view of the world."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    from ..preview import draw_world

    figure, axis = plt.subplots(figsize=(9, 8), layout='constrained')
    goal = runs[0].goal if runs else np.zeros(2)
    extent = max([np.abs(np.array(r.path) - goal).max() for r in runs] + [2.0]) + 1.5
    draw_world(figure, axis, world, 40.0)
    for r in runs:
        points = np.array(r.path)
        axis.plot(points[:, 0], points[:, 1], '-', color='#2e7d32' if r.success else '#c62828', linewidth=1.5)
        axis.plot(*points[0], 'o', color='#1565c0', markersize=4)
    axis.plot(*goal, '*', color='gold', markersize=18, markeredgecolor='k', label='home (snapshot)')
    axis.plot([], [], 'o', color='#1565c0', label='start')
    axis.plot([], [], '-', color='#2e7d32', label='path, ended within 0.3 m')
    axis.plot([], [], '-', color='#c62828', label='path, missed')
    axis.set_xlim(goal[0] - extent, goal[0] + extent)
    axis.set_ylim(goal[1] - extent, goal[1] + extent)
    axis.legend(loc='upper right')
    axis.set_title(title)
    figure.savefig(path, dpi=80)
    plt.close(figure)
