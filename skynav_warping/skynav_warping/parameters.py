# SPDX-License-Identifier: Apache-2.0
"""The warping node's parameters: names, defaults and meaning (skynav_core.parameters)."""

from __future__ import annotations

import math

from skynav_core.parameters import Parameter
from skynav_core.rotations import MAX_TILT
from skynav_sh.basis import DEFAULT_DEGREE

TARGETS = ('match', 'index', 'next')  # which snapshot to home to

PARAMETERS = {
    'map': Parameter('', 'SQLite map file (`skynav map build`) whose snapshots are homed to'),
    # route following: the snapshot 6 places beyond the matched one (0.6-1.2 m on the bundled routes; nearer
    # targets give unsure home vectors, farther ones cut corners)
    'target': Parameter('next', f'which snapshot to home to: {", ".join(TARGETS)}'),
    'index': Parameter(0, "the snapshot of target 'index'"),
    'lookahead': Parameter(6, "how many snapshots beyond the matched one target 'next' aims at"),
    'use_compass': Parameter(True, 'start from the compass estimate of the same view (wait for it)'),
    'max_degree': Parameter(DEFAULT_DEGREE, 'SH degree of the search'),
    'max_tilt_deg': Parameter(
        float(math.degrees(MAX_TILT)),
        'largest tilt between the current view and the snapshot the rotation search considers (deg)',
    ),
}
