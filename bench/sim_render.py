# SPDX-License-Identifier: Apache-2.0
"""Benchmark: rendering one synthetic fish-eye frame (ray casting, shading, sensor), per world style and camera.

    .venv/bin/python bench/sim_render.py [--frames N] [--cameras uv-green colour colour-compressed]

Prints the median and 90th percentile wall time per frame over N frames of a teach drive, at
640x480 and 320x240 with a 200-degree field of view, on one thread, and the ratio to the 0.1 s
frame period of the contract's recordings (below 1: faster than real time), for each camera: the
UV/green pair (mono16), a colour camera (rgb8) and one delivering JPEG (quality 95), all synthetic.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import time  # noqa: E402

import numpy as np  # noqa: E402

from skynav_core.camera import EquidistantCamera  # noqa: E402
from skynav_sim.recording import CAMERAS, CameraOutput, captures  # noqa: E402
from skynav_sim.scenarios import ScenarioParameters, build  # noqa: E402
from skynav_sim.world import STYLES, generate  # noqa: E402

FRAME_PERIOD = 0.1  # s
ENCODING = {'uv-green': 'mono16', 'colour': 'rgb8', 'colour-compressed': 'rgb8'}  # each camera's, as timed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--frames', type=int, default=12)
    parser.add_argument('--cameras', nargs='+', choices=CAMERAS, default=list(CAMERAS))
    args = parser.parse_args()
    print(f'{"world":8s} {"size":>8s} {"camera":>18s} {"median":>9s} {"p90":>9s} {"/ 0.1 s":>8s}')
    for style in STYLES:
        world = generate(style, 1)
        frames = build('teach', world, ScenarioParameters(route_length=6.0, speed=0.5), seed=1)
        chosen = frames[:: max(1, len(frames) // args.frames)][: args.frames]
        for width, height in ((640, 480), (320, 240)):
            camera = EquidistantCamera.for_field_of_view(width, height, np.radians(200), (0.015, -0.002, 0, 0))
            for kind in args.cameras:
                times = []
                output = CameraOutput(kind, ENCODING[kind])
                stream = captures(world, camera, [chosen[0]] + chosen, output, 1)
                next(stream)  # the first frame also builds the shadow map of the sun; not counted
                start = time.perf_counter()
                for _ in chosen:
                    next(stream)
                    now = time.perf_counter()
                    times.append(now - start)
                    start = now
                median, p90 = np.median(times), np.percentile(times, 90)
                print(
                    f'{style:8s} {width:>4d}x{height:<3d} {kind:>18s} {median * 1e3:7.0f}ms {p90 * 1e3:7.0f}ms '
                    f'{median / FRAME_PERIOD:8.2f}',
                    flush=True,
                )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
