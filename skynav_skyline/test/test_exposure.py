# SPDX-License-Identifier: Apache-2.0
"""The exposure check: shares of the image circle saturated or dark in any channel, against the named bounds."""

import numpy as np
import pytest

from skynav_skyline.exposure import (
    MAX_DARK_SHARE,
    MAX_SATURATED_SHARE,
    OVEREXPOSED,
    UNDEREXPOSED,
    ExposureError,
    check_exposure,
    exposure_shares,
)
from skynav_skyline.features import decode

SIZE = 1000  # pixels of the image circle (one row)


def channel(saturated=0, dark=0, outside=0):
    """A mono8 channel: `saturated` pixels at 255 and `dark` at 0 among SIZE inside, then `outside` saturated ones."""
    values = np.full((1, SIZE + outside), 120, np.uint8)
    values[0, :saturated] = 255
    values[0, saturated : saturated + dark] = 0
    values[0, SIZE:] = 255
    return decode(values, 'mono8')


def circle(outside=0):
    inside = np.zeros((1, SIZE + outside), bool)
    inside[0, :SIZE] = True
    return inside


def test_a_frame_over_the_saturated_share_in_either_channel_is_overexposed():
    at_bound = int(MAX_SATURATED_SHARE * SIZE)
    check_exposure([channel(at_bound), channel()], circle())  # at the bound: segmented
    for channels in ([channel(at_bound + 1), channel()], [channel(), channel(at_bound + 1)]):
        with pytest.raises(ExposureError) as refused:
            check_exposure(channels, circle())
        assert refused.value.reason == OVEREXPOSED and refused.value.share == pytest.approx((at_bound + 1) / SIZE)
    # saturated in one channel here and in the other there: together over the bound
    half = at_bound // 2 + 1
    uv, green = channel(half), channel(0, 0)
    green.saturated[0, half : 2 * half] = True
    assert exposure_shares([uv, green], circle())[0] == pytest.approx(2 * half / SIZE)
    with pytest.raises(ExposureError):
        check_exposure([uv, green], circle())


def test_a_frame_over_the_dark_share_is_underexposed():
    at_bound = int(MAX_DARK_SHARE * SIZE)
    check_exposure([channel(dark=at_bound)], circle())
    with pytest.raises(ExposureError) as refused:
        check_exposure([channel(dark=at_bound + 1)], circle())
    assert refused.value.reason == UNDEREXPOSED


def test_pixels_outside_the_image_circle_do_not_count():
    outside = 3 * SIZE  # all saturated, three times as many as inside
    assert exposure_shares([channel(10, 20, outside)], circle(outside)) == pytest.approx((0.01, 0.02))
    check_exposure([channel(outside=outside)], circle(outside))
