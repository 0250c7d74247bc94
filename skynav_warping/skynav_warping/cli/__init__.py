# SPDX-License-Identifier: Apache-2.0
"""The `skynav` subcommands of skynav_warping (found through the skynav.commands entry points)."""
