# SPDX-License-Identifier: Apache-2.0
"""Calibrate a fish-eye camera from views of a checkerboard and write the YAML camera drivers read.

INPUT is image files, folders of images, or a recording (rosbag2 MCAP; its image topic, --topic to choose:
by default the first of /camera/image_raw, /camera/image_raw/compressed, /camera/uv/image_raw it holds).
The board has COLSxROWS inner corners and squares of M metres. Hold it, or move the camera, so that its
views cover the whole image circle, the rim included. The command prints the views used and refused (with the
reason), the RMS reprojection error and the share of the image circle the corners covered; it writes
CAMERA.yaml (camera_calibration_parsers' format, distortion_model equidistant: what `camera_info_url`
reads) and a plot of the corners over the image circle (--plot, default CAMERA.png beside the YAML).

  skynav calibrate views/ --board 9x6 --square 0.025 --out fisheye.yaml
  skynav calibrate calibration.mcap --board 9x6 --square 0.025 --out fisheye.yaml --topic /camera/image_raw
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from skynav_core.names import COLOUR_COMPRESSED, COLOUR_IMAGE, UV_IMAGE

if TYPE_CHECKING:
    import numpy as np

    from skynav_core.calibration import Board, Calibration
    from skynav_core.recording.bag import BagReader, RawMessage

HELP = 'calibrate a fish-eye camera from checkerboard views; write its camera YAML'
# Image topics a recording's views are taken from, in the order the default prefers them.
DEFAULT_TOPICS = (COLOUR_IMAGE, COLOUR_COMPRESSED, UV_IMAGE)
IMAGE_TYPES = ('sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage')
# Frames of a recording examined by default (evenly spaced): a minute of video holds far more than a fit needs.
DEFAULT_MAX_FRAMES = 100
# Below these, the report suggests more views: share of the circle's cells holding a corner, largest off-axis (deg).
ADVICE_COVERAGE = 0.6
ADVICE_OFF_AXIS_DEG = 75.0


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav calibrate`."""
    parser.add_argument('inputs', nargs='+', metavar='INPUT', help='image files, folders of images, or a recording')
    parser.add_argument(
        '--board', required=True, metavar='COLSxROWS', help='inner corners of the board, e.g. 9x6 (10x7 squares)'
    )
    parser.add_argument('--square', required=True, type=float, metavar='M', help='side of one square, metres')
    parser.add_argument('--out', required=True, type=Path, metavar='CAMERA.yaml', help='the calibration to write')
    parser.add_argument(
        '--topic',
        metavar='TOPIC',
        help=f'image topic of a recording (default: the first of {", ".join(DEFAULT_TOPICS)})',
    )
    parser.add_argument(
        '--fov',
        type=float,
        metavar='DEG',
        help='full field of view of the lens for the first guess (default: try 180, 200 and 220, keep the best)',
    )
    parser.add_argument(
        '--max-frames',
        type=int,
        default=DEFAULT_MAX_FRAMES,
        metavar='N',
        help=f'frames of a recording to examine, evenly spaced (default {DEFAULT_MAX_FRAMES}; 0: all)',
    )
    parser.add_argument('--plot', type=Path, metavar='FILE.png', help='the plot to write (default: beside the YAML)')
    parser.add_argument('--camera-name', metavar='NAME', help="camera_name in the YAML (default: the file's stem)")


@dataclass
class Frame:
    """One view as read: its name, and its 8-bit grey pixels or why it could not be read."""

    name: str
    grey: np.ndarray | None
    reason: str = ''


@dataclass
class Source:
    """One INPUT: how many views it holds and how to read them."""

    label: str
    count: int
    frames: Iterator[Frame]


def _image_frame(path: Path) -> Frame:
    """Return the view of an image file (8-bit files as they are; 16-bit and float ones taken as linear)."""
    import cv2
    import numpy as np

    from skynav_core.calibration import grey_for_detection

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # a damaged file is refused below, in one line
    try:
        pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    finally:
        cv2.utils.logging.setLogLevel(level)
    if pixels is None:
        return Frame(path.name, None, 'not an image OpenCV can read (damaged, or another format)')
    try:
        return Frame(path.name, grey_for_detection(pixels, linear=pixels.dtype != np.uint8, order='bgr'))
    except ValueError as exc:
        return Frame(path.name, None, str(exc))


