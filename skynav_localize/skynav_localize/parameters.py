# SPDX-License-Identifier: Apache-2.0
"""The localize node's parameters: names, defaults and meaning (skynav_core.parameters)."""

from __future__ import annotations

import math

from skynav_core.parameters import Parameter

from .localizer import DESCRIPTOR_DEGREE, OUR_METHODS

PARAMETERS = {
    'map': Parameter('', 'SQLite map file (`skynav map build`); empty: no map'),
    'method': Parameter('amplitude-seq', f'one of {", ".join(OUR_METHODS)}'),
    'sequence_length': Parameter(10, 'views in a sequence (sequence methods)'),
    'min_speed': Parameter(0.5, 'slowest progress along the map, snapshots per view (sequence methods)'),
    'max_speed': Parameter(2.0, 'fastest progress along the map, snapshots per view (sequence methods)'),
    'max_ratio': Parameter(math.nan, "acceptance: best / runner-up distance at most this; NaN: the method's"),
    'max_view_ratio': Parameter(
        math.nan,
        "acceptance of sequences: the newest view's own best / runner-up ratio at "
        "the matched snapshot at most this; NaN: the method's",
    ),
    'max_distance': Parameter(math.inf, 'acceptance: best descriptor distance at most this'),
    'max_self_similarity': Parameter(
        math.nan,
        "acceptance where the route looks alike: a match whose snapshot's "
        "self-similarity (the route's step there over the distance to its "
        'nearest look-alike elsewhere on the route) exceeds this is accepted '
        'only after views that vouched for a steady drive (sequences); NaN: '
        "the method's",
    ),
    'candidates': Parameter(5, 'runners-up in each match'),
    'max_degree': Parameter(DESCRIPTOR_DEGREE, 'SH degree of the place descriptors (views and map are cut to it)'),
}
