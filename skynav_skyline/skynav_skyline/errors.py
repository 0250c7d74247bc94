# SPDX-License-Identifier: Apache-2.0
"""The error of skynav_skyline: images, thresholds, models and datasets that cannot be segmented or learned from."""

from __future__ import annotations

from skynav_core.errors import SkynavError


class SkylineError(SkynavError, ValueError):
    """A skyline input or setting that cannot be used (a ValueError too, as the built-in it replaces)."""
