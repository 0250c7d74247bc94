# SPDX-License-Identifier: Apache-2.0
"""The compass's laboratory, apart from what the node runs: evaluation against ground truth, the recordings and sets
it reads, and the peer methods it is measured against (the source method's exhaustive search, the yaw-only visual
compasses, feature-based rotation). `skynav eval compass` and the benchmarks load it; the compass node never does.
"""
