# SPDX-License-Identifier: Apache-2.0
"""Place recognition's laboratory, apart from what the node runs: evaluation against ground truth (evaluation) and
the peer methods it is measured against (baselines: SeqSLAM on raw UV images, a bag of ORB words), registered with
the Localizer when loaded. `skynav eval localization`, `skynav map build --baselines` and the benchmarks load it; the
localize node never does.
"""
