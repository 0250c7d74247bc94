# SPDX-License-Identifier: Apache-2.0
"""sensor_msgs/Image <-> numpy for the encodings of the contract, with checks that name what is wrong.

Works with rclpy and rosbags message objects alike (only their fields are used).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .errors import SkynavError

if TYPE_CHECKING:
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

DTYPES: dict[str, np.dtype] = {
    'mono8': np.dtype(np.uint8),
    'mono16': np.dtype(np.uint16),
    '32FC1': np.dtype(np.float32),
}


class ImageError(SkynavError, ValueError):
    """An image message that cannot be read; `reason` is a short tag for diagnostics counts."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason


def image_to_array(message: Image, encodings: tuple[str, ...] = tuple(DTYPES)) -> np.ndarray:
    """Return the pixels (height, width) of a single-channel Image message in its encoding's dtype."""
    encoding = message.encoding
    if encoding not in encodings:
        raise ImageError('encoding', f'encoding {encoding!r} is not one of {", ".join(encodings)}')
    dtype = DTYPES[encoding]
    height, width, step = int(message.height), int(message.width), int(message.step)
    if height <= 0 or width <= 0:
        raise ImageError('malformed', f'image size {width}x{height} is empty')
    if step < width * dtype.itemsize:
        raise ImageError('malformed', f'step {step} is shorter than a row of {width} {encoding} pixels')
    data = np.frombuffer(bytes(message.data) if not isinstance(message.data, np.ndarray) else message.data, np.uint8)
    if data.size != step * height:
        raise ImageError('malformed', f'{data.size} data bytes for {height} rows of {step} bytes')
    rows = data.reshape(height, step)[:, : width * dtype.itemsize]
    pixels = np.ascontiguousarray(rows).view(dtype.newbyteorder('>' if message.is_bigendian else '<'))
    return pixels.astype(dtype, copy=False).reshape(height, width)


def fill_image(message: Image, pixels: np.ndarray, encoding: str) -> Image:
    """Fill an (empty) Image message with single-channel pixels in `encoding`; return it."""
    pixels = np.ascontiguousarray(pixels, DTYPES[encoding])
    message.height, message.width = pixels.shape
    message.encoding = encoding
    message.is_bigendian = 0
    message.step = pixels.shape[1] * pixels.itemsize
    message.data = pixels.tobytes()  # bytes, not an array: assigning bytes is ~100x faster in rclpy
    return message


def stamp_ns(header: Header) -> int:
    """Return a header's stamp in nanoseconds since the epoch."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
