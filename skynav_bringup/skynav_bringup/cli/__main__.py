# SPDX-License-Identifier: Apache-2.0
"""`python -m skynav_bringup.cli` is `skynav`."""

from . import entry

entry()
