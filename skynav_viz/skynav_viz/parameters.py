# SPDX-License-Identifier: Apache-2.0
"""The viz node's parameters: names, defaults and meaning (skynav_core.parameters)."""

from __future__ import annotations

from skynav_core.parameters import Parameter

PARAMETERS = {
    'map': Parameter('', "SQLite map file whose snapshots are drawn (the other nodes' map; `skynav launch --map`)"),
    'arrow_length': Parameter(1.0, 'length of the home-vector and route-direction arrows in the 3D view (m)'),
    'snapshot_size': Parameter(0.15, 'diameter of a snapshot sphere in the 3D view (m); the matched one is twice that'),
    'jpeg_quality': Parameter(80, 'JPEG quality of the overlay image (1..100)'),
}
