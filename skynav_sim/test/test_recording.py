# SPDX-License-Identifier: Apache-2.0
"""Recordings from scenarios: reproducible to the byte, the contract's topics, masks that match the light."""

import hashlib

import numpy as np
import pytest
from scipy.ndimage import binary_erosion

from skynav_core.camera import EquidistantCamera, angles_from_directions
from skynav_core.names import (
    CAMERA_FRAME,
    GREEN_IMAGE,
    GROUND_TRUTH_MASK,
    GROUND_TRUTH_POSE,
    MAP_FRAME,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.recording.bag import open_bag
from skynav_sim.materials import GREEN_RANGE, UV_RANGE
from skynav_sim.render import Renderer
from skynav_sim.scenarios import ScenarioParameters, build
from skynav_sim.sky import Sky
from skynav_sim.world import generate
from skynav_testing import one_line_error, run_skynav

pytestmark = pytest.mark.heavy(40)

SMALL = ['--size', '96x72', '--length', '1.0', '--speed', '1.0']


def _bag(tmp_path, name, *extra):
    out = tmp_path / name
    result = run_skynav('sim', 'bag', 'teach', '--world', 'mineral', '--seed', '2', *SMALL, *extra, '--out', str(out))
    assert result.returncode == 0, result.stderr
    return out


def test_same_seed_same_bytes(tmp_path):
    # The file's own name is part of its rosbag2 metadata, so both copies get the same name.
    (tmp_path / 'one').mkdir()
    (tmp_path / 'two').mkdir()
    a, b = _bag(tmp_path / 'one', 'run.mcap'), _bag(tmp_path / 'two', 'run.mcap')
    assert hashlib.sha256(a.read_bytes()).digest() == hashlib.sha256(b.read_bytes()).digest()
    (tmp_path / 'three').mkdir()
    other = tmp_path / 'three' / 'run.mcap'
    assert (
        run_skynav('sim', 'bag', 'teach', '--world', 'mineral', '--seed', '3', *SMALL, '--out', str(other)).returncode
        == 0
    )
    assert a.read_bytes() != other.read_bytes()


def test_recording_has_the_contract_topics(tmp_path):
    path = _bag(tmp_path, 'contract.mcap', '--encoding', 'mono8')
    with open_bag(path) as bag:
        assert set(bag.topics) == {
            UV_IMAGE,
            GREEN_IMAGE,
            UV_CAMERA_INFO,
            GROUND_TRUTH_POSE,
            GROUND_TRUTH_MASK,
        }
        per_topic: dict[str, list] = {}
        for message in bag.messages():
            data = bag.deserialize(message)
            per_topic.setdefault(message.topic, []).append(data)
        assert bag.custom_data['skynav_sim'].count('label: route') == 10
    stamps = {t: [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in ms] for t, ms in per_topic.items()}
    reference = stamps[UV_IMAGE]
    assert len(reference) == 10 and np.all(np.diff(reference) == 100_000_000)  # 10 Hz, strictly increasing
    assert all(s == reference for s in stamps.values())
    uv, mask, info = (
        per_topic[UV_IMAGE][0],
        per_topic[GROUND_TRUTH_MASK][0],
        per_topic[UV_CAMERA_INFO][0],
    )
    assert (uv.encoding, uv.width, uv.height, uv.step) == ('mono8', 96, 72, 96)
    assert mask.encoding == 'mono8' and set(np.unique(mask.data)) <= {0, 255}
    assert uv.header.frame_id == CAMERA_FRAME and per_topic[GROUND_TRUTH_POSE][0].header.frame_id == MAP_FRAME
    camera = EquidistantCamera.from_camera_info(info)
    assert camera.field_of_view == pytest.approx(np.radians(200), abs=1e-9)


def test_masks_agree_with_the_rendered_light():
    world = generate('garden', 4)
    camera = EquidistantCamera.for_field_of_view(160, 120, np.radians(200))
    frames = build('skyline', world, ScenarioParameters(count=1), seed=4)
    renderer = Renderer(world, camera)
    for frame in frames[::3]:
        sky = Sky(frame.hours, frame.cloud_cover, cloud_seed=4)
        view = renderer.render(frame.pose, sky)
        directions = frame.pose.rotation.apply(camera.pixel_directions())
        # Two pixels away from the sky's boundary: the renderer averages sub-pixel rays next to it.
        interior = binary_erosion(view.sky, np.ones((5, 5), bool))
        # Sky pixels show exactly the sky's light in their direction.
        for band, image in (('uv', view.uv), ('green', view.green)):
            expected = sky.radiance(band, directions[interior], frame.pose.position)
            assert np.allclose(image[interior], expected, rtol=1e-5), (frame.label, band)
        # Ground pixels show reflected light, which no material makes brighter than its albedo allows.
        ground = binary_erosion(~view.sky & view.inside, np.ones((5, 5), bool))
        for band, image, ranges in (('uv', view.uv, UV_RANGE), ('green', view.green, GREEN_RANGE)):
            bound = ranges[:, 1].max() * (sky.direct[band] + sky.diffuse[band]) / np.pi
            assert image[ground].max() <= bound * 1.0001
        theta, _ = angles_from_directions(camera.pixel_directions())
        assert not view.sky[~view.inside].any() and not view.sky[theta > camera.theta_max].any()


@pytest.mark.parametrize(
    ('args', 'code', 'text'),
    [
        (['--world', 'desert'], 2, 'invalid choice'),
        (['--fov', '250'], 2, 'impossible'),
        (['--fov', '0'], 2, 'impossible'),
        (['--size', 'big'], 2, 'WIDTHxHEIGHT'),
        (['--distortion', '1,2'], 2, 'four numbers'),
        (['--distortion', '0,-0.5,0,0'], 2, 'folds the image'),
        (['--time', 'teatime'], 2, 'unknown time of day'),
        (['--clouds', '3'], 2, 'cover between 0 and 1'),
    ],
)
def test_bad_input_is_refused_before_anything_is_written(tmp_path, args, code, text):
    out = tmp_path / 'never.mcap'
    result = run_skynav('sim', 'bag', 'teach', *SMALL, *args, '--out', str(out))
    assert result.returncode == code and text in result.stderr, result.stderr
    assert 'Traceback' not in result.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('where', ['/proc/skynav_test.mcap', 'missing_folder/x.mcap', 'a_file/x.mcap'])
def test_unwritable_output_path(tmp_path, where):
    # /proc refuses new files even to root; the others name folders that do not exist.
    (tmp_path / 'a_file').write_text('not a folder')
    result = run_skynav('sim', 'bag', 'teach', *SMALL, '--out', where, cwd=tmp_path)
    assert result.returncode == 1 and one_line_error(result.stderr), result.stderr
    assert not any('.mcap' in p.name for p in tmp_path.rglob('*'))


def test_preview_draws_a_sheet_from_a_bag(tmp_path):
    path = _bag(tmp_path, 'for_preview.mcap')
    sheet = tmp_path / 'sheet.png'
    result = run_skynav('sim', 'preview', '--bag', str(path), '--frames', '2', '--out', str(sheet))
    assert result.returncode == 0, result.stderr
    assert sheet.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and sheet.stat().st_size > 20_000
