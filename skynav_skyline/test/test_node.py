# SPDX-License-Identifier: Apache-2.0
"""The skyline node inside the in-process graph of `skynav run`: pairing, waiting for camera info, ordering."""

import math

import numpy as np
import pytest
from rclpy.serialization import serialize_message

from skynav_core.camera import EquidistantCamera
from skynav_core.graph import in_process
from skynav_core.images import fill_image, image_to_array, stamp_ns
from skynav_core.names import GREEN_IMAGE, SKYLINE_MASK, UV_CAMERA_INFO, UV_IMAGE
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage

SPEC = NodeSpec('skyline', 'skynav_skyline', 'skynav_skyline.node:SkylineNode')
CAMERA = EquidistantCamera.for_field_of_view(64, 48, math.radians(200))
T0 = 1_700_000_000 * 10**9


def raw(topic, message, stamp):
    from skynav_core.graph import type_name

    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
    return RawMessage(topic, type_name(message), stamp, serialize_message(message))


def image(pixels, encoding='mono16'):
    from sensor_msgs.msg import Image

    return fill_image(Image(), pixels, encoding)


def camera_info():
    from sensor_msgs.msg import CameraInfo

    info = CameraInfo()
    for key, value in CAMERA.camera_info_fields().items():
        setattr(info, key, value)
    return info


@pytest.fixture
def scene():
    """A UV/green exposure: sky everywhere but a ground band on the left."""
    rng = np.random.default_rng(1)
    sky = np.full((48, 64), 30000, np.uint16)
    sky[:, :20] = 2000
    uv = (sky + rng.integers(0, 300, sky.shape)).astype(np.uint16)
    green = (sky // 2 + 8000 + rng.integers(0, 300, sky.shape)).astype(np.uint16)
    return uv, green


def masks_of(graph):
    return [o for o in graph.outputs if o.topic == SKYLINE_MASK]


def test_frames_wait_for_camera_info_and_pair_by_stamp(scene):
    uv, green = scene
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        # Two exposures before any camera info, the green of the second first; then the camera info.
        graph.feed(raw(UV_IMAGE, image(uv), T0))
        graph.feed(raw(GREEN_IMAGE, image(green), T0 + 10**8))
        graph.feed(raw(GREEN_IMAGE, image(green), T0))
        graph.feed(raw(UV_IMAGE, image(uv), T0 + 10**8))
        assert masks_of(graph) == []
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0 + 10**8))
        stamps = [stamp_ns(o.message.header) for o in masks_of(graph)]
        assert stamps == [T0, T0 + 10**8]
        mask = image_to_array(masks_of(graph)[0].message)
        assert (mask[:, :18] == 0).all()  # the ground band
        assert (mask[24, 30:40] == 255).all() and not mask[~CAMERA.image_circle()].any()
        assert sum(node.rejected.values()) == 0 and node.errors == 0


def test_out_of_order_and_mismatched_inputs_are_rejected(scene):
    uv, green = scene
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(UV_IMAGE, image(uv), T0))
        graph.feed(raw(GREEN_IMAGE, image(green), T0))
        graph.feed(raw(UV_IMAGE, image(uv), T0 - 10**8))  # older than the last mask
        graph.feed(raw(UV_IMAGE, image(uv[:, :32]), T0 + 10**8))
        graph.feed(raw(GREEN_IMAGE, image(green), T0 + 10**8))  # differs in size from its UV
        graph.feed(raw(UV_IMAGE, image(uv[:24]), T0 + 2 * 10**8))
        graph.feed(raw(GREEN_IMAGE, image(green[:24]), T0 + 2 * 10**8))  # not the camera's size
        assert len(masks_of(graph)) == 1
        assert node.rejected == {'out_of_order': 1, 'size_mismatch': 1, 'camera_info_mismatch': 1}


def exposure(graph, uv, green, stamp):
    """Feed the UV and green frames of one exposure stamped `stamp` (ns); return the masks it gave."""
    before = len(masks_of(graph))
    graph.feed(raw(UV_IMAGE, image(uv), stamp))
    graph.feed(raw(GREEN_IMAGE, image(green), stamp))
    return masks_of(graph)[before:]


