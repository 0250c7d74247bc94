# SPDX-License-Identifier: Apache-2.0
"""The route controller's `skynav` commands (found through the skynav.commands entry points)."""
