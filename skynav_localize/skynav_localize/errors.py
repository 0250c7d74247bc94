# SPDX-License-Identifier: Apache-2.0
"""The error of skynav_localize: descriptors, sequences, maps and evaluations that cannot be built."""

from __future__ import annotations

from skynav_core.errors import SkynavError


class LocalizeError(SkynavError, ValueError):
    """A place-recognition input or setting that cannot be used (a ValueError too, as the built-in it replaces)."""
