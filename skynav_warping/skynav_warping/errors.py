# SPDX-License-Identifier: Apache-2.0
"""The error of skynav_warping: views, snapshots and settings the home vector cannot be computed from."""

from __future__ import annotations

from skynav_core.errors import SkynavError


class WarpingError(SkynavError, ValueError):
    """A 3D-warping input or setting that cannot be used (a ValueError too, as the built-in it replaces)."""
