# SPDX-License-Identifier: Apache-2.0
"""A colour camera's frames -> linear RGB: raw, Bayer and compressed (JPEG/PNG); 8-bit sRGB decoded to linear.

One input stage for whatever a colour camera delivers (docs/interfaces.md, "Cameras as robots have them"):
`rgb8`/`bgr8`/`rgba8`/`bgra8` and their 16-bit forms, Bayer mosaics (demosaiced with OpenCV), and
image_transport's `compressed` frames (decoded with OpenCV). 8-bit values are sRGB-encoded, as drivers and JPEG
deliver them, and are decoded to linear through a 256-entry table; 16-bit values are linear already. Every frame
comes out as uint16 (height, width, 3) linear RGB, 0 black and LINEAR_FULL_SCALE the encoding's maximum
(saturated), so that the stages after it see what a mono16 channel gives them: the blue plane stands in for UV,
the green plane for green. A frame that cannot be decoded raises ImageError with a short reason for the counts.

Also the inverse steps a simulated camera needs: linear to sRGB, the Bayer mosaic, and compression with the
`format` text image_transport writes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from .images import BAYER_PATTERNS, LAYOUTS, ImageError, image_to_array

if TYPE_CHECKING:
    from sensor_msgs.msg import CompressedImage, Image

#: The encodings of a colour camera on /camera/image_raw (docs/interfaces.md).
COLOUR_ENCODINGS: tuple[str, ...] = tuple(
    name for name, layout in LAYOUTS.items() if name[:4] != 'mono' and name != '32FC1'
)
#: Linear output value of a saturated sample (uint16 counts); 0 is black.
LINEAR_FULL_SCALE = 65535
#: Codecs of image_transport's `compressed` transport that skynav decodes.
CODECS = ('jpeg', 'png')
#: Bytes that end every complete JPEG stream (the EOI marker); a truncated one lacks them.
JPEG_END = b'\xff\xd9'
#: The colour order OpenCV decodes and encodes compressed colour frames in.
_OPENCV_ORDER = 'bgr'

_TO_RGB = {
    'rgb': None,
    'bgr': cv2.COLOR_BGR2RGB,
    'rgba': cv2.COLOR_RGBA2RGB,
    'bgra': cv2.COLOR_BGRA2RGB,
    **{f'bayer_{p}': getattr(cv2, f'COLOR_Bayer{p.upper()}2RGB') for p in BAYER_PATTERNS},
}


def srgb_to_linear(values: np.ndarray | float) -> np.ndarray:
    """Return linear intensities (0-1, float32) of sRGB-encoded values (0-1), IEC 61966-2-1."""
    values = np.asarray(values, np.float32)
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(values: np.ndarray | float) -> np.ndarray:
    """Return sRGB-encoded values (0-1, float32) of linear intensities (clipped to 0-1), IEC 61966-2-1."""
    values = np.clip(np.asarray(values, np.float32), 0.0, 1.0)
    encoded = np.where(values <= 0.0031308, values * 12.92, 1.055 * values ** (1 / 2.4) - 0.055)
    return encoded.astype(np.float32)


#: sRGB code value (0-255) -> linear uint16 (0-LINEAR_FULL_SCALE): the 8-bit decoding table.
SRGB8_TO_LINEAR16 = np.rint(srgb_to_linear(np.arange(256) / 255.0) * LINEAR_FULL_SCALE).astype(np.uint16)


def linear_to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Return uint8 sRGB code values of linear intensities (0-1; 1 and above saturate at 255)."""
    return np.rint(linear_to_srgb(linear) * 255.0).astype(np.uint8)


def _colour_order(encoding: str) -> str:
    """Return the channel order or Bayer pattern of a colour encoding ('rgb', 'bgra', 'bayer_rggb', ...)."""
    return encoding.rstrip('0123456789')


