# SPDX-License-Identifier: Apache-2.0
"""Measure a method against the ground truth of recordings: each package adds its evaluation here."""

HELP = 'measure methods against ground truth'