def _image_source(paths: list[Path], label: str) -> Source:
    """Return the source of image files."""
    return Source(label, len(paths), (_image_frame(path) for path in paths))


def _recording_source(path: Path, topic: str | None, max_frames: int) -> Source:
    """Return the source of a recording's image topic, at most `max_frames` frames evenly spaced (0: all)."""
    import numpy as np

    from skynav_core.cli import CliError
    from skynav_core.recording.bag import open_bag

    bag = open_bag(path)
    if topic is None:
        topic = next((t for t in DEFAULT_TOPICS if t in bag.topics), None)
        if topic is None:
            bag.close()
            raise CliError(f'{path}: no image topic ({", ".join(DEFAULT_TOPICS)}); choose one with --topic')
    elif topic not in bag.topics:
        bag.close()
        raise CliError(f'{path}: no topic {topic} (it has {", ".join(sorted(bag.topics)) or "none"})')
    if bag.topics[topic].msgtype not in IMAGE_TYPES:
        bag.close()
        raise CliError(f'{path}: {topic} carries {bag.topics[topic].msgtype}, not images')
    count = bag.topics[topic].count
    wanted = count if max_frames <= 0 else min(count, max_frames)
    chosen = set(np.linspace(0, count - 1, wanted).round().astype(int).tolist()) if wanted else set()

    def frames() -> Iterator[Frame]:
        """Yield the chosen frames of the topic, decoded."""
        with bag:
            for index, raw in enumerate(bag.messages([topic])):
                if index in chosen:
                    yield _message_frame(bag, raw, f'{path.name} {topic} #{index}')

    return Source(f'{path} ({topic})', len(chosen), frames())


def _message_frame(bag: BagReader, raw: RawMessage, name: str) -> Frame:
    """Return the view of one recorded Image or CompressedImage message (colour decoded to linear, mono as linear)."""
    from skynav_core.calibration import grey_for_detection
    from skynav_core.colour import decode_compressed, decode_image
    from skynav_core.images import DTYPES, ImageError, image_to_array
    from skynav_core.recording.bag import BagError

    try:
        message = bag.deserialize(raw)
        if raw.msgtype.endswith('CompressedImage'):
            pixels = decode_compressed(message)
        elif message.encoding in DTYPES:
            pixels = image_to_array(message)
        else:
            pixels = decode_image(message)
        return Frame(name, grey_for_detection(pixels, linear=True, order='rgb'))
    except (BagError, ImageError, ValueError) as exc:
        return Frame(name, None, f'cannot decode: {exc}')


def _sources(inputs: list[str], topic: str | None, max_frames: int) -> list[Source]:
    """Return the sources of the INPUT arguments; CliError for one that does not exist or holds no views."""
    from skynav_core.calibration import IMAGE_SUFFIXES
    from skynav_core.cli import CliError

    sources = []
    for text in inputs:
        path = Path(text)
        if not path.exists():
            raise CliError(f'{path}: no such file or folder')
        if path.suffix in ('.mcap', '.db3') or (path.is_dir() and (path / 'metadata.yaml').exists()):
            sources.append(_recording_source(path, topic, max_frames))
        elif path.is_dir():
            images = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
            if not images:
                raise CliError(f'{path}: a folder without images ({", ".join(IMAGE_SUFFIXES)})')
            sources.append(_image_source(images, str(path)))
        else:
            sources.append(_image_source([path], str(path)))
    return sources


def _camera_name(args: argparse.Namespace) -> str:
    """Return camera_name for the YAML: --camera-name, else the output's stem in letters, digits and underscores."""
    import re

    if args.camera_name:
        return args.camera_name
    return re.sub(r'\W', '_', args.out.stem) or 'camera'


