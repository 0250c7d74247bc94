# SPDX-License-Identifier: Apache-2.0
"""Learn the global UV/green separator from labelled recordings and write it as the skyline node's parameters.

For each recording's exposures, the normalised log UV and log green values of every pixel inside
the image circle are labelled by /ground_truth/mask; the projection angle a and threshold t that
classify most pixels correctly are learned for the UV/green contrast, and t alone for UV only.
The result is a ROS 2 parameter file for the skyline node (`skynav launch --params`, `skynav run
--params`, or `ros2 launch ... params_file:=`).
"""

from __future__ import annotations

import argparse
import sys

HELP = 'learn the global separator from labelled bags'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav skyline train`."""
    parser.add_argument('bags', nargs='+', metavar='BAG', help='recordings with /ground_truth/mask')
    parser.add_argument('--out', required=True, metavar='params.yaml', help='parameter file to write')
    parser.add_argument(
        '--channels',
        choices=('uv', 'uv-green'),
        default='uv-green',
        help='which the node should use (both are learned; default uv-green)',
    )
    parser.add_argument('--method', default=None, help='method to write (default: keep the shipped one)')
    parser.add_argument(
        '--max-pixels',
        type=int,
        default=2_000_000,
        metavar='N',
        help='learn from at most N pixels, drawn at random (default 2e6)',
    )


def run(args: argparse.Namespace) -> int:
    """Learn and write; return the exit code."""
    import math
    import os
    from pathlib import Path

    import yaml
    from tqdm import tqdm

    from skynav_core.cli import CliError

    from ..classify import learn_global
    from ..eval.dataset import count_frames, labelled_frames
    from ..features import extract_features
    from ..parameters import PARAMETERS
    from ..segment import METHODS

    out = Path(args.out)
    if not out.parent.is_dir():
        raise CliError(f'{out.parent}: no such directory')
    if args.method is not None and args.method not in METHODS:
        raise CliError(f'unknown method {args.method!r} (one of {", ".join(METHODS)})', exit_code=2)
    features, truths, circles = [], [], []
    total = sum(count_frames(path) for path in args.bags)
    with tqdm(total=total, unit='frame', desc='reading', file=sys.stderr, disable=None) as bar:
        for path in args.bags:
            for frame in labelled_frames(path):
                circle = frame.camera.image_circle()
                features.append(extract_features(frame.uv, frame.green, *frame.encoding, circle))
                truths.append(frame.truth)
                circles.append(circle)
                bar.update()
    if not features:
        raise CliError('no labelled exposures in the given recordings')
    models = {}
    for channels in ('uv', 'uv-green'):
        print(f'skynav skyline train: learning the {channels} separator ...', file=sys.stderr)
        models[channels] = learn_global(features, truths, circles, channels=channels, max_samples=args.max_pixels)
    chosen = models[args.channels]
    parameters = {
        'method': args.method or PARAMETERS['method'][0],
        'channels': args.channels,
        'angle_deg': round(math.degrees(models['uv-green'].angle), 3),
        'threshold': round(float(models['uv-green'].threshold), 5),
        'threshold_uv': round(float(models['uv'].threshold), 5),
    }
    header = (
        f'# skyline node parameters learned by `skynav skyline train` from {len(features)} exposures of\n'
        + ''.join(f'#   {path}\n' for path in args.bags)
        + f'# classification rate on those exposures: UV only {100 * models["uv"].rate:.2f} %, '
        f'UV/green {100 * models["uv-green"].rate:.2f} % (a = {parameters["angle_deg"]} deg)\n'
    )
    text = header + yaml.safe_dump({'skyline': {'ros__parameters': parameters}}, sort_keys=False)
    partial = out.with_name(f'.{out.name}.partial')
    partial.write_text(text)
    os.replace(partial, out)
    print(
        f'skynav skyline train: UV only t = {parameters["threshold_uv"]} ({100 * models["uv"].rate:.2f} %), '
        f'UV/green a = {parameters["angle_deg"]} deg, t = {parameters["threshold"]} '
        f'({100 * models["uv-green"].rate:.2f} %); wrote {out} (channels {chosen.channels})',
        file=sys.stderr,
    )
    return 0
