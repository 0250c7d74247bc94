# SPDX-License-Identifier: Apache-2.0
"""Rotation-invariant place recognition on a taught route, with SQLite maps.

Typical use (no ROS needed)::

    from skynav_core.maps import MapStore
    from skynav_localize import Localizer
    store = MapStore.open('garden.db')                 # read-only, checked; MapError if not a usable map
    localizer = Localizer(store, 'amplitude-seq')      # or 'amplitude', 'bispectrum(-seq)', baselines
    match = localizer.query(coefficients=sh)           # Match: index, distance, score, accepted, candidates

Public names are loaded on first use (PEP 562), so `import skynav_localize` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from skynav_core.lazy import lazy_exports

_EXPORTS = {
    'descriptors': (
        'DESCRIPTOR_VERSION',
        'DescriptorIndex',
        'amplitude_descriptor',
        'bispectrum_descriptor',
        'describe',
        'descriptor_distance',
        'distance_matrix',
    ),
    'matching': (
        'Acceptance',
        'Match',
        'SequenceBuffer',
        'SequenceParams',
        'best_candidates',
        'contrast_normalise',
        'sequence_match',
        'sequence_scores',
        'single_frame',
    ),
    'baselines': ('BowVocabulary', 'orb_descriptors', 'raw_uv_descriptor', 'train_bow'),
    'mapping': ('SnapshotSelector', 'build_map', 'create_map', 'descriptor_settings', 'snapshot_descriptors'),
    'localizer': ('BASELINE_METHODS', 'METHODS', 'OUR_METHODS', 'Localizer', 'Matches', 'Method', 'method'),
    'evaluation': (
        'DEFAULT_TOLERANCE',
        'LocalizationResult',
        'PRCurve',
        'compare',
        'correct_matches',
        'evaluate',
        'format_table',
        'has_true_place',
        'plot_matches_along_route',
        'plot_pr_curves',
        'pr_auc',
        'precision_recall',
        'recall_at_1',
        'recall_at_full_precision',
        'threshold_at_full_precision',
    ),
}
__getattr__, __dir__, __all__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # static analysers see the real imports
    from skynav_localize.baselines import *  # noqa: F401,F403
    from skynav_localize.descriptors import *  # noqa: F401,F403
    from skynav_localize.evaluation import *  # noqa: F401,F403
    from skynav_localize.localizer import *  # noqa: F401,F403
    from skynav_localize.mapping import *  # noqa: F401,F403
    from skynav_localize.matching import *  # noqa: F401,F403