def test_one_exposure_stamped_a_day_ahead_poisons_no_later_one(scene):
    uv, green = scene
    day = 86_400 * 10**9
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        stamps = [T0, T0 + 10**8, T0 + 2 * 10**8 + day, T0 + 3 * 10**8, T0 + 4 * 10**8]
        got = [stamp_ns(m.message.header) for t in stamps for m in exposure(graph, uv, green, t)]
        assert got == stamps  # the stray exposure is taken, and so is every one after it
        assert node.time_resets == 2 and sum(node.rejected.values()) == 0
        # a small reordering is still refused
        assert exposure(graph, uv, green, T0 + 3 * 10**8) == []
        assert node.rejected == {'out_of_order': 2}  # its UV and its green frame
        values = {kv.key: kv.value for kv in node.diagnostic_status().values}
        assert values['time_resets'] == '2' and values['rejected_out_of_order'] == '2'


def test_a_recording_played_again_gives_its_masks_again(scene):
    uv, green = scene
    stamps = [T0 + k * 10**8 for k in range(15)]  # 1.4 s: longer than max_stamp_jump_s
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        for _ in range(3):
            graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
            for stamp in stamps:
                exposure(graph, uv, green, stamp)
        assert [stamp_ns(m.message.header) for m in masks_of(graph)] == stamps * 3
        assert node.time_resets == 2 and sum(node.rejected.values()) == 0 and node.errors == 0


def test_a_small_jump_parameter_restarts_time_on_a_reordering(scene):
    uv, green = scene
    with in_process([SPEC], ['-p', 'max_stamp_jump_s:=0.05']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        exposure(graph, uv, green, T0)
        assert len(exposure(graph, uv, green, T0 - 10**8)) == 1
        assert node.time_resets == 1 and sum(node.rejected.values()) == 0
        result = node.set_parameters([__import__('rclpy').parameter.Parameter('max_stamp_jump_s', value=0.0)])[0]
        assert not result.successful and 'max_stamp_jump_s' in result.reason


def test_an_unusable_jump_parameter_falls_back_to_the_default():
    with in_process([SPEC], ['-p', 'max_stamp_jump_s:=-1.0']) as graph:
        node = graph.nodes[0]
        assert node.get_parameter('max_stamp_jump_s').value == 1.0 and node.max_stamp_jump_ns == 10**9
        assert node.rejected == {'parameters': 1}


def test_frames_lost_waiting_are_counted_as_dropped(scene):
    uv, green = scene
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        # a UV frame whose green never comes, then a frame far later: the waiting UV frame is dropped
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        exposure(graph, uv, green, T0)
        graph.feed(raw(UV_IMAGE, image(uv), T0 + 10**8))
        exposure(graph, uv, green, T0 + 100 * 10**8)
        assert node.dropped == {'unpaired': 1} and node.time_resets == 1
    with in_process([SPEC]) as graph:
        node = graph.nodes[0]
        # exposures with no camera info: held, then dropped when they have waited too long
        for k in range(3):
            exposure(graph, uv, green, T0 + k * 10**8)
        graph.feed(raw(UV_IMAGE, image(uv), T0 + 10 * 10**9))
        graph.publish_diagnostics()
        assert node.dropped == {'no_camera_info': 3}
        values = {kv.key: kv.value for kv in node.diagnostic_status().values}
        assert values['dropped'] == '3' and values['dropped_no_camera_info'] == '3'


def test_uv_only_does_not_wait_for_green(scene):
    uv, _ = scene
    with in_process([SPEC], ['-p', 'channels:=uv']) as graph:
        graph.keep_outputs = True
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(UV_IMAGE, image(uv), T0))
        assert len(masks_of(graph)) == 1


def test_unusable_parameters_fall_back_to_the_defaults(scene):
    with in_process([SPEC], ['-p', 'method:=no-such-method']) as graph:
        node = graph.nodes[0]
        assert node.get_parameter('method').value == 'sector-min-error'
        result = node.set_parameters([__import__('rclpy').parameter.Parameter('sectors', value=0)])[0]
        assert not result.successful and 'sector' in result.reason


