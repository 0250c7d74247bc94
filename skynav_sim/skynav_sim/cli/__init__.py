# SPDX-License-Identifier: Apache-2.0
"""Synthetic UV/green fish-eye recordings with ground truth (pose, sky mask), rendered from seeded worlds.

Everything these commands make is synthetic: rendered from procedural worlds,
not photographed. Use it to measure methods against ground truth.
"""

HELP = 'synthetic UV/green fish-eye recordings with ground truth'
