# SPDX-License-Identifier: Apache-2.0
"""The skyline parameters: shipped file and built-in defaults agree, and they make usable settings."""

import math

import pytest

from skynav_core.process.environment import share_directory
from skynav_skyline.parameters import PARAMETERS, defaults, load_parameter_file, skyline_params


def test_shipped_parameter_file_matches_the_built_in_defaults():
    shipped = load_parameter_file(str(share_directory('skynav_bringup') / 'config' / 'skynav.yaml'))
    assert shipped, 'the shipped parameter file has no skyline parameters'
    for name, value in shipped.items():
        default = PARAMETERS[name][0]
        assert value == pytest.approx(default) if isinstance(default, float) else value == default, name


def test_defaults_are_usable_and_channels_pick_their_threshold():
    values = defaults()
    contrast = skyline_params(values)
    uv_only = skyline_params({**values, 'channels': 'uv'})
    assert contrast.threshold == values['threshold'] and uv_only.threshold == values['threshold_uv']
    assert contrast.angle == pytest.approx(math.radians(values['angle_deg'])) and uv_only.angle == 0.0
    with pytest.raises(ValueError):
        skyline_params({**values, 'method': 'magic'})
