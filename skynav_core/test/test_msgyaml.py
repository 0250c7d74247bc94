# SPDX-License-Identifier: Apache-2.0
"""Messages as YAML: every field in definition order, long arrays abbreviated."""

import math

import yaml

from skynav_core.names import CAMERA_FRAME
from skynav_core.recording.msgyaml import to_plain, to_yaml
from skynav_testing import sample_messages


def _first(msgtype):
    return next(m for _, t, _, m in sample_messages(frames=2) if t == msgtype)


def test_fields_in_definition_order_and_nested():
    text = to_yaml(_first('skynav_msgs/msg/CompassEstimate'))
    data = yaml.safe_load(text)
    assert list(data) == ['header', 'snapshot_index', 'rotation', 'residual', 'confidence', 'confident']
    assert data['confidence'] == 0.9 and data['confident'] is True
    assert data['header']['frame_id'] == CAMERA_FRAME
    assert set(data['rotation']) == {'x', 'y', 'z', 'w'}
    assert '__msgtype__' not in text


def test_long_arrays_are_abbreviated_with_their_length():
    image = to_plain(_first('sensor_msgs/msg/Image'), truncate_length=4)
    assert len(image['data']) == 5
    assert image['data'][-1] == f'... {64 * 48 * 2 - 4} more, {64 * 48 * 2} in all'
    full = to_plain(_first('sensor_msgs/msg/Image'), truncate_length=None)
    assert len(full['data']) == 64 * 48 * 2


def test_special_floats_survive():
    match = yaml.safe_load(to_yaml(_first('skynav_msgs/msg/PlaceMatch')))
    assert math.isinf(match['distance']) and match['index'] == -1
    assert match['candidate_indices'] == [0, 1, 2]
