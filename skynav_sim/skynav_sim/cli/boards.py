# SPDX-License-Identifier: Apache-2.0
"""Render synthetic checkerboard views through a known fish-eye camera, to try `skynav calibrate` on.

Writes DIR/synthetic_board_NN.png (8-bit sRGB colour, as a driver delivers), the camera they were rendered
through as DIR/synthetic_truth.yaml (the same YAML format `skynav calibrate` writes, to compare with), and
DIR/synthetic_boards.yaml saying how they were made. The board is held as a person calibrating holds it: its
centre at off-axis angles from 0 to 86 degrees, all round the circle, 0.28-0.5 m from the lens, facing it.
Everything here is synthetic.

  skynav sim boards --out boards/ --count 21
  skynav calibrate boards/ --board 9x6 --square 0.025 --out boards/fisheye.yaml
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'render synthetic checkerboard views for `skynav calibrate`'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav sim boards`."""
    parser.add_argument('--out', required=True, type=Path, metavar='DIR', help='folder to write into (created)')
    parser.add_argument('--count', type=int, default=21, metavar='N', help='views to render (default 21)')
    parser.add_argument('--board', default='9x6', metavar='COLSxROWS', help='inner corners (default 9x6)')
    parser.add_argument('--square', type=float, default=0.025, metavar='M', help='square side, m (default 0.025)')
    parser.add_argument('--size', default='640x480', metavar='WxH', help='image size in pixels (default 640x480)')
    parser.add_argument(
        '--fov', type=float, default=200.0, metavar='DEG', help="the lens's field of view (default 200)"
    )
    parser.add_argument('--seed', type=int, default=0, help='poses, sky and noise seed (default 0)')


def run(args: argparse.Namespace) -> int:
    """Render and write; return the exit code."""
    import cv2
    import numpy as np
    import yaml
    from tqdm import tqdm

    from skynav_core.calibration import Board
    from skynav_core.camera_yaml import write_camera_yaml
    from skynav_core.cli import CliError

    from ..checkerboard import BoardRenderer, Checkerboard, calibration_poses, synthetic_fisheye
    from ..errors import SimError

    try:
        board = Board.parse(args.board, args.square)
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None
    try:
        width, height = (int(x) for x in args.size.lower().split('x'))
    except ValueError:
        raise CliError(f'--size must be WxH in pixels, such as 640x480, not {args.size!r}', exit_code=2) from None
    if not (args.count >= 1 and 16 <= min(width, height) and 90 < args.fov <= 220):
        raise CliError('--count must be >= 1, --size at least 16x16 and --fov between 90 and 220 degrees', exit_code=2)
    fov = np.radians(args.fov)
    camera = synthetic_fisheye(width, height, fov)
    checkerboard = Checkerboard(board.cols, board.rows, board.square)
    try:
        poses = calibration_poses(camera, checkerboard, args.count, args.seed, fov)
    except SimError as exc:
        raise CliError(str(exc)) from None
    args.out.mkdir(parents=True, exist_ok=True)
    renderer = BoardRenderer(camera, checkerboard, fov, seed=args.seed)
    for index, pose in enumerate(tqdm(poses, unit='view', desc='synthetic boards', file=sys.stderr, disable=None)):
        image = renderer.render(pose, index)
        cv2.imwrite(str(args.out / f'synthetic_board_{index:02d}.png'), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    write_camera_yaml(args.out / 'synthetic_truth.yaml', camera, 'synthetic_fisheye')
    description = {
        'synthetic': True,
        'made_by': f'skynav sim boards --count {args.count} --board {args.board} --square {args.square:g} '
        f'--size {width}x{height} --fov {args.fov:g} --seed {args.seed}',
        'views': args.count,
        'board': {'cols': board.cols, 'rows': board.rows, 'square_m': board.square},
        'lens_fov_deg': args.fov,
        'seed': args.seed,
        'camera': 'synthetic_truth.yaml',
    }
    (args.out / 'synthetic_boards.yaml').write_text(yaml.safe_dump(description, sort_keys=False))
    print(
        f'skynav sim boards: wrote {args.count} synthetic views of a {board.cols}x{board.rows} board through a '
        f'{args.fov:g}-degree lens to {args.out} (the camera: {args.out / "synthetic_truth.yaml"})',
        file=sys.stderr,
    )
    return 0
