# SPDX-License-Identifier: Apache-2.0
"""Benchmark: decoding a colour camera's 640x480 frame to linear RGB, on one core, against plain cv2.imdecode.

    taskset -c 0 .venv/bin/python bench/colour_decode.py

Renders one synthetic colour exposure (garden, forenoon) and times, per frame, what the skyline node does with
each kind of input (skynav_core.colour): a JPEG through image_transport's `compressed` (cv2.imdecode, BGR to RGB,
sRGB to linear), a PNG likewise, raw rgb8 and bgr8 (sRGB to linear), a Bayer mosaic (demosaic, sRGB to linear),
and 16-bit linear rgb16. The peer is the decode a user would write anyway: plain cv2.imdecode of the same JPEG
(8-bit BGR, nothing more). Prints the median and 90th percentile of milliseconds per frame, and for the
compressed inputs what decoding adds on top of the peer (the target: under 3 ms per 640x480 frame).
"""

from __future__ import annotations

import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from sensor_msgs.msg import CompressedImage, Image  # noqa: E402

from skynav_core.camera import EquidistantCamera  # noqa: E402
from skynav_core.colour import compress, decode_compressed, decode_image, linear_to_srgb8, mosaic  # noqa: E402
from skynav_core.images import fill_image  # noqa: E402
from skynav_sim.recording import CameraOutput, captures  # noqa: E402
from skynav_sim.scenarios import ScenarioParameters, build  # noqa: E402
from skynav_sim.world import generate  # noqa: E402

REPEATS = 300


def times_ms(call, repeats: int = REPEATS) -> np.ndarray:
    """Return the wall time (ms) of each of `repeats` calls of `call()`, after one to warm up."""
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return 1e3 * np.asarray(times)


def main() -> int:
    cv2.setNumThreads(1)
    camera = EquidistantCamera.for_field_of_view(640, 480, np.radians(200), (0.015, -0.002, 0.0, 0.0))
    world = generate('garden', 4)
    frame = build('skyline', world, ScenarioParameters(count=1), seed=4)[6]  # forenoon, clear
    capture = next(captures(world, camera, [frame], CameraOutput('colour', 'rgb8'), 4))
    signal = capture.exposure.signal
    assert signal is not None  # a colour camera's exposure carries its linear signal
    srgb = linear_to_srgb8(signal)
    jpeg, png = CompressedImage(), CompressedImage()
    jpeg.format, jpeg.data = compress(srgb, 'jpeg', 90)
    png.format, png.data = compress(srgb, 'png')
    inputs = {
        'jpeg (compressed)': (decode_compressed, jpeg),
        'png (compressed)': (decode_compressed, png),
        'rgb8': (decode_image, fill_image(Image(), srgb, 'rgb8')),
        'bgr8': (decode_image, fill_image(Image(), srgb[..., ::-1], 'bgr8')),
        'bayer_rggb8': (decode_image, fill_image(Image(), mosaic(srgb, 'rggb'), 'bayer_rggb8')),
        'rgb16 (linear)': (decode_image, fill_image(Image(), np.rint(signal * 65535).astype(np.uint16), 'rgb16')),
    }
    jpeg_bytes = np.frombuffer(bytes(jpeg.data), np.uint8)
    peer = times_ms(lambda: cv2.imdecode(jpeg_bytes, cv2.IMREAD_UNCHANGED))
    peer_median = float(np.median(peer))
    png_bytes = np.frombuffer(bytes(png.data), np.uint8)
    png_peer_median = float(np.median(times_ms(lambda: cv2.imdecode(png_bytes, cv2.IMREAD_UNCHANGED))))
    print(f'640x480 synthetic colour frame (garden, forenoon), {REPEATS} decodes each, one thread')
    print(f'{"input":20s} {"median ms":>9s} {"p90 ms":>7s} {"added ms":>9s}')
    for name, (decode, message) in inputs.items():
        ms = times_ms(lambda decode=decode, message=message: decode(message))
        median = float(np.median(ms))
        base = {'jpeg (compressed)': peer_median, 'png (compressed)': png_peer_median}.get(name)
        added = f'{median - base:9.2f}' if base is not None else f'{"":9s}'
        print(f'{name:20s} {median:9.2f} {np.percentile(ms, 90):7.2f} {added}')
    print(f'{"cv2.imdecode (peer)":20s} {peer_median:9.2f} {np.percentile(peer, 90):7.2f}   (JPEG, 8-bit BGR only)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