def to_linear_rgb(pixels: np.ndarray, encoding: str) -> np.ndarray:
    """Return uint16 (H, W, 3) linear RGB of a colour encoding's pixels: Bayer demosaiced, 8-bit sRGB decoded."""
    if encoding not in COLOUR_ENCODINGS:
        raise ImageError('encoding', f'encoding {encoding!r} is not a colour encoding ({", ".join(COLOUR_ENCODINGS)})')
    conversion = _TO_RGB[_colour_order(encoding)]
    rgb = pixels if conversion is None else cv2.cvtColor(np.ascontiguousarray(pixels), conversion)
    if rgb.dtype == np.uint8:
        return cv2.LUT(rgb, SRGB8_TO_LINEAR16)
    return np.ascontiguousarray(rgb)


def decode_image(message: Image) -> np.ndarray:
    """Return uint16 (H, W, 3) linear RGB of a colour sensor_msgs/Image (raw or Bayer); ImageError if unreadable."""
    return to_linear_rgb(image_to_array(message, COLOUR_ENCODINGS), message.encoding)


def compressed_codec(format_text: str) -> str:
    """Return the codec ('jpeg' or 'png') a CompressedImage's `format` names; ImageError for any other."""
    # image_transport writes '<encoding>; <codec> compressed <encoding>'; cameras that compress themselves 'jpeg'.
    described = format_text.split(';', 1)[-1].strip().lower()
    codec = described.split()[0] if described else ''
    codec = 'jpeg' if codec == 'jpg' else codec
    if codec not in CODECS:
        raise ImageError('format', f'compressed format {format_text!r} is not one of {", ".join(CODECS)}')
    return codec


def decode_compressed(message: CompressedImage) -> np.ndarray:
    """Return uint16 (H, W, 3) linear RGB of a JPEG or PNG CompressedImage; ImageError if it cannot be decoded."""
    codec = compressed_codec(str(message.format))
    data = message.data if isinstance(message.data, np.ndarray) else bytes(message.data)
    buffer = np.frombuffer(data, np.uint8)
    if codec == 'jpeg' and buffer[-2:].tobytes() != JPEG_END:
        raise ImageError('decode', f'JPEG of {buffer.size} bytes is truncated (no end-of-image marker)')
    pixels = cv2.imdecode(buffer, cv2.IMREAD_UNCHANGED) if buffer.size else None
    if pixels is None:
        raise ImageError('decode', f'{buffer.size} bytes could not be decoded as {codec.upper()}')
    if pixels.ndim != 3 or pixels.shape[2] not in (3, 4):
        raise ImageError('encoding', f'compressed {codec.upper()} holds a grey image; a colour camera was expected')
    bits = 8 * pixels.itemsize
    return to_linear_rgb(pixels, f'{_OPENCV_ORDER}{"a" if pixels.shape[2] == 4 else ""}{bits}')


def mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """Return the (H, W) Bayer mosaic of an (H, W, 3) RGB image with a pattern of BAYER_PATTERNS ('rggb', ...)."""
    if pattern not in BAYER_PATTERNS:
        raise ValueError(f'unknown Bayer pattern {pattern!r}; expected one of {", ".join(BAYER_PATTERNS)}')
    out = np.empty(rgb.shape[:2], rgb.dtype)
    for k, colour in enumerate(pattern):
        row, column = divmod(k, 2)
        out[row::2, column::2] = rgb[row::2, column::2, 'rgb'.index(colour)]
    return out


def compress(rgb: np.ndarray, codec: str = 'jpeg', quality: int = 90) -> tuple[str, bytes]:
    """Return (format, data) of an (H, W, 3) RGB image (uint8 sRGB or uint16 linear) as image_transport compresses."""
    if codec not in CODECS:
        raise ValueError(f'unknown codec {codec!r}; expected one of {", ".join(CODECS)}')
    bits = 8 * rgb.itemsize
    if codec == 'jpeg' and bits != 8:
        raise ValueError('JPEG holds 8-bit images only')
    parameters = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] if codec == 'jpeg' else []
    ok, data = cv2.imencode(f'.{"jpg" if codec == "jpeg" else codec}', cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), parameters)
    if not ok:
        raise ValueError(f'OpenCV could not encode the image as {codec}')
    return f'rgb{bits}; {codec} compressed {_OPENCV_ORDER}{bits}', data.tobytes()
