# SPDX-License-Identifier: Apache-2.0
"""Draw a contact sheet of a synthetic scenario or recording: UV, green, ground-truth mask, and a top view (a
colour camera's frames: the frame as delivered, its blue channel and the mask).

Either render a few frames of a scenario (the same options as `skynav sim bag`) or read them from a
recording with --bag; the top view shows the world's relief, its objects and every camera pose.

  skynav sim preview teach --world park --seed 3 --out sheet.png
  skynav sim preview --bag bags/synthetic_garden_teach.mcap --out sheet.png
"""

from __future__ import annotations

import argparse
import sys

from skynav_core.names import (
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    GREEN_IMAGE,
    GROUND_TRUTH_MASK,
    GROUND_TRUTH_POSE,
    UV_IMAGE,
)

HELP = 'draw a contact sheet of a synthetic scenario or bag'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav sim preview`."""
    from . import options

    options.add_arguments(parser)
    for action in parser._actions:
        if action.dest == 'scenario':
            action.nargs = '?'  # not needed with --bag
    parser.add_argument('--bag', metavar='BAG', help='draw frames of this recording instead of rendering')
    parser.add_argument('--frames', type=int, default=4, metavar='N', help='frames to show (default 4)')
    parser.add_argument('--out', required=True, metavar='SHEET.png', help='the image to write')


def run(args: argparse.Namespace) -> int:
    """Draw the sheet; return the exit code."""
    from pathlib import Path

    from skynav_core.cli import CliError

    out = Path(args.out)
    if not out.parent.is_dir():
        raise CliError(f'{out.parent}: no such directory')
    if args.frames < 1:
        raise CliError('--frames must be at least 1', exit_code=2)
    if args.bag:
        frames, positions, world, title = _from_bag(args)
    elif args.scenario:
        frames, positions, world, title = _from_scenario(args)
    else:
        raise CliError('give a SCENARIO to render, or --bag to read', exit_code=2)
    from ..preview import draw

    draw(out, frames, positions, world, title)
    print(f'skynav sim preview: drew {len(frames)} frames to {out}', file=sys.stderr)
    return 0


#: The image topics of each camera a recording may hold, in the order a preview looks for them.
CAMERA_TOPICS = (
    (UV_IMAGE, GREEN_IMAGE),
    (COLOUR_IMAGE,),
    (COLOUR_COMPRESSED,),
)


def _chosen(count: int, wanted: int) -> list[int]:
    """Return up to `wanted` frame indices spread evenly over `count` frames."""
    import numpy as np

    return sorted(set(np.linspace(0, count - 1, min(wanted, count)).round().astype(int).tolist()))


def _from_scenario(args):
    import numpy as np

    from skynav_core.cli import CliError
    from skynav_core.colour import linear_to_srgb8
    from skynav_core.rotations import tilt

    from ..preview import SheetFrame
    from ..recording import captures
    from . import options

    try:
        camera = options.camera(args)
        output = options.camera_output(args)
        world, frames, _ = options.scenario(args)
    except (ValueError, RuntimeError) as exc:
        raise CliError(str(exc), exit_code=2 if isinstance(exc, ValueError) else 1) from None
    chosen = _chosen(len(frames), args.frames)
    sheet = []
    for index, capture in zip(chosen, captures(world, camera, [frames[i] for i in chosen], output, args.seed)):
        f = capture.frame
        signal = capture.exposure.signal
        sheet.append(
            SheetFrame(
                index,
                capture.uv if signal is None else signal[..., 2],
                capture.green if signal is None else signal[..., 1],
                capture.view.sky.astype(np.uint8) * 255,
                f.pose.position,
                f.pose.quaternion,
                f'{f.label}, {f.hours:.2f} h, clouds {f.cloud_cover:g}, '
                f'tilt {np.degrees(tilt(f.pose.rotation)):.0f} deg',
                None if signal is None else linear_to_srgb8(signal),
            )
        )
    positions = np.array([f.pose.position for f in frames])
    title = (
        f'SYNTHETIC {args.scenario}: {args.world} world, seed {args.seed}, {len(frames)} frames, '
        f'{camera.width}x{camera.height}, fov {args.fov:g} deg, {output.kind} camera, {output.encoding}'
    )
    return sheet, positions, world, title


def _from_bag(args):
    import numpy as np
    import yaml

    from skynav_core.colour import LINEAR_FULL_SCALE, linear_to_srgb8
    from skynav_core.recording.bag import open_bag

    from ..preview import SheetFrame
    from ..world import generate

    with open_bag(args.bag) as bag:
        cameras = [names for names in CAMERA_TOPICS if all(topic in bag.topics for topic in names)]
        for topic in (cameras[0] if cameras else CAMERA_TOPICS[0]) + (GROUND_TRUTH_MASK, GROUND_TRUTH_POSE):
            if topic not in bag.topics:
                from skynav_core.cli import CliError

                raise CliError(f'{args.bag} has no {topic}; a preview needs images, masks and poses')
        wanted = [*cameras[0], GROUND_TRUTH_MASK, GROUND_TRUTH_POSE]
        by_stamp: dict[int, dict] = {}
        for message in bag.messages(wanted):
            data = bag.deserialize(message)
            stamp = data.header.stamp.sec * 10**9 + data.header.stamp.nanosec
            by_stamp.setdefault(stamp, {})[message.topic] = data
        info = yaml.safe_load(bag.custom_data.get('skynav_sim', '') or '{}') or {}
    complete = [by_stamp[s] for s in sorted(by_stamp) if len(by_stamp[s]) == len(wanted)]
    labels = info.get('frames', [])
    chosen = _chosen(len(complete), args.frames)
    sheet = []
    for index in chosen:
        parts = complete[index]
        pose = parts[GROUND_TRUTH_POSE].pose
        label = labels[index] if index < len(labels) else {}
        caption = (
            f'{label.get("label", "")}, {label.get("hours", "?")} h, clouds {label.get("cloud_cover", "?")}'
            if label
            else ''
        )
        colour = _linear_rgb(parts)
        sheet.append(
            SheetFrame(
                index,
                _pixels(parts[UV_IMAGE]) if colour is None else colour[..., 2],
                _pixels(parts[GREEN_IMAGE]) if colour is None else colour[..., 1],
                _pixels(parts[GROUND_TRUTH_MASK]),
                np.array([pose.position.x, pose.position.y, pose.position.z]),
                np.array([pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w]),
                caption,
                None if colour is None else linear_to_srgb8(colour / LINEAR_FULL_SCALE),
            )
        )
    positions = np.array(
        [[p[GROUND_TRUTH_POSE].pose.position.x, p[GROUND_TRUTH_POSE].pose.position.y] for p in complete]
    ).reshape(-1, 2)
    world = generate(info['world'], int(info['world_seed'])) if 'world' in info else None
    kind = 'SYNTHETIC ' if info.get('synthetic') else ''
    camera = info.get('camera', {})
    title = (
        f'{kind}recording {args.bag}: {len(complete)} frames'
        + (f', {info.get("scenario")} in the {info.get("world")} world, seed {info.get("seed")}' if info else '')
        + (f', {camera.get("kind")} camera ({camera.get("encoding")})' if camera else '')
    )
    return sheet, positions, world, title


def _linear_rgb(parts: dict):
    """Return the linear RGB (H, W, 3, uint16) of a colour camera's frame among a stamp's messages (None: no such
    frame), decoded as the nodes decode it."""
    from skynav_core.colour import decode_compressed, decode_image

    if COLOUR_IMAGE in parts:
        return decode_image(parts[COLOUR_IMAGE])
    if COLOUR_COMPRESSED in parts:
        return decode_compressed(parts[COLOUR_COMPRESSED])
    return None


def _pixels(image):
    """Return the pixels of a rosbags sensor_msgs/Image (mono8, mono16 or 32FC1)."""
    import numpy as np

    dtype = {'mono8': np.uint8, 'mono16': np.uint16, '32FC1': np.float32}[image.encoding]
    return np.frombuffer(image.data.tobytes(), dtype=dtype).reshape(image.height, image.width)
