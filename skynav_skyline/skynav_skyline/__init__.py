# SPDX-License-Identifier: Apache-2.0
"""Sky/ground segmentation of upward-looking UV/green fish-eye images: the skyline.

Plain numpy and OpenCV (connected components and morphology of the structure steps, the optional
Debevec merge); no ROS imports. Typical use::

    from skynav_skyline import SkylineGeometry, SkylineParams, SkylineSegmenter
    segmenter = SkylineSegmenter(SkylineGeometry.from_camera(camera), SkylineParams(method='sector-otsu'))
    mask = segmenter.segment(uv, green, 'mono8', 'mono8')   # uint8, 255 sky, 0 ground
"""

from .classify import (
    CHANNEL_MODES,
    UV_GREEN_CONTRAST_ANGLE,
    GlobalModel,
    best_threshold,
    classification_rate,
    learn_global,
    project,
)
from .features import (
    ENCODINGS,
    REFERENCE_PERCENTILE,
    Channel,
    Features,
    decode,
    extract_features,
    log_feature,
    reference_level,
)
from .geometry import SectorLayout, SkylineGeometry
from .hdr import merge_brackets
from .segment import (
    METHODS,
    SectorThresholds,
    Segmentation,
    SkylineParams,
    SkylineSegmenter,
    is_bimodal,
    sector_thresholds,
    segment,
)
from .threshold import (
    HistogramSplit,
    between_class_variance,
    histogram,
    minimum_error_criterion,
    minimum_error_split,
    minimum_error_threshold,
    otsu_split,
    otsu_threshold,
)

__all__ = [
    'CHANNEL_MODES',
    'ENCODINGS',
    'METHODS',
    'REFERENCE_PERCENTILE',
    'UV_GREEN_CONTRAST_ANGLE',
    'Channel',
    'Features',
    'GlobalModel',
    'HistogramSplit',
    'SectorLayout',
    'SectorThresholds',
    'Segmentation',
    'SkylineGeometry',
    'SkylineParams',
    'SkylineSegmenter',
    'best_threshold',
    'between_class_variance',
    'classification_rate',
    'decode',
    'extract_features',
    'histogram',
    'is_bimodal',
    'learn_global',
    'log_feature',
    'merge_brackets',
    'minimum_error_criterion',
    'minimum_error_split',
    'minimum_error_threshold',
    'otsu_split',
    'otsu_threshold',
    'project',
    'reference_level',
    'sector_thresholds',
    'segment',
]
