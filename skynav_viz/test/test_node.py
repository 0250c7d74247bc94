# SPDX-License-Identifier: Apache-2.0
"""The viz node in an in-process graph on scripted frames: one set of outputs per frame, in any order of its parts."""

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Float64, Int32

from skynav_core.camera import EquidistantCamera
from skynav_core.graph import in_process
from skynav_core.images import fill_image
from skynav_core.maps import MapStore
from skynav_core.names import (
    CAMERA_FRAME,
    HOME_VECTOR,
    LOCALIZATION_MATCH,
    MAP_FRAME,
    SKYLINE_MASK,
    UV_CAMERA_INFO,
    UV_IMAGE,
    VIZ_CONFIDENCE,
    VIZ_MARKERS,
    VIZ_OVERLAY,
    VIZ_STATE,
)
from skynav_core.nodes import NodeSpec
from skynav_msgs.msg import HomeVector, PlaceMatch
from skynav_viz import node as viz

CAMERA = EquidistantCamera.for_field_of_view(64, 48, np.deg2rad(180.0))
SPEC = NodeSpec('viz', 'skynav_viz', 'skynav_viz.node:VizNode')
SECOND = 1_000_000_000
VIZ_TOPICS = (VIZ_MARKERS, VIZ_OVERLAY, VIZ_CONFIDENCE, VIZ_STATE)


def stamped(message, stamp: int):
    """Stamp a message (ns) in camera_link; return it."""
    return viz.header_of(message, stamp, CAMERA_FRAME)


def image(stamp: int, pixels: np.ndarray) -> Image:
    return stamped(fill_image(Image(), pixels, 'mono8'), stamp)


def match(stamp: int, index: int, accepted: bool = True) -> PlaceMatch:
    return stamped(PlaceMatch(index=index, accepted=accepted, distance=0.1), stamp)


def home(stamp: int, index: int, residual: float) -> HomeVector:
    message = stamped(HomeVector(snapshot_index=index, residual=residual), stamp)
    message.direction.x, message.rotation.w = 1.0, 1.0
    return message


@pytest.fixture
def graph(tmp_path):
    with MapStore.create(tmp_path / 'route.db', 'route', 2) as store:
        for i in range(4):
            store.add_snapshot(np.zeros(9), i, np.array([i, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]))
    with in_process([SPEC], ['-p', f'map:={tmp_path / "route.db"}']) as graph:
        graph.keep_outputs = True
        info = CameraInfo(**CAMERA.camera_info_fields())
        graph.publish(UV_CAMERA_INFO, stamped(info, 0))
        yield graph


def published(graph) -> dict[str, list]:
    """Return the viz outputs so far by topic, and forget them."""
    outputs = {t: [o.message for o in graph.outputs if o.topic == t] for t in VIZ_TOPICS}
    graph.outputs.clear()
    return outputs


def feed(graph, *messages) -> None:
    for topic, message in messages:
        graph.publish(topic, message)


def test_a_frame_is_published_once_it_is_complete_in_any_order(graph):
    sky = np.zeros((48, 64), np.uint8)
    sky[:24] = 255
    uv = np.full((48, 64), 100, np.uint8)
    # skynav run's order: the match and home vector come before the frame's mask (depth first, sh reads it first)
    feed(graph, (UV_IMAGE, image(SECOND, uv)), (LOCALIZATION_MATCH, match(SECOND, 1)))
    feed(graph, (HOME_VECTOR, home(SECOND, 2, 0.25)))
    assert not any(published(graph).values())  # the mask is still to come
    feed(graph, (SKYLINE_MASK, image(SECOND, sky)))
    first = published(graph)
    assert {t: len(v) for t, v in first.items()} == dict.fromkeys(VIZ_TOPICS, 1)
    assert first[VIZ_CONFIDENCE][0] == Float64(data=0.75)
    assert first[VIZ_STATE][0] == Int32(data=2)
    markers = {m.ns: m for m in first[VIZ_MARKERS][0].markers}
    assert markers['matched'].points[0].x == 1.0 and markers['target'].points[0].x == 2.0
    assert markers['snapshots'].header.frame_id == MAP_FRAME and len(markers['snapshots'].points) == 4
    home_arrow = markers['home_vector'].points
    assert (home_arrow[0].x, home_arrow[1].x) == (1.0, 2.0)  # from the match, along +x of snapshot 2 (1 m)
    assert first[VIZ_OVERLAY][0].format == 'jpeg' and first[VIZ_OVERLAY][0].header.stamp.sec == 1

    # a live order: the last part completes the frame
    feed(graph, (SKYLINE_MASK, image(2 * SECOND, sky)), (HOME_VECTOR, home(2 * SECOND, 3, 0.5)))
    feed(graph, (UV_IMAGE, image(2 * SECOND, uv)))
    assert not any(published(graph).values())
    feed(graph, (LOCALIZATION_MATCH, match(2 * SECOND, 2, accepted=False)))
    second = published(graph)
    assert second[VIZ_STATE] == [Int32(data=1)] and second[VIZ_CONFIDENCE] == [Float64(data=0.5)]
    assert len(second[VIZ_OVERLAY]) == 1


