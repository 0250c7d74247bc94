# SPDX-License-Identifier: Apache-2.0
"""The exposure check: a frame so largely saturated, or so largely dark, that its classes are not measured is refused.

The skyline's rules decide the pixels a channel does not measure (classify.py): a saturated UV pixel is sky, a dark
one ground. That is right for the sun and bright sky, for deep shade, but it is a rule, not a measurement: when an
exposure is far too long the ground saturates too and the rule calls it sky (a 20-fold gain on the bundled garden
drive saturates two thirds of the image circle and makes up to 93 % of it sky, 54 % being sky); when it is far too
short the sky goes dark and the rule calls it ground. Such a mask would be published as if it were right.

An automatic exposure sets its level by the bulk of a frame's pixels, so it clips at most a small part of it (the
sun, a bright cloud: at most 0.7 % of the image circle in any frame of the bundled recordings); dark pixels are
more common (deep shade on the ground: up to 61 % of the circle in the bundled park views at dawn). A frame is
*overexposed* when more than MAX_SATURATED_SHARE of its image circle is saturated in any channel the method uses,
*underexposed* when more than MAX_DARK_SHARE is dark in any of them. Either is refused (ExposureError, whose
`reason` names which): the node publishes no mask for it, logs one line and counts it in /diagnostics.

The shares are of the pixels inside the image circle (pixels outside carry nothing), counted per channel flag
(features.Channel: saturated = at the encoding's maximum, dark = at or below black level + dark margin). 32FC1
radiance is never saturated, so an HDR frame is refused only when dark.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from skynav_skyline.errors import SkylineError

from .features import Channel

#: Share (0..1) of the image circle saturated in any channel above which a frame is overexposed: past half the view
#: the saturated-is-sky rule, not the contrast, decides the mask, and no automatic exposure clips that much.
MAX_SATURATED_SHARE = 0.5
#: Share (0..1) of the image circle dark in any channel above which a frame is underexposed: less than a tenth of
#: the view is measured (shaded ground alone darkens up to 61 % of the bundled views).
MAX_DARK_SHARE = 0.9
#: Reasons of a refused frame, as /diagnostics counts them.
OVEREXPOSED, UNDEREXPOSED = 'overexposed', 'underexposed'


class ExposureError(SkylineError):
    """A frame refused for its exposure; `reason` is OVEREXPOSED or UNDEREXPOSED, `share` the share that was over."""

    def __init__(self, reason: str, share: float, message: str) -> None:
        super().__init__(message)
        self.reason, self.share = reason, share


def exposure_shares(channels: Sequence[Channel], circle: np.ndarray) -> tuple[float, float]:
    """Return (saturated, dark): the shares (0..1) of the image circle's pixels saturated, and dark, in any channel."""
    circle = np.asarray(circle, bool)
    inside = int(np.count_nonzero(circle))
    if inside == 0 or not channels:
        return 0.0, 0.0
    saturated = np.zeros(circle.shape, bool)
    dark = np.zeros(circle.shape, bool)
    for channel in channels:
        saturated |= channel.saturated
        dark |= channel.dark
    return (
        int(np.count_nonzero(saturated & circle)) / inside,
        int(np.count_nonzero(dark & circle)) / inside,
    )


def check_exposure(channels: Sequence[Channel], circle: np.ndarray) -> None:
    """Raise ExposureError when the channels (those the method uses) are overexposed or underexposed (see above)."""
    saturated, dark = exposure_shares(channels, circle)
    if saturated > MAX_SATURATED_SHARE:
        raise ExposureError(
            OVEREXPOSED,
            saturated,
            f'overexposed: {100 * saturated:.0f} % of the image circle is saturated (more than '
            f'{100 * MAX_SATURATED_SHARE:.0f} %: the saturated-is-sky rule would decide the mask, not the image)',
        )
    if dark > MAX_DARK_SHARE:
        raise ExposureError(
            UNDEREXPOSED,
            dark,
            f'underexposed: {100 * dark:.0f} % of the image circle is dark (more than {100 * MAX_DARK_SHARE:.0f} %: '
            'the dark-is-ground rule would decide the mask, not the image)',
        )
