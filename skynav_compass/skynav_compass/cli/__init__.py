# SPDX-License-Identifier: Apache-2.0
"""The compass's `skynav` commands (found through the skynav.commands entry points)."""
