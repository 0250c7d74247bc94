# SPDX-License-Identifier: Apache-2.0
"""Render a scenario into a rosbag2 MCAP recording with the contract's topics and ground truth.

The recording holds, per frame at 10 Hz: the camera's topics, /ground_truth/pose and /ground_truth/mask.
The camera (--camera) is the UV/green pair (/camera/uv/image_raw, /camera/green/image_raw,
/camera/uv/camera_info), or one colour camera: raw on /camera/image_raw (rgb8, bgr8, Bayer, ...: --encoding)
or compressed on /camera/image_raw/compressed (--codec jpeg|png, --jpeg-quality), with /camera/camera_info.
Its metadata (custom_data 'skynav_sim') records the scenario, world, seed, parameters and camera, so
the same command reproduces it byte for byte. Scenarios:

  teach    a drive along a route through the yard
  repeat   the same route (same --seed and --route-seed) at another --time, --offset, --shake, --wobble,
           optionally with a --detour: a loop off the route (frames labelled 'detour', the others 'route')
  homing   a snapshot place and a grid of places around it (--spacing, --grid-radius, --bump-tilt)
  compass  one place under many rotations (--max-tilt), then nearby places (--max-translation)
  skyline  places across the yard at every named time of day, clear and cloudy (--count each)

All of it is synthetic. Examples:
  skynav sim bag teach --world park --seed 3 --length 15 --out synthetic_park_teach.mcap
  skynav sim bag repeat --world garden --seed 1 --camera colour-compressed --out synthetic_garden_colour.mcap
"""

from __future__ import annotations

import argparse
import sys

HELP = 'render a synthetic scenario into an MCAP bag'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav sim bag`."""
    from . import options

    options.add_arguments(parser)
    parser.add_argument('--out', required=True, metavar='FILE.mcap', help='the recording to write (must not exist)')


def run(args: argparse.Namespace) -> int:
    """Render and write; return the exit code."""
    from pathlib import Path

    from tqdm import tqdm

    from skynav_core.cli import CliError

    from .. import recording
    from . import options

    out = Path(args.out)
    if out.exists():
        raise CliError(f'{out} exists already; choose another name or remove it first')
    if not out.parent.is_dir():
        raise CliError(f'{out.parent}: no such directory')
    try:
        camera = options.camera(args)
        output = options.camera_output(args)
        world, frames, description = options.scenario(args)
    except (ValueError, RuntimeError) as exc:
        raise CliError(str(exc), exit_code=2 if isinstance(exc, ValueError) else 1) from None
    with tqdm(
        total=len(frames),
        unit='frame',
        desc=f'synthetic {args.scenario}',
        file=sys.stderr,
        disable=None,
        dynamic_ncols=True,
    ) as bar:
        recording.write(out, world, camera, frames, output, args.seed, description, progress=bar.update)
    through = {
        'uv-green': '',
        'colour': f', colour camera, {output.encoding}',
        'colour-compressed': f', colour camera, {output.encoding} compressed as {output.codec.upper()}',
    }[output.kind]
    print(
        f'skynav sim bag: wrote {len(frames)} synthetic frames ({args.scenario}, {args.world} world, '
        f'seed {args.seed}{through}) to {out}',
        file=sys.stderr,
    )
    return 0
