# SPDX-License-Identifier: Apache-2.0
"""The compass node's parameters: names, defaults and meaning (skynav_core.parameters)."""

from __future__ import annotations

import math

from skynav_core.parameters import Parameter
from skynav_core.rotations import MAX_TILT
from skynav_sh.basis import DEFAULT_DEGREE

REFERENCES = ('match', 'index', 'live')  # what the compass compares against

PARAMETERS = {
    'map': Parameter('', 'SQLite map file (`skynav map build`) whose snapshots are compared against'),
    'reference': Parameter(
        'match',
        f'what to compare against: {", ".join(REFERENCES)} (match: the snapshot of the latest accepted place match)',
    ),
    'index': Parameter(0, "the snapshot of reference 'index'"),
    'max_degree': Parameter(DEFAULT_DEGREE, 'SH degree of the estimate'),
    'max_tilt_deg': Parameter(
        float(math.degrees(MAX_TILT)),
        'largest tilt between the current view and the snapshot considered (deg, up to 180); '
        'a mower tilts 20-25 deg on rough lawn, two views up to 45',
    ),
}