def test_bounded_sector_thresholds_reach_the_global_method(scene):
    from skynav_skyline.geometry import SkylineGeometry
    from skynav_skyline.parameters import defaults, skyline_params
    from skynav_skyline.segment import SkylineSegmenter

    uv, green = scene
    geometry = SkylineGeometry.from_camera(CAMERA)
    bounded = SkylineSegmenter(geometry, skyline_params({**defaults(), 'max_deviation': 0.0}))
    global_ = SkylineSegmenter(geometry, skyline_params({**defaults(), 'method': 'global'}))
    free = SkylineSegmenter(geometry, skyline_params({**defaults(), 'max_deviation': float('inf')}))
    assert np.array_equal(
        bounded.segment(uv, green, 'mono16', 'mono16'), global_.segment(uv, green, 'mono16', 'mono16')
    )
    thresholds = free.run(uv, green, 'mono16', 'mono16').threshold
    assert np.nanmax(np.abs(thresholds - defaults()['threshold'])) > 0.05  # the free sectors do move


def test_frames_of_one_exposure_pair_within_the_tolerance_of_their_stamps(scene):
    # cameras that stamp the two channels of one exposure apart: 0.5 ms and 1.9 ms pair under the default 2 ms,
    # each mask stamped with the earlier frame's stamp; 2.5 ms apart they are two exposures, and neither has a pair
    uv, green = scene
    ms = 10**6
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, camera_info(), T0))
        graph.feed(raw(UV_IMAGE, image(uv), T0))
        graph.feed(raw(GREEN_IMAGE, image(green), T0 + ms // 2))
        graph.feed(raw(GREEN_IMAGE, image(green), T0 + 10**8))
        graph.feed(raw(UV_IMAGE, image(uv), T0 + 10**8 + 19 * ms // 10))
        assert [stamp_ns(m.message.header) for m in masks_of(graph)] == [T0, T0 + 10**8]
        graph.feed(raw(UV_IMAGE, image(uv), T0 + 2 * 10**8))
        graph.feed(raw(GREEN_IMAGE, image(green), T0 + 2 * 10**8 + 5 * ms // 2))
        assert len(masks_of(graph)) == 2
        assert sum(node.rejected.values()) == 0 and node.errors == 0


def test_an_overexposed_or_underexposed_frame_gets_no_mask_and_is_counted():
    """The bundled garden drive's first frame gives a mask; with 20 times its gain (clipped: ground saturated too, two
    thirds of the image circle) it would be mostly sky by the saturated-is-sky rule, with a 40th of it (95 % dark)
    mostly ground by the dark-is-ground rule: neither is segmented, each is one counted reject."""
    from pathlib import Path

    from sensor_msgs.msg import CameraInfo

    from skynav_skyline.eval.dataset import labelled_frames

    bag = Path(__file__).resolve().parents[2] / 'bags' / 'synthetic_garden_repeat.mcap'
    frame = next(iter(labelled_frames(bag)))
    info = CameraInfo()
    for key, value in frame.camera.camera_info_fields().items():
        setattr(info, key, value)
    full = {'mono8': 255, 'mono16': 65535}

    def exposure(gain, stamp):
        """Feed the frame with its raw values times `gain`, clipped to the encoding's range; return its masks."""
        before = len(masks_of(graph))
        for topic, pixels, encoding in (
            (UV_IMAGE, frame.uv, frame.encoding[0]),
            (GREEN_IMAGE, frame.green, frame.encoding[1]),
        ):
            scaled = np.clip(np.rint(pixels.astype(float) * gain), 0, full[encoding]).astype(pixels.dtype)
            graph.feed(raw(topic, image(scaled, encoding), stamp))
        return masks_of(graph)[before:]

    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        graph.feed(raw(UV_CAMERA_INFO, info, T0))
        assert len(exposure(1.0, T0)) == 1
        assert exposure(20.0, T0 + 10**8) == [] and node.rejected == {'overexposed': 1}
        assert exposure(1 / 40, T0 + 2 * 10**8) == [] and node.rejected == {'overexposed': 1, 'underexposed': 1}
        assert len(exposure(1.0, T0 + 3 * 10**8)) == 1  # the node goes on
        values = {kv.key: kv.value for kv in node.diagnostic_status().values}
        assert values['rejected_overexposed'] == '1' and values['rejected_underexposed'] == '1'
        assert node.errors == 0
