# SPDX-License-Identifier: Apache-2.0
"""Which camera a node takes and whose geometry it uses: auto and fixed sources, camera_info_url, sizes."""

import math

import pytest
from sensor_msgs.msg import CameraInfo

from skynav_core.camera import EquidistantCamera
from skynav_core.camera_input import CAMERA_SOURCES, CameraInput, CameraSourceError, recorded_source
from skynav_core.camera_yaml import write_camera_yaml
from skynav_core.errors import SkynavError
from skynav_core.names import (
    COLOUR_CAMERA_INFO,
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    GREEN_IMAGE,
    ODOM,
    UV_CAMERA_INFO,
    UV_IMAGE,
)

PAIR = EquidistantCamera.for_field_of_view(64, 48, math.radians(200))
COLOUR = EquidistantCamera.for_field_of_view(80, 60, math.radians(190), (0.01, -0.002, 0.0, 0.0))


def info(camera):
    return CameraInfo(**camera.camera_info_fields())


class Counts:
    """What a node's reject and drop calls would count."""

    def __init__(self):
        self.rejected, self.dropped = {}, {}

    def reject(self, reason, detail):
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    def drop(self, cause, count, detail):
        if count:
            self.dropped[cause] = self.dropped.get(cause, 0) + count


def camera_input(setting='auto', url=''):
    counts = Counts()
    node = CameraInput(counts.reject, counts.drop)
    node.configure(setting, url, 0.0)
    return node, counts


def test_auto_takes_the_first_source_to_deliver_and_its_geometry():
    node, counts = camera_input()
    node.update(info(PAIR), UV_CAMERA_INFO)
    node.update(info(COLOUR), COLOUR_CAMERA_INFO)
    assert node.admits('colour-compressed')
    assert node.camera == COLOUR  # the colour camera's geometry, not the pair's that came first
    assert node.admits('colour-compressed') and not node.admits('uv-green') and not node.admits('colour')
    assert counts.dropped == {'other_camera': 2}


def test_a_fixed_source_ignores_the_others_geometry():
    node, counts = camera_input('uv-green')
    node.update(info(COLOUR), COLOUR_CAMERA_INFO)
    assert node.camera is None  # the pair's camera info has not come
    node.update(info(PAIR), UV_CAMERA_INFO)
    assert node.camera == PAIR and node.admits('uv-green') and not node.admits('colour')
    assert counts.dropped == {'other_camera': 1}


def test_a_node_without_frames_moves_to_the_geometry_that_fits_its_images():
    node, counts = camera_input()
    node.update(info(PAIR), UV_CAMERA_INFO)
    node.update(info(COLOUR), COLOUR_CAMERA_INFO)
    assert node.camera == PAIR  # the first to come
    assert node.matches((60, 80)) and node.camera == COLOUR
    assert not node.matches((10, 10)) and counts.rejected == {'camera_info_mismatch': 1}


def test_camera_info_url_wins_over_the_topic(tmp_path):
    path = tmp_path / 'fisheye.yaml'
    write_camera_yaml(path, COLOUR, 'fisheye')
    node, _ = camera_input('colour', f'file://{path}')
    assert node.camera == COLOUR  # before any camera info
    node.update(info(PAIR), COLOUR_CAMERA_INFO)  # a driver's wrong geometry
    assert node.camera == COLOUR


def test_unusable_settings_are_refused_in_one_line(tmp_path):
    node, _ = camera_input()
    with pytest.raises(CameraSourceError, match='camera must be one of'):
        node.configure('infrared', '', 0.0)
    with pytest.raises(SkynavError):
        node.configure('auto', f'file://{tmp_path / "missing.yaml"}', 0.0)


def test_a_recordings_source_is_the_camera_whose_frames_it_holds():
    assert recorded_source([UV_IMAGE, GREEN_IMAGE, UV_CAMERA_INFO]) is CAMERA_SOURCES['uv-green']
    assert recorded_source([COLOUR_COMPRESSED, COLOUR_CAMERA_INFO]) is CAMERA_SOURCES['colour-compressed']
    assert recorded_source([COLOUR_IMAGE, COLOUR_CAMERA_INFO, ODOM]) is CAMERA_SOURCES['colour']
    assert recorded_source([UV_IMAGE, UV_CAMERA_INFO]) is None  # the pair without its green
