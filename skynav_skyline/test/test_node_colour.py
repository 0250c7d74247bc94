# SPDX-License-Identifier: Apache-2.0
"""The skyline node on a colour camera: raw, Bayer and compressed frames, the camera source, refusals counted."""

import math

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from skynav_core.camera import EquidistantCamera
from skynav_core.colour import compress, linear_to_srgb8, mosaic
from skynav_core.graph import in_process, type_name
from skynav_core.images import fill_image, image_to_array, stamp_ns
from skynav_core.names import (
    COLOUR_CAMERA_INFO,
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    GREEN_IMAGE,
    SKYLINE_MASK,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage

SPEC = NodeSpec('skyline', 'skynav_skyline', 'skynav_skyline.node:SkylineNode')
CAMERA = EquidistantCamera.for_field_of_view(80, 60, math.radians(200))
T0 = 1_700_000_000 * 10**9
GROUND_COLUMNS = 25  # the scene's ground: a band on the left (image columns 0..24)


def raw(topic, message, stamp):
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
    return RawMessage(topic, type_name(message), stamp, serialize_message(message))


def camera_info(camera=CAMERA):
    info = CameraInfo()
    for key, value in camera.camera_info_fields().items():
        setattr(info, key, value)
    return info


@pytest.fixture(scope='module')
def scene():
    """A colour exposure (linear RGB, 0-1): blue sky with a grey cloud, green-brown ground in a band on the left."""
    rng = np.random.default_rng(2)
    rgb = np.empty((60, 80, 3))
    rgb[...] = (0.25, 0.45, 0.85)  # clear sky: blue
    rgb[10:25, 50:70] = (0.7, 0.72, 0.75)  # a cloud: bright, nearly grey
    rgb[:, :GROUND_COLUMNS] = (0.05, 0.09, 0.03)  # vegetation: dark, green
    rgb *= rng.uniform(0.9, 1.1, rgb.shape[:2])[..., None]  # texture and noise
    return np.clip(rgb, 0, 1)


def frames(rgb):
    """Return the same exposure as every kind of colour frame: (topic, message) per encoding."""
    srgb = linear_to_srgb8(rgb)
    rgb16 = np.rint(rgb * 65535).astype(np.uint16)
    out = {
        'rgb8': (COLOUR_IMAGE, fill_image(Image(), srgb, 'rgb8')),
        'bgr8': (COLOUR_IMAGE, fill_image(Image(), srgb[..., ::-1], 'bgr8')),
        'rgb16': (COLOUR_IMAGE, fill_image(Image(), rgb16, 'rgb16')),
        'bayer_rggb8': (COLOUR_IMAGE, fill_image(Image(), mosaic(srgb, 'rggb'), 'bayer_rggb8')),
        'bayer_gbrg16': (COLOUR_IMAGE, fill_image(Image(), mosaic(rgb16, 'gbrg'), 'bayer_gbrg16')),
    }
    for codec in ('jpeg', 'png'):
        message = CompressedImage()
        message.format, message.data = compress(srgb, codec)
        out[codec] = (COLOUR_COMPRESSED, message)
    return out


def masks_of(graph):
    return [o for o in graph.outputs if o.topic == SKYLINE_MASK]


def expected_mask():
    truth = np.full((60, 80), 255, np.uint8)
    truth[:, :GROUND_COLUMNS] = 0
    return np.where(CAMERA.image_circle(), truth, 0)


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8', 'rgb16', 'bayer_rggb8', 'bayer_gbrg16', 'jpeg', 'png'])
@pytest.mark.parametrize('method', ['discriminant', 'sector-min-error'])
def test_every_colour_encoding_gives_a_mask_of_the_input_size(scene, encoding, method):
    topic, message = frames(scene)[encoding]
    with in_process([SPEC], ['-p', f'colour_method:={method}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(COLOUR_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(topic, message, T0))
        (mask,) = masks_of(graph)
        assert stamp_ns(mask.message.header) == T0
        pixels = image_to_array(mask.message)
        assert pixels.shape == (60, 80)
        inside = CAMERA.image_circle()
        right = np.count_nonzero((pixels == expected_mask()) & inside) / np.count_nonzero(inside)
        assert right > 0.97, f'{encoding}: {right:.3f} of the pixels right'
        assert not pixels[~inside].any()
        assert sum(node.rejected.values()) == 0 and node.errors == 0


def test_frames_that_cannot_be_decoded_are_counted_and_the_node_goes_on(scene):
    good = frames(scene)
    truncated = CompressedImage(format=good['jpeg'][1].format, data=bytes(good['jpeg'][1].data)[:300])
    unknown = CompressedImage(format='16UC1; compressedDepth png', data=bytes(good['png'][1].data))
    wrong_step = fill_image(Image(), linear_to_srgb8(scene), 'rgb8')
    wrong_step.step += 1
    mono = fill_image(Image(), linear_to_srgb8(scene)[..., 0], 'mono8')
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(COLOUR_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(COLOUR_COMPRESSED, truncated, T0))
        graph.feed(raw(COLOUR_COMPRESSED, unknown, T0 + 1))
        graph.feed(raw(COLOUR_IMAGE, wrong_step, T0 + 2))
        graph.feed(raw(COLOUR_IMAGE, mono, T0 + 3))
        assert masks_of(graph) == []
        assert node.rejected == {'decode': 1, 'format': 1, 'malformed': 1, 'encoding': 1}
        graph.feed(raw(*good['jpeg'], T0 + 4))  # and the next good frame is segmented
        assert [stamp_ns(m.message.header) for m in masks_of(graph)] == [T0 + 4]
        assert node.errors == 0


def test_auto_takes_the_first_source_and_drops_the_others(scene):
    srgb = linear_to_srgb8(scene)
    uv = fill_image(Image(), np.rint(scene[..., 2] * 65535).astype(np.uint16), 'mono16')
    green = fill_image(Image(), np.rint(scene[..., 1] * 65535).astype(np.uint16), 'mono16')
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(COLOUR_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(COLOUR_IMAGE, fill_image(Image(), srgb, 'rgb8'), T0))
        graph.feed(raw(UV_IMAGE, uv, T0 + 10**8))
        graph.feed(raw(GREEN_IMAGE, green, T0 + 10**8))
        graph.feed(raw(COLOUR_IMAGE, fill_image(Image(), srgb, 'rgb8'), T0 + 2 * 10**8))
        assert [stamp_ns(m.message.header) for m in masks_of(graph)] == [T0, T0 + 2 * 10**8]
        assert node.dropped == {'other_camera': 2} and sum(node.rejected.values()) == 0


def test_a_fixed_camera_takes_only_its_source(scene):
    srgb = linear_to_srgb8(scene)
    with in_process([SPEC], ['-p', 'camera:=colour-compressed']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(COLOUR_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(COLOUR_IMAGE, fill_image(Image(), srgb, 'rgb8'), T0))
        graph.feed(raw(*frames(scene)['jpeg'], T0 + 10**8))
        assert [stamp_ns(m.message.header) for m in masks_of(graph)] == [T0 + 10**8]
        assert node.dropped == {'other_camera': 1}
        result = node.set_parameters([__import__('rclpy').parameter.Parameter('camera', value='infrared')])[0]
        assert not result.successful and 'camera must be one of' in result.reason


def test_colour_frames_wait_for_their_own_camera_info(scene):
    other = EquidistantCamera.for_field_of_view(64, 48, math.radians(200))
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        graph.feed(raw(UV_CAMERA_INFO, camera_info(other), T0))  # the UV/green pair's, another size
        graph.feed(raw(*frames(scene)['rgb8'], T0))
        assert masks_of(graph) == []  # held: the colour camera's geometry has not come
        graph.feed(raw(COLOUR_CAMERA_INFO, camera_info(), T0))
        assert [stamp_ns(m.message.header) for m in masks_of(graph)] == [T0]


def test_camera_info_url_gives_the_geometry_when_the_driver_sends_none(scene, tmp_path):
    from skynav_core.camera_yaml import write_camera_yaml

    write_camera_yaml(tmp_path / 'fisheye.yaml', CAMERA, 'fisheye')
    with in_process([SPEC], ['-p', f'camera_info_url:=file://{tmp_path / "fisheye.yaml"}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(*frames(scene)['jpeg'], T0))
        (mask,) = masks_of(graph)  # no camera info came: the file's geometry
        assert image_to_array(mask.message).shape == (60, 80)
        result = node.set_parameters(
            [__import__('rclpy').parameter.Parameter('camera_info_url', value=f'file://{tmp_path / "none.yaml"}')]
        )[0]
        assert not result.successful and 'none.yaml' in result.reason  # refused in one line; the node goes on
        graph.feed(raw(*frames(scene)['jpeg'], T0 + 10**8))
        assert len(masks_of(graph)) == 2 and node.errors == 0
