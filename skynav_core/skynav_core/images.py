# SPDX-License-Identifier: Apache-2.0
"""sensor_msgs/Image <-> numpy for the encodings of the contract, with checks that name what is wrong.

Works with rclpy and rosbags message objects alike (only their fields are used). Mono encodings come back as
(height, width) arrays, colour and alpha encodings as (height, width, channels) in the encoding's channel order;
skynav_core.colour turns colour, Bayer and compressed frames into linear RGB.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .errors import SkynavError

if TYPE_CHECKING:
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header


class Layout(NamedTuple):
    """How an encoding stores one pixel: its sample type and number of channels."""

    dtype: np.dtype
    channels: int


_U8, _U16 = np.dtype(np.uint8), np.dtype(np.uint16)
#: The single-channel encodings of the UV/green pair (docs/interfaces.md, "Topics").
DTYPES: dict[str, np.dtype] = {'mono8': _U8, 'mono16': _U16, '32FC1': np.dtype(np.float32)}
#: The Bayer patterns of a colour camera, as ROS names them (the colours of the first two rows' first two pixels).
BAYER_PATTERNS = ('rggb', 'bggr', 'gbrg', 'grbg')
#: Every encoding skynav reads, with its layout: the mono ones above and those of a colour camera.
LAYOUTS: dict[str, Layout] = {
    **{name: Layout(dtype, 1) for name, dtype in DTYPES.items()},
    **{
        f'{order}{bits}': Layout(dtype, len(order))
        for order in ('rgb', 'bgr', 'rgba', 'bgra')
        for bits, dtype in (('8', _U8), ('16', _U16))
    },
    **{
        f'bayer_{pattern}{bits}': Layout(dtype, 1)
        for pattern in BAYER_PATTERNS
        for bits, dtype in (('8', _U8), ('16', _U16))
    },
}


class ImageError(SkynavError, ValueError):
    """An image message that cannot be read; `reason` is a short tag for diagnostics counts."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason


def image_to_array(message: Image, encodings: tuple[str, ...] = tuple(DTYPES)) -> np.ndarray:
    """Return the pixels of an Image message in its encoding's dtype: (height, width), or (height, width, channels)."""
    encoding = message.encoding
    if encoding not in encodings or encoding not in LAYOUTS:
        raise ImageError('encoding', f'encoding {encoding!r} is not one of {", ".join(encodings)}')
    dtype, channels = LAYOUTS[encoding]
    height, width, step = int(message.height), int(message.width), int(message.step)
    if height <= 0 or width <= 0:
        raise ImageError('malformed', f'image size {width}x{height} is empty')
    row_bytes = width * channels * dtype.itemsize
    if step < row_bytes:
        raise ImageError('malformed', f'step {step} is shorter than a row of {width} {encoding} pixels')
    data = np.frombuffer(bytes(message.data) if not isinstance(message.data, np.ndarray) else message.data, np.uint8)
    if data.size != step * height:
        raise ImageError('malformed', f'{data.size} data bytes for {height} rows of {step} bytes')
    rows = data.reshape(height, step)[:, :row_bytes]
    pixels = np.ascontiguousarray(rows).view(dtype.newbyteorder('>' if message.is_bigendian else '<'))
    shape = (height, width) if channels == 1 else (height, width, channels)
    return pixels.astype(dtype, copy=False).reshape(shape)


def fill_image(message: Image, pixels: np.ndarray, encoding: str) -> Image:
    """Fill an (empty) Image message with pixels in `encoding` ((H, W) or (H, W, channels)); return it."""
    dtype, channels = LAYOUTS[encoding]
    pixels = np.ascontiguousarray(pixels, dtype)
    if pixels.shape[2:] != (() if channels == 1 else (channels,)):
        raise ValueError(f'pixels of shape {pixels.shape} do not fit encoding {encoding}')
    message.height, message.width = pixels.shape[:2]
    message.encoding = encoding
    message.is_bigendian = 0
    message.step = pixels.shape[1] * channels * pixels.itemsize
    message.data = pixels.tobytes()  # bytes, not an array: assigning bytes is ~100x faster in rclpy
    return message


def stamp_ns(header: Header) -> int:
    """Return a header's stamp in nanoseconds since the epoch."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
