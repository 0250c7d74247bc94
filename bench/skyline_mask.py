# SPDX-License-Identifier: Apache-2.0
"""Benchmark: one skyline mask at 640x480 per method, on one core, against OpenCV's Otsu threshold.

    .venv/bin/python bench/skyline_mask.py [--encoding mono8|mono16|32FC1]

Renders three synthetic exposures (garden, park, mineral; forenoon), then times every method of the
skyline node with its shipped parameters, the default method once more without the structure steps
(enclosed ground, ground ring: what they cost) and without its fit check (max_disagreement), the colour
camera's method (colour_method) on the same
exposures seen by a synthetic colour camera (uint16 linear RGB, as skynav_core.colour decodes a frame), and
the peer a user might pick instead: cv2.threshold with THRESH_OTSU on the UV image (8-bit). Every mask is
timed on its own; prints the median and the 90th percentile of milliseconds per mask over all repeats, and
the ratio of the medians to the peer's. Pin it to one core (`taskset -c 0`) for the one-core figure.
"""

from __future__ import annotations

import argparse
import math
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from skynav_core.camera import EquidistantCamera  # noqa: E402
from skynav_sim.recording import CameraOutput, captures  # noqa: E402
from skynav_sim.scenarios import ScenarioParameters, build  # noqa: E402
from skynav_sim.world import generate  # noqa: E402
from skynav_skyline.geometry import SkylineGeometry  # noqa: E402
from skynav_skyline.parameters import colour_params, defaults, skyline_params  # noqa: E402
from skynav_skyline.segment import METHODS, SkylineSegmenter  # noqa: E402

REPEATS = 60


def mask_times_ms(segment_one, inputs, repeats: int = REPEATS) -> np.ndarray:
    """Return the wall time (ms) of every call `segment_one(*pair)` over `repeats` rounds of the inputs."""
    times = []
    for _ in range(repeats):
        for pair in inputs:
            start = time.perf_counter()
            segment_one(*pair)
            times.append(time.perf_counter() - start)
    return 1e3 * np.asarray(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--encoding', default='mono16', choices=('mono8', 'mono16', '32FC1'))
    args = parser.parse_args()
    cv2.setNumThreads(1)
    camera = EquidistantCamera.for_field_of_view(640, 480, np.radians(200), (0.015, -0.002, 0.0, 0.0))
    exposures, colour_frames = [], []
    for style in ('garden', 'park', 'mineral'):
        world = generate(style, 4)
        frame = build('skyline', world, ScenarioParameters(count=1), seed=4)[6]  # forenoon, clear
        capture = next(captures(world, camera, [frame], args.encoding, 4))
        exposures.append((capture.uv, capture.green))
        signal = next(captures(world, camera, [frame], CameraOutput('colour', 'rgb16'), 4)).exposure.signal
        assert signal is not None  # a colour camera's exposure carries its linear signal
        colour_frames.append((np.rint(signal * 65535).astype(np.uint16),))
    geometry = SkylineGeometry.from_camera(camera)
    peer_input = [cv2.normalize(uv, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8) for uv, _ in exposures]

    def peer(image: np.ndarray) -> None:
        cv2.threshold(image, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)

    peer_ms = mask_times_ms(peer, [(image,) for image in peer_input])
    peer_median = float(np.median(peer_ms))
    print(f'640x480 {args.encoding}, {REPEATS} x {len(exposures)} synthetic exposures, each mask timed')
    print(f'{"method":18s} {"channels":9s} {"median ms":>9s} {"p90 ms":>7s} {"/ cv2 Otsu":>10s}')
    shipped = defaults()
    rows = [(method, channels, {}) for channels in ('uv', 'uv-green') for method in METHODS]
    rows.append((shipped['method'], shipped['channels'], {'hole_margin': 0.0, 'ring_share': math.inf}))
    rows.append((shipped['method'], shipped['channels'], {'max_disagreement': math.inf}))
    for method, channels, changes in rows:
        segmenter = SkylineSegmenter(
            geometry, skyline_params({**shipped, 'method': method, 'channels': channels, **changes})
        )

        def run(uv: np.ndarray, green: np.ndarray) -> None:
            segmenter.segment(uv, green, args.encoding, args.encoding)

        mask_times_ms(run, exposures, 1)  # warm up
        ms = mask_times_ms(run, exposures)
        median = float(np.median(ms))
        label = method + (' -fit check' if 'max_disagreement' in changes else ' -structure' if changes else '')
        print(f'{label:18s} {channels:9s} {median:9.2f} {np.percentile(ms, 90):7.2f} {median / peer_median:10.1f}')
    colour = colour_params(shipped)
    segmenter = SkylineSegmenter(geometry, colour)
    mask_times_ms(segmenter.segment_colour, colour_frames, 1)  # warm up
    ms = mask_times_ms(segmenter.segment_colour, colour_frames)
    median = float(np.median(ms))
    print(f'{colour.method:18s} {"colour":9s} {median:9.2f} {np.percentile(ms, 90):7.2f} {median / peer_median:10.1f}')
    print(f'{"cv2 Otsu (peer)":18s} {"uv":9s} {peer_median:9.2f} {np.percentile(peer_ms, 90):7.2f} {1.0:10.1f}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
