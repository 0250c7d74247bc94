# SPDX-License-Identifier: Apache-2.0
"""Camera calibration files (camera_calibration_parsers' YAML) and camera_info_url: round trips and refusals."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from skynav_core.camera import EquidistantCamera
from skynav_core.camera_yaml import (
    CameraYamlError,
    camera_from_url,
    camera_yaml_text,
    read_camera_yaml,
    resolve_camera_url,
    write_camera_yaml,
)
from skynav_core.errors import SkynavError

# Every value differs from every other, so a swapped pair (k1/k2, fx/fy, cx/cy) cannot read back equal.
CAMERA = EquidistantCamera(1280, 960, 301.25, 302.5, 641.75, 478.125, (0.031, -0.0125, 0.0021, -0.00034))


def test_a_written_camera_reads_back_exactly(tmp_path):
    path = tmp_path / 'fisheye.yaml'
    write_camera_yaml(path, CAMERA, 'fisheye')
    camera = read_camera_yaml(path)
    assert camera == CAMERA  # dataclass equality: every field, k1..k4 in their order
    assert camera.k[0] == 0.031 and camera.k[1] == -0.0125
    assert camera.fx == 301.25 and camera.fy == 302.5 and (camera.cx, camera.cy) == (641.75, 478.125)


def test_the_file_has_the_fields_and_layout_camera_drivers_read(tmp_path):
    path = tmp_path / 'fisheye.yaml'
    write_camera_yaml(path, CAMERA, 'front_fisheye')
    document = yaml.safe_load(path.read_text())
    assert list(document) == [
        'image_width',
        'image_height',
        'camera_name',
        'camera_matrix',
        'distortion_model',
        'distortion_coefficients',
        'rectification_matrix',
        'projection_matrix',
    ]
    assert document['image_width'] == 1280 and document['image_height'] == 960
    assert document['camera_name'] == 'front_fisheye'
    assert document['distortion_model'] == 'equidistant'
    assert document['camera_matrix'] == {'rows': 3, 'cols': 3, 'data': [301.25, 0, 641.75, 0, 302.5, 478.125, 0, 0, 1]}
    assert document['distortion_coefficients'] == {'rows': 1, 'cols': 4, 'data': [0.031, -0.0125, 0.0021, -0.00034]}
    assert document['rectification_matrix'] == {'rows': 3, 'cols': 3, 'data': [1, 0, 0, 0, 1, 0, 0, 0, 1]}
    assert document['projection_matrix']['data'] == [301.25, 0, 641.75, 0, 0, 302.5, 478.125, 0, 0, 0, 1, 0]


def test_a_file_camera_calibration_parsers_wrote_reads(tmp_path):
    # As camera_calibration_parsers writes it (block style matrices, its own key order), by hand.
    path = tmp_path / 'ost.yaml'
    path.write_text(
        'image_width: 640\nimage_height: 480\ncamera_name: narrow_stereo\ncamera_matrix:\n  rows: 3\n  cols: 3\n'
        '  data: [200.5, 0, 320.25, 0, 201, 240.75, 0, 0, 1]\ndistortion_model: equidistant\n'
        'distortion_coefficients:\n  rows: 1\n  cols: 4\n  data: [0.1, 0.02, -0.003, 0.0004]\n'
        'rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n'
        'projection_matrix:\n  rows: 3\n  cols: 4\n  data: [200.5, 0, 320.25, 0, 0, 201, 240.75, 0, 0, 0, 1, 0]\n'
    )
    assert read_camera_yaml(path) == EquidistantCamera(
        640, 480, 200.5, 201.0, 320.25, 240.75, (0.1, 0.02, -0.003, 0.0004)
    )


def test_writing_is_atomic_and_replaces_an_old_file(tmp_path):
    path = tmp_path / 'fisheye.yaml'
    path.write_text('old')
    write_camera_yaml(path, CAMERA, 'fisheye')
    assert read_camera_yaml(path) == CAMERA
    assert sorted(p.name for p in tmp_path.iterdir()) == ['fisheye.yaml']  # no temporary file left behind


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / 'fisheye.yaml'
    write_camera_yaml(path, CAMERA, 'fisheye')

    def refuse(*args):
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(os, 'replace', refuse)
    other = EquidistantCamera(640, 480, 100.0, 100.0, 320.0, 240.0)
    with pytest.raises(CameraYamlError, match='No space left'):
        write_camera_yaml(path, other, 'fisheye')
    monkeypatch.undo()
    assert read_camera_yaml(path) == CAMERA
    assert sorted(p.name for p in tmp_path.iterdir()) == ['fisheye.yaml']


def _edited(tmp_path: Path, change) -> Path:
    """Return a calibration file of CAMERA with `change` applied to its parsed document."""
    document = yaml.safe_load(camera_yaml_text(CAMERA, 'fisheye'))
    change(document)
    path = tmp_path / 'edited.yaml'
    path.write_text(yaml.safe_dump(document))
    return path


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda d: d.update(distortion_model='plumb_bob'), "distortion_model is 'plumb_bob'"),
        (lambda d: d.pop('distortion_model'), 'distortion_model is None'),
        (lambda d: d['distortion_coefficients'].update(cols=5, data=[0.1] * 5), 'is 1x5, expected 1x4'),
        (lambda d: d['distortion_coefficients'].update(data=[0.1] * 3), 'has 3 values, expected 4'),
        (lambda d: d['camera_matrix'].update(rows=2), 'is 2x3, expected 3x3'),
        (lambda d: d['camera_matrix']['data'].__setitem__(0, float('nan')), 'non-finite'),
        (lambda d: d['distortion_coefficients']['data'].__setitem__(2, float('inf')), 'non-finite'),
        (lambda d: d['camera_matrix']['data'].__setitem__(1, 0.5), 'skew'),
        (lambda d: d['camera_matrix']['data'].__setitem__(0, -300.0), 'must be > 0'),
        (lambda d: d['camera_matrix']['data'].__setitem__(4, 'wide'), 'not a number'),
        (lambda d: d.update(image_width=0), 'image_width is 0'),
        (lambda d: d.pop('image_height'), 'image_height is None'),
        (lambda d: d.pop('camera_matrix'), 'camera_matrix is not a matrix'),
        (lambda d: d['projection_matrix'].update(cols=3, data=[0.0] * 9), 'projection_matrix is 3x3, expected 3x4'),
    ],
)
def test_an_unusable_file_is_refused_in_one_line_naming_the_problem(tmp_path, change, message):
    path = _edited(tmp_path, change)
    with pytest.raises(CameraYamlError, match=message) as refused:
        read_camera_yaml(path)
    assert isinstance(refused.value, SkynavError)  # the `skynav` command and the nodes print it as one line
    assert '\n' not in str(refused.value) and str(path) in str(refused.value)


def test_a_missing_file_and_bad_yaml_are_refused_in_one_line(tmp_path):
    with pytest.raises(CameraYamlError, match='no such camera calibration file'):
        read_camera_yaml(tmp_path / 'missing.yaml')
    broken = tmp_path / 'broken.yaml'
    broken.write_text('image_width: 640\ncamera_matrix: {rows: 3, cols: [\n')
    with pytest.raises(CameraYamlError, match='not valid YAML at line') as refused:
        read_camera_yaml(broken)
    assert '\n' not in str(refused.value)
    listing = tmp_path / 'list.yaml'
    listing.write_text('- 1\n- 2\n')
    with pytest.raises(CameraYamlError, match='not a camera calibration file'):
        read_camera_yaml(listing)


def test_a_file_url_resolves_as_camera_info_manager_does(tmp_path):
    path = tmp_path / 'fisheye.yaml'
    write_camera_yaml(path, CAMERA, 'fisheye')
    assert camera_from_url(f'file://{path}') == CAMERA  # file:///abs/path.yaml
    assert camera_from_url(f'FILE://{path}') == CAMERA  # camera_info_manager compares the scheme case-blind
    assert camera_from_url(str(path)) == CAMERA  # a plain path
    assert resolve_camera_url('file:///a/b c.yaml') == Path('/a/b c.yaml')


def test_a_package_url_resolves_through_the_ament_index(tmp_path):
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory('skynav_core'))
    assert resolve_camera_url('package://skynav_core/calibration/fisheye.yaml') == share / 'calibration/fisheye.yaml'
    with pytest.raises(CameraYamlError, match="package 'no_such_package' is not installed"):
        camera_from_url('package://no_such_package/fisheye.yaml')


@pytest.mark.parametrize('url', ['http://example.org/fisheye.yaml', 'ftp://host/fisheye.yaml', ''])
def test_other_urls_are_refused_in_one_line(url):
    with pytest.raises(CameraYamlError) as refused:
        camera_from_url(url)
    assert '\n' not in str(refused.value)
    assert ('unsupported URL scheme' in str(refused.value)) if url else ('empty' in str(refused.value))


def test_the_camera_of_a_file_projects_as_the_one_written(tmp_path):
    path = tmp_path / 'fisheye.yaml'
    write_camera_yaml(path, CAMERA, 'fisheye')
    theta = np.radians([10.0, 45.0, 80.0, 100.0])
    rays = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=-1)
    np.testing.assert_array_equal(camera_from_url(f'file://{path}').project(rays), CAMERA.project(rays))