def run(args: argparse.Namespace) -> int:
    """Detect, fit, write and report; return the exit code."""
    import numpy as np
    from tqdm import tqdm

    from skynav_core.calibration import Board, View, calibrate, find_corners, find_image_circle, plot_calibration
    from skynav_core.camera_yaml import write_camera_yaml
    from skynav_core.cli import CliError

    try:
        board = Board.parse(args.board, args.square)
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None
    if args.fov is not None and not 0 < args.fov < 360:
        raise CliError(f'--fov must be a full field of view in degrees between 0 and 360, not {args.fov}', exit_code=2)
    if not args.out.parent.is_dir():
        raise CliError(f'{args.out.parent}: no such directory')
    plot_path = args.plot or args.out.with_suffix('.png')
    if not plot_path.parent.is_dir():
        raise CliError(f'{plot_path.parent}: no such directory')
    sources = _sources(args.inputs, args.topic, args.max_frames)
    views: list[View] = []
    sizes: dict[int, tuple[int, int]] = {}  # view index -> (width, height) of the views read
    brightest: dict[tuple[int, int], np.ndarray] = {}  # per image size: the brightest value of each pixel
    with tqdm(total=sum(s.count for s in sources), unit='view', desc='corners', file=sys.stderr, disable=None) as bar:
        for source in sources:
            for frame in source.frames:
                bar.update(1)
                if frame.grey is None:
                    views.append(View(frame.name, None, frame.reason))
                    continue
                size = frame.grey.shape[1], frame.grey.shape[0]
                sizes[len(views)] = size
                brightest[size] = np.maximum(brightest[size], frame.grey) if size in brightest else frame.grey
                corners = find_corners(frame.grey, board)
                views.append(View(frame.name, corners, '' if corners is not None else 'board not found'))
    if not sizes:
        raise CliError(f'no readable views among {len(views)} ({views[0].reason if views else "none given"})')
    # One camera: the image size most views showing the board have (a stray image of another size is refused).
    size = max(brightest, key=lambda s: sum(sizes.get(i) == s and v.used for i, v in enumerate(views)))
    for index, view_size in sizes.items():
        if view_size != size:
            views[index].corners = None
            views[index].reason = f'{view_size[0]}x{view_size[1]}, not {size[0]}x{size[1]} as the views of the board'
    circle = find_image_circle(brightest[size])
    result = calibrate(views, board, size, circle, None if args.fov is None else np.radians(args.fov))
    write_camera_yaml(args.out, result.camera, _camera_name(args))
    plot_calibration(result, brightest[size], plot_path)
    print(report(result, board, args.out, plot_path))
    return 0


def report(result: Calibration, board: Board, out: Path, plot_path: Path) -> str:
    """Return the report of a calibration as text: views, circle, camera, RMS, coverage and the files written."""
    import numpy as np

    from skynav_core.calibration import circle_field_of_view

    camera, circle, coverage = result.camera, result.circle, result.coverage
    width = max(len(v.name) for v in result.views)
    lines = [
        f'{len(result.views)} views of a {board.cols}x{board.rows} board ({board.square * 1000:g} mm squares): '
        f'{len(result.used)} used, {len(result.refused)} refused'
    ]
    for view in result.views:
        status = f'used     {view.rms:.3f} px' if view.used else f'refused  {view.reason}'
        lines.append(f'  {view.name:<{width}}  {status}')
    found = 'found in the views' if circle.fitted else 'fills the frame: its centre and half-diagonal'
    lines += [
        f'image circle: centre ({circle.cx:.1f}, {circle.cy:.1f}) px, radius {circle.radius:.1f} px ({found}); '
        f'first guess from it for a {np.degrees(result.fov_guess):.0f}-degree lens',
        f'camera: fx {camera.fx:.3f}  fy {camera.fy:.3f}  cx {camera.cx:.3f}  cy {camera.cy:.3f} px  '
        f'k1..k4 {" ".join(f"{k:.6g}" for k in camera.k)}',
        f'field of view across the image circle: {np.degrees(circle_field_of_view(result)):.1f} degrees',
        f'RMS reprojection error: {result.rms:.3f} px over {result.corners_used} corners',
        f'coverage: corners in {coverage.cells_filled} of {coverage.cells_total} cells of the image circle '
        f'({coverage.share:.0%}), up to {np.degrees(coverage.max_off_axis):.1f} degrees off-axis',
    ]
    if coverage.share < ADVICE_COVERAGE or np.degrees(coverage.max_off_axis) < ADVICE_OFF_AXIS_DEG:
        lines.append(
            'advice: the corners leave much of the circle empty; add views with the board in the empty parts, '
            'its rim above all (the fit extrapolates where no corner is)'
        )
    lines.append(f'wrote {out} (camera_info_url: file://{out.resolve()}) and the plot {plot_path}')
    return '\n'.join(lines)
