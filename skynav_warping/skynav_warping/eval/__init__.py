# SPDX-License-Identifier: Apache-2.0
"""The homing laboratory, apart from what the node runs: evaluation against ground truth and in closed loop, the
recordings and synthetic views it reads, and the peer methods it is measured against (planar warping on the
panorama). `skynav eval homing` and the benchmarks load it; the warping node never does.
"""