def test_a_frame_without_a_home_vector_goes_out_when_a_newer_mask_comes_and_late_parts_are_dropped(graph):
    sky = np.zeros((48, 64), np.uint8)
    sky[:24] = 255
    feed(graph, (UV_IMAGE, image(SECOND, sky)), (LOCALIZATION_MATCH, match(SECOND, -1, accepted=False)))
    feed(graph, (SKYLINE_MASK, image(SECOND, sky)))
    assert not any(published(graph).values())
    feed(graph, (SKYLINE_MASK, image(2 * SECOND, sky)))
    outputs = published(graph)
    assert outputs[VIZ_STATE] == [Int32(data=0)] and outputs[VIZ_CONFIDENCE] == [Float64(data=0.0)]
    deleted = {m.ns for m in outputs[VIZ_MARKERS][0].markers if m.action == m.DELETE}
    assert deleted == {'matched', 'target', 'home_vector', 'route_direction'}
    feed(graph, (HOME_VECTOR, home(SECOND, 2, 0.1)))
    assert not any(published(graph).values())
    assert graph.nodes[0].dropped['late'] == 1


def test_a_colour_cameras_frame_is_drawn_in_colour_with_its_own_camera(graph):
    from sensor_msgs.msg import CompressedImage

    from skynav_core.colour import compress
    from skynav_core.names import COLOUR_CAMERA_INFO, COLOUR_COMPRESSED

    colour_camera = EquidistantCamera.for_field_of_view(80, 60, np.deg2rad(200.0))  # another size than the UV pair
    graph.publish(COLOUR_CAMERA_INFO, stamped(CameraInfo(**colour_camera.camera_info_fields()), 0))
    rgb = np.zeros((60, 80, 3), np.uint8)
    rgb[...] = (60, 120, 230)  # a blue sky
    frame = CompressedImage()
    frame.format, frame.data = compress(rgb, 'jpeg')
    sky = np.full((60, 80), 255, np.uint8)
    feed(graph, (COLOUR_COMPRESSED, stamped(frame, SECOND)), (LOCALIZATION_MATCH, match(SECOND, 1)))
    feed(graph, (HOME_VECTOR, home(SECOND, 2, 0.25)), (SKYLINE_MASK, image(SECOND, sky)))
    (drawn,) = published(graph)[VIZ_OVERLAY]
    import cv2

    bgr = cv2.imdecode(np.frombuffer(bytes(drawn.data), np.uint8), cv2.IMREAD_COLOR)
    assert bgr.shape == (60, 80, 3)
    blue, green, red = (int(c) for c in bgr[30, 20])  # off the circle's edge and the home arrow
    assert blue > green > red  # the camera's colours, not a grey image
    rim = bgr[0:2, 36:44].reshape(-1, 3).astype(int)  # the top of the colour camera's image circle
    assert np.abs(rim - viz.overlay.CIRCLE_COLOUR).sum(axis=1).min() < np.abs(rim - bgr[30, 20]).sum(axis=1).min()
