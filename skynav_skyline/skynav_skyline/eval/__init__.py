# SPDX-License-Identifier: Apache-2.0
"""The skyline's laboratory, apart from what the node runs: the labelled recordings (dataset: frames with their
ground-truth masks) that `skynav skyline eval` and `skynav skyline train` read; the skyline node never does.
"""
