# SPDX-License-Identifier: Apache-2.0
"""The one base class of skynav's errors: each package derives its own, and every one reads as one line."""

from __future__ import annotations


class SkynavError(Exception):
    """A failure skynav reports as one line (its message) rather than a traceback."""
