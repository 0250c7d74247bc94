# SPDX-License-Identifier: Apache-2.0
"""The SH node's parameters: names, defaults and meaning (skynav_core.parameters)."""

from __future__ import annotations

from skynav_core.camera_input import CAMERA_PARAMETERS
from skynav_core.parameters import Parameter

from .basis import DEFAULT_DEGREE
from .fisheye import FILLS

PARAMETERS = {
    'max_degree': Parameter(DEFAULT_DEGREE, 'SH degree L of the published coefficients'),
    'fill': Parameter('zero', f'value outside the field of view: {", ".join(FILLS)}'),
    'supersampling': Parameter(2, 'sub-samples per grid cell side (area-averaged sampling)'),
    'field_of_view_deg': Parameter(0.0, 'narrow the field of view to this full angle (deg); 0: whole image circle'),
    **CAMERA_PARAMETERS,
}
