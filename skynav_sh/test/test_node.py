# SPDX-License-Identifier: Apache-2.0
"""The SH node in the in-process graph: a mask in, the library's coefficients out; bad masks rejected."""

import math

import numpy as np
from rclpy.serialization import serialize_message

from skynav_core.camera import EquidistantCamera
from skynav_core.graph import in_process, type_name
from skynav_core.images import fill_image
from skynav_core.names import CAMERA_FRAME, COLOUR_CAMERA_INFO, SKYLINE_MASK, SKYLINE_SH, UV_CAMERA_INFO
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage
from skynav_sh.fisheye import FisheyeTransform

SPEC = NodeSpec('sh', 'skynav_sh', 'skynav_sh.node:ShNode')
CAMERA = EquidistantCamera.for_field_of_view(96, 72, math.radians(200))
T0 = 1_700_000_000 * 10**9


def raw(topic, message, stamp):
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
    return RawMessage(topic, type_name(message), stamp, serialize_message(message))


def camera_info():
    from sensor_msgs.msg import CameraInfo

    info = CameraInfo()
    for key, value in CAMERA.camera_info_fields().items():
        setattr(info, key, value)
    return info


def mask_message(pixels, encoding='mono8'):
    from sensor_msgs.msg import Image

    return fill_image(Image(), pixels, encoding)


def test_mask_in_library_coefficients_out():
    v, u = np.mgrid[0:72, 0:96]
    mask = np.where((u > 30) | (v > 50), 255, 0).astype(np.uint8) * CAMERA.image_circle()
    with in_process([SPEC], ['-p', 'max_degree:=8', '-p', 'fill:=mean']) as graph:
        graph.keep_outputs = True
        graph.feed(raw(SKYLINE_MASK, mask_message(mask), T0))  # waits for the camera
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        outputs = [o.message for o in graph.outputs if o.topic == SKYLINE_SH]
    assert len(outputs) == 1
    message = outputs[0]
    expected = FisheyeTransform(CAMERA, 8, 'mean').coefficients(mask)
    assert message.max_degree == 8 and message.fill == 'mean' and len(message.coefficients) == 81
    assert np.allclose(message.coefficients, expected, rtol=0, atol=1e-12)
    assert message.field_of_view == np.float32(CAMERA.field_of_view)
    assert message.header.stamp.sec * 10**9 + message.header.stamp.nanosec == T0
    assert message.header.frame_id == CAMERA_FRAME


def test_bad_masks_are_rejected_and_counted():
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(SKYLINE_MASK, mask_message(np.zeros((72, 96), np.uint16), 'mono16'), T0))
        graph.feed(raw(SKYLINE_MASK, mask_message(np.zeros((36, 48), np.uint8)), T0 + 1))
        assert not [o for o in graph.outputs if o.topic == SKYLINE_SH]
        assert node.rejected == {'encoding': 1, 'camera_info_mismatch': 1} and node.errors == 0


def test_the_colour_cameras_masks_take_its_own_geometry():
    from sensor_msgs.msg import CameraInfo

    colour = EquidistantCamera.for_field_of_view(80, 60, math.radians(190), (0.02, 0.0, 0.0, 0.0))
    v, u = np.mgrid[0:60, 0:80]
    mask = np.where(u > 30, 255, 0).astype(np.uint8) * colour.image_circle()
    with in_process([SPEC], ['-p', 'max_degree:=6']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))  # the UV/green pair's, another size
        graph.feed(raw(COLOUR_CAMERA_INFO, CameraInfo(**colour.camera_info_fields()), T0))
        graph.feed(raw(SKYLINE_MASK, mask_message(mask), T0))
        (message,) = [o.message for o in graph.outputs if o.topic == SKYLINE_SH]
    expected = FisheyeTransform(colour, 6, 'zero').coefficients(mask)
    assert np.allclose(message.coefficients, expected, rtol=0, atol=1e-12)
    assert message.field_of_view == np.float32(colour.field_of_view) and sum(node.rejected.values()) == 0
