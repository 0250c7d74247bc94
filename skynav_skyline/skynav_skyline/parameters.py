# SPDX-License-Identifier: Apache-2.0
"""The skyline node's parameters: names, defaults, meaning, and their translation into SkylineParams.

One definition for the node, `skynav skyline train` (which writes them) and `skynav skyline eval`
(which reads them), so that what is measured is what runs.
"""

from __future__ import annotations

import math
from typing import Any

from skynav_core.camera_input import CAMERA_PARAMETERS
from skynav_core.parameters import Parameter, read_parameter_file
from skynav_core.parameters import defaults as table_defaults

from .segment import DISCRIMINANT, METHODS, SkylineParams

# The segmentation's parameters. The angle and thresholds were learned by `skynav skyline train` on synthetic
# recordings (tools/skyline_training_set.sh: 180 exposures, seeds 10-12 of every world style); learn your own from
# labelled recordings of a real camera.
PARAMETERS = {
    'method': Parameter('sector-min-error', f'one of {", ".join(METHODS)}'),
    'channels': Parameter('uv-green', "'uv' (UV only) or 'uv-green' (UV/green contrast)"),
    'angle_deg': Parameter(-4.45, 'projection angle a of s = cos(a) log UV + sin(a) log G (degrees; 0 for UV only)'),
    'threshold': Parameter(-0.8071, 'global threshold t on s for uv-green (normalised log units); NaN: none'),
    'threshold_uv': Parameter(
        -0.88444, 'global threshold t on log UV for channels uv (normalised log units); NaN: none'
    ),
    'sectors': Parameter(16, 'azimuth sectors of the sector methods'),
    'bins': Parameter(256, 'histogram bins of the local methods'),
    'min_separability': Parameter(0.8, 'least Otsu separability of a bimodal histogram (0..1)'),
    # 0.05 maximised the mean rate on the training recordings (inf, 0.3, 0.2, 0.1, 0.05, 0 tried).
    'max_deviation': Parameter(
        0.05, 'local thresholds stay within this of the global threshold (log units); inf: free'
    ),
    # The structure steps (structure.py) were set on views of real landscapes, the seed 4 skyline sets of garching
    # and hurricane: the dim sky the threshold misses lies within 0.25 of it, enclosed regions that are ground
    # reach 0.7 or more below it; a ground ring with sky beyond surrounds 75-100 % of the azimuths in hurricane's
    # views and at most 13 % in the other seed 4 sets. Checked on views they were not set on (other places, tilts
    # up to 30 degrees, the synthetic training and compass sets: 58-100 % in hurricane, at most 31 % elsewhere);
    # docs/methods.md, Sky/ground segmentation.
    'hole_margin': Parameter(
        0.5, 'ground enclosed by sky that nowhere falls this far below its threshold is sky (log units); 0: off'
    ),
    'ring_share': Parameter(
        0.5,
        'sky beyond a band of ground along the rays is ground when such bands ring at least this share '
        'of the azimuths (0..1); above 1: off',
    ),
    'ring_width_deg': Parameter(2.0, 'least width of such a band of ground along a ray (degrees of off-axis angle)'),
    # 0.2: on the synthetic UV/green sets and drives the two masks disagree on at most 0.146 of a view (median 0.007),
    # on a synthetic colour camera's blue and green on 0.21 (median; docs/cameras.md)
    'max_disagreement': Parameter(
        0.2,
        "where the image's own discriminant and a threshold method disagree on more of the image circle than this "
        "share, the discriminant's mask is taken (uv-green; inf: never)",
    ),
    'black_level_uv': Parameter(0.0, 'UV black level (counts, or radiance for 32FC1)'),
    'black_level_green': Parameter(0.0, 'green black level (counts, or radiance for 32FC1)'),
    'colour_method': Parameter(
        DISCRIMINANT,
        f'method for colour frames: one of {", ".join(METHODS)} (discriminant: all channels; the others blue for UV)',
    ),
}


#: The node's table: the segmentation's parameters and what only the node uses.
NODE_PARAMETERS = {
    **PARAMETERS,
    **CAMERA_PARAMETERS,
    'field_of_view_deg': Parameter(0.0, 'narrow the field of view to this full angle (deg); 0: whole image circle'),
    'pair_tolerance_ms': Parameter(2.0, 'UV and green frames this close in stamp form a pair (ms)'),
    'fit_check_period': Parameter(
        10,
        'run the fit check (max_disagreement) on one UV/green exposure in this many, and on each one while the last '
        'check came near its bound (1: every exposure)',
    ),
}


def defaults() -> dict[str, Any]:
    """Return the segmentation's parameter defaults by name."""
    return table_defaults(PARAMETERS)


def skyline_params(values: dict[str, Any]) -> SkylineParams:
    """Return the segmentation settings of parameter values (defaults for missing ones); ValueError if unusable."""
    merged = {**defaults(), **values}
    channels = str(merged['channels'])
    threshold = float(merged['threshold_uv' if channels == 'uv' else 'threshold'])
    return SkylineParams(
        method=str(merged['method']),
        channels=channels,
        angle=0.0 if channels == 'uv' else math.radians(float(merged['angle_deg'])),
        threshold=None if math.isnan(threshold) else threshold,
        sectors=int(merged['sectors']),
        bins=int(merged['bins']),
        min_separability=float(merged['min_separability']),
        max_deviation=float(merged['max_deviation']),
        hole_margin=float(merged['hole_margin']),
        ring_share=float(merged['ring_share']),
        ring_width_deg=float(merged['ring_width_deg']),
        max_disagreement=float(merged['max_disagreement']),
        black_level=(float(merged['black_level_uv']), float(merged['black_level_green'])),
    )


def colour_params(values: dict[str, Any]) -> SkylineParams:
    """Return the segmentation settings of colour frames from parameter values (defaults for missing ones).

    The method is `colour_method`, on the UV/green channels (blue for UV); decoded colour frames are linear with a
    black level of 0, so the UV and green black levels do not apply. ValueError if unusable.
    """
    merged = {**defaults(), **values}
    return skyline_params(
        {
            **merged,
            'method': merged['colour_method'],
            'channels': 'uv-green',
            'black_level_uv': 0.0,
            'black_level_green': 0.0,
        }
    )


def load_parameter_file(path: str) -> dict[str, Any]:
    """Return the segmentation parameters a ROS 2 parameter file sets for the skyline node (its section or '/**')."""
    return read_parameter_file(path, 'skyline', PARAMETERS)
