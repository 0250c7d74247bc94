# SPDX-License-Identifier: Apache-2.0
"""Learn and evaluate sky/ground segmentation on labelled recordings (with /ground_truth/mask)."""

HELP = 'learn and evaluate sky/ground segmentation'
