# SPDX-License-Identifier: Apache-2.0
"""Rotation-invariant place recognition on a taught route, with SQLite maps.

Typical use (no ROS needed)::

    from skynav_core.maps import MapStore
    from skynav_localize import Localizer
    store = MapStore.open('garden.db')                 # read-only, checked; MapError if not a usable map
    localizer = Localizer(store, 'amplitude-seq')      # or 'amplitude', 'bispectrum(-seq)'; baselines: eval
    match = localizer.query(coefficients=sh)           # Match: index, distance, score, accepted, candidates

The laboratory (evaluation against ground truth, the baselines, whose methods a Localizer knows once
skynav_localize.eval.baselines is loaded) lives in eval/, apart from what the node runs.

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
    'eval.baselines': (
        'BASELINE_METHODS',
        'EVALUATED_METHODS',
        'BowVocabulary',
        'orb_descriptors',
        'raw_uv_descriptor',
        'snapshot_descriptors',
        'train_bow',
    ),
    'mapping': ('SnapshotSelector', 'build_map', 'create_map', 'descriptor_settings'),
    'localizer': ('METHODS', 'OUR_METHODS', 'Localizer', 'Matches', 'Method', 'method', 'register'),
    'eval.evaluation': (
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
    from skynav_localize.descriptors import *  # noqa: F401,F403
    from skynav_localize.eval.baselines import *  # noqa: F401,F403
    from skynav_localize.eval.evaluation import *  # noqa: F401,F403
    from skynav_localize.localizer import *  # noqa: F401,F403
    from skynav_localize.mapping import *  # noqa: F401,F403
    from skynav_localize.matching import *  # noqa: F401,F403
