"""Benchmark: one skyline mask at 640x480 per method, on one core, against OpenCV's Otsu threshold.

    .venv/bin/python bench/skyline_mask.py [--encoding mono8|mono16|32FC1]

Renders three synthetic exposures (garden, park, mineral; forenoon), then times every method of the
skyline node with its shipped parameters, and the peer a user might pick instead: cv2.threshold
with THRESH_OTSU on the UV image (8-bit). Prints median milliseconds per mask and the ratio to the peer.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from skynav_sh.camera import EquidistantCamera  # noqa: E402
from skynav_sim.recording import captures  # noqa: E402
from skynav_sim.scenarios import ScenarioParameters, build  # noqa: E402
from skynav_sim.world import generate  # noqa: E402
from skynav_skyline.geometry import SkylineGeometry  # noqa: E402
from skynav_skyline.parameters import defaults, skyline_params  # noqa: E402
from skynav_skyline.segment import METHODS, SkylineSegmenter  # noqa: E402

REPEATS = 30


def median_ms(function, repeats: int = REPEATS) -> float:
    """Return the median wall time of `function()` in milliseconds."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--encoding', default='mono16', choices=('mono8', 'mono16', '32FC1'))
    args = parser.parse_args()
    cv2.setNumThreads(1)
    camera = EquidistantCamera.for_field_of_view(640, 480, np.radians(200), (0.015, -0.002, 0.0, 0.0))
    exposures = []
    for style in ('garden', 'park', 'mineral'):
        world = generate(style, 4)
        frame = build('skyline', world, ScenarioParameters(count=1), seed=4)[6]  # forenoon, clear
        capture = next(captures(world, camera, [frame], args.encoding, 4))
        exposures.append((capture.uv, capture.green))
    geometry = SkylineGeometry.from_camera(camera)
    peer_input = [cv2.normalize(uv, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8) for uv, _ in exposures]

    def peer() -> None:
        for image in peer_input:
            cv2.threshold(image, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)

    peer_ms = median_ms(peer) / len(exposures)
    print(f'640x480 {args.encoding}, one core, median of {REPEATS} x {len(exposures)} synthetic exposures')
    print(f'{"method":18s} {"channels":9s} {"ms/mask":>8s} {"/ cv2 Otsu":>10s}')
    for channels in ('uv', 'uv-green'):
        for method in METHODS:
            segmenter = SkylineSegmenter(geometry, skyline_params({**defaults(), 'method': method,
                                                                   'channels': channels}))

            def run() -> None:
                for uv, green in exposures:
                    segmenter.segment(uv, green, args.encoding, args.encoding)

            run()
            ms = median_ms(run) / len(exposures)
            print(f'{method:18s} {channels:9s} {ms:8.2f} {ms / peer_ms:10.1f}')
    print(f'{"cv2 Otsu (peer)":18s} {"uv":9s} {peer_ms:8.2f} {1.0:10.1f}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
