# SPDX-License-Identifier: Apache-2.0
"""Synthetic UV/green fish-eye recordings with ground truth."""
