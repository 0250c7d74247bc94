# SPDX-License-Identifier: Apache-2.0
"""Colour frames to linear RGB: every encoding of the contract, Bayer patterns, JPEG/PNG, and refusals."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sensor_msgs.msg import CompressedImage, Image

from skynav_core.colour import (
    COLOUR_ENCODINGS,
    LINEAR_FULL_SCALE,
    SRGB8_TO_LINEAR16,
    compress,
    compressed_codec,
    decode_compressed,
    decode_image,
    linear_to_srgb,
    linear_to_srgb8,
    mosaic,
    srgb_to_linear,
)
from skynav_core.images import BAYER_PATTERNS, ImageError, fill_image


def smooth_rgb(height: int = 48, width: int = 64, bits: int = 8) -> np.ndarray:
    """Return a smooth RGB test image (each channel its own gradient), so demosaicing is exact away from edges."""
    v, u = np.mgrid[0:height, 0:width]
    top = 255 if bits == 8 else 65535
    channels = [(u / width) * 0.8 + 0.1, (v / height) * 0.6 + 0.2, np.full(u.shape, 0.5)]
    return np.rint(np.stack(channels, -1) * top).astype(np.uint8 if bits == 8 else np.uint16)


def test_srgb_curve_is_the_standard_one_and_the_table_matches_it():
    np.testing.assert_allclose(srgb_to_linear([0.0, 0.04045, 0.5, 1.0]), [0.0, 0.0031308, 0.2140, 1.0], atol=1e-4)
    assert SRGB8_TO_LINEAR16[0] == 0 and SRGB8_TO_LINEAR16[255] == LINEAR_FULL_SCALE
    assert np.all(np.diff(SRGB8_TO_LINEAR16.astype(int)) > 0)  # strictly increasing: no two codes merge
    np.testing.assert_allclose(SRGB8_TO_LINEAR16[128] / LINEAR_FULL_SCALE, srgb_to_linear(128 / 255), atol=1e-5)


@given(st.lists(st.integers(0, 255), min_size=1, max_size=64))
def test_srgb8_round_trips_through_linear(codes):
    codes = np.array(codes, np.uint8)
    assert np.array_equal(linear_to_srgb8(srgb_to_linear(codes / 255.0)), codes)


@given(st.floats(0.0, 1.0))
def test_linear_to_srgb_inverts_srgb_to_linear(value):
    assert linear_to_srgb(srgb_to_linear(value)) == pytest.approx(value, abs=1e-5)


@pytest.mark.parametrize('bits', [8, 16])
@pytest.mark.parametrize('order', ['rgb', 'bgr', 'rgba', 'bgra'])
def test_raw_colour_encodings_give_linear_rgb_in_rgb_order(order, bits):
    rgb = smooth_rgb(bits=bits)
    channels = [rgb[..., 'rgb'.index(c)] for c in order.rstrip('a')]
    if order.endswith('a'):
        channels.append(np.full(rgb.shape[:2], 7, rgb.dtype))  # an alpha that must be dropped
    message = fill_image(Image(), np.stack(channels, -1), f'{order}{bits}')
    linear = decode_image(message)
    assert linear.dtype == np.uint16 and linear.shape == rgb.shape
    expected = SRGB8_TO_LINEAR16[rgb] if bits == 8 else rgb  # 8-bit is sRGB, 16-bit linear
    assert np.array_equal(linear, expected)


@pytest.mark.parametrize('bits', [8, 16])
@pytest.mark.parametrize('pattern', BAYER_PATTERNS)
def test_bayer_patterns_demosaic_to_the_colours_they_name(pattern, bits):
    rgb = smooth_rgb(bits=bits)
    message = fill_image(Image(), mosaic(rgb, pattern), f'bayer_{pattern}{bits}')
    linear = decode_image(message).astype(float)
    expected = (SRGB8_TO_LINEAR16[rgb] if bits == 8 else rgb).astype(float)
    inner = (slice(2, -2), slice(2, -2))  # demosaicing interpolates; the border pixels have half a neighbourhood
    # a swapped pattern would exchange red and blue (0.1-0.9 against 0.5 of full scale): far beyond 2 %
    np.testing.assert_allclose(linear[inner], expected[inner], atol=0.02 * LINEAR_FULL_SCALE)


def test_mosaic_keeps_the_named_colour_at_each_site():
    rgb = np.stack([np.full((4, 4), 1), np.full((4, 4), 2), np.full((4, 4), 3)], -1).astype(np.uint8)
    assert mosaic(rgb, 'rggb')[:2, :2].tolist() == [[1, 2], [2, 3]]
    assert mosaic(rgb, 'gbrg')[:2, :2].tolist() == [[2, 3], [1, 2]]


def compressed(rgb: np.ndarray, codec: str) -> CompressedImage:
    message = CompressedImage()
    message.format, data = compress(rgb, codec)
    message.data = data
    return message


def test_jpeg_decodes_close_to_its_source_and_png_exactly():
    rgb = smooth_rgb()
    jpeg = decode_compressed(compressed(rgb, 'jpeg'))
    assert jpeg.shape == rgb.shape
    assert np.abs(jpeg.astype(float) - SRGB8_TO_LINEAR16[rgb]).mean() < 0.01 * LINEAR_FULL_SCALE
    assert np.array_equal(decode_compressed(compressed(rgb, 'png')), SRGB8_TO_LINEAR16[rgb])
    rgb16 = smooth_rgb(bits=16)
    assert np.array_equal(decode_compressed(compressed(rgb16, 'png')), rgb16)  # 16-bit is linear as it is


@pytest.mark.parametrize(
    'text, codec',
    [('bgr8; jpeg compressed bgr8', 'jpeg'), ('rgb8; png compressed bgr8', 'png'), ('jpeg', 'jpeg'), ('JPG', 'jpeg')],
)
def test_the_codec_is_read_from_image_transports_format(text, codec):
    assert compressed_codec(text) == codec


def test_damaged_and_unknown_compressed_frames_are_refused_with_a_reason():
    rgb = smooth_rgb()
    jpeg, png = compressed(rgb, 'jpeg'), compressed(rgb, 'png')
    damaged = {
        'truncated JPEG': (jpeg.format, bytes(jpeg.data)[: len(jpeg.data) // 2], 'decode'),
        'empty JPEG': (jpeg.format, b'', 'decode'),
        'garbage with an end marker': (jpeg.format, b'\x00' * 100 + b'\xff\xd9', 'decode'),
        'truncated PNG': (png.format, bytes(png.data)[:-40], 'decode'),
        'depth transport': ('16UC1; compressedDepth png', bytes(png.data), 'format'),
        'grey JPEG': ('mono8; jpeg compressed mono8', cv2.imencode('.jpg', rgb[..., 0])[1].tobytes(), 'encoding'),
    }
    for case, (text, data, reason) in damaged.items():
        with pytest.raises(ImageError) as refused:
            decode_compressed(CompressedImage(format=text, data=data))
        assert refused.value.reason == reason, case


def test_raw_frames_with_a_wrong_step_or_encoding_are_refused():
    message = fill_image(Image(), smooth_rgb(), 'rgb8')
    message.step -= 3
    with pytest.raises(ImageError) as refused:
        decode_image(message)
    assert refused.value.reason == 'malformed'
    mono = fill_image(Image(), smooth_rgb()[..., 0], 'mono8')
    with pytest.raises(ImageError) as refused:
        decode_image(mono)
    assert refused.value.reason == 'encoding'
    assert 'mono8' not in COLOUR_ENCODINGS and '32FC1' not in COLOUR_ENCODINGS


def test_big_endian_16_bit_colour_is_read_in_its_byte_order():
    rgb16 = smooth_rgb(bits=16)
    message = fill_image(Image(), rgb16, 'rgb16')
    message.data = rgb16.astype('>u2').tobytes()
    message.is_bigendian = 1
    assert np.array_equal(decode_image(message), rgb16)
