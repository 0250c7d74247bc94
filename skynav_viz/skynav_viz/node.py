# SPDX-License-Identifier: Apache-2.0
"""The viz node: what a person watches live (Foxglove, `skynav view`; RViz) and in `skynav run`'s recording.

Subscribes the camera's image (/camera/uv/image_raw of the UV/green pair, or a colour camera's /camera/image_raw or
/camera/image_raw/compressed) and camera info, /skyline/mask, /localization/match, /homing/home_vector and
/tf_static (the camera's mount, which turns the home vector onto odometry poses);
publishes, per camera frame and stamped with its stamp (docs/interfaces.md, "Visualization"):

- /skynav/viz/markers (visualization_msgs/MarkerArray, frame `odom` or `map`: skynav_viz.scene): the taught route's
  snapshots, the matched snapshot, the home vector's snapshot, the home vector and the route direction;
- /skynav/viz/overlay/compressed (sensor_msgs/CompressedImage, JPEG): the UV input (or the colour camera's frame)
  with the mask's edge, the image circle and the home vector (skynav_viz.overlay);
- /skynav/viz/confidence (std_msgs/Float64): 1 - the home vector's residual, 0..1 (0 without one);
- /skynav/viz/state (std_msgs/Int32): 0 no snapshot matched, 1 a match not accepted, 2 a match accepted.

Live, the overlay and the markers are drawn only while a subscriber takes them (a Foxglove client through `skynav
view`, a recorder): what only a person looks at is not drawn for nobody. The last three of a frame, and the
markers, go out once the frame is complete (its image, its mask and, with a
map, its match and home vector), or when the mask of a newer frame shows that nothing more is coming for it. The
markers, confidence and state need the frame's place match (a map); the overlay needs its image and its mask.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import Point
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_msgs.msg import ColorRGBA, Float64, Int32
from visualization_msgs.msg import Marker, MarkerArray

from skynav_core.camera import EquidistantCamera
from skynav_core.camera_input import CAMERA_INFO_TOPICS
from skynav_core.colour import COLOUR_ENCODINGS, decode_compressed, decode_image
from skynav_core.images import ImageError, image_to_array, stamp_ns
from skynav_core.maps import MapStore, map_for_parameter
from skynav_core.names import (
    CAMERA_FRAME,
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    HOME_VECTOR,
    LOCALIZATION_MATCH,
    SKYLINE_MASK,
    TF_STATIC,
    UV_IMAGE,
    VIZ_CONFIDENCE,
    VIZ_MARKERS,
    VIZ_NODE,
    VIZ_OVERLAY,
    VIZ_STATE,
)
from skynav_core.node import SENSOR_QOS, SkynavNode
from skynav_core.ros import run_node
from skynav_core.rotations import as_matrix
from skynav_msgs.msg import HomeVector, PlaceMatch

from . import overlay, scene
from .parameters import PARAMETERS

IMAGE_TOPICS = (UV_IMAGE, COLOUR_IMAGE, COLOUR_COMPRESSED)  # the image drawn under the overlay, of either camera
KEPT_FRAMES = 8  # frames waiting for their parts; older ones are dropped beyond this
COLOURS = {  # RGBA
    'route': (0.6, 0.6, 0.6, 1.0),
    'snapshots': (0.2, 0.4, 1.0, 1.0),
    'accepted': (0.1, 0.9, 0.2, 1.0),
    'unaccepted': (1.0, 0.6, 0.0, 1.0),
    'target': (0.9, 0.2, 0.9, 1.0),
    'home_vector': (1.0, 0.1, 0.1, 1.0),
    'route_direction': (0.1, 0.9, 0.9, 1.0),
}


@dataclass
class Frame:
    """What arrived of one camera frame so far."""

    uv: Image | None = None
    mask: Image | None = None
    match: PlaceMatch | None = None
    home: HomeVector | None = None


def header_of(message: Any, stamp: int, frame_id: str) -> Any:
    """Stamp a message's header with `stamp` (ns) and `frame_id`; return the message."""
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(int(stamp), 1_000_000_000)
    message.header.frame_id = frame_id
    return message


def point(xyz: np.ndarray) -> Point:
    """Return a geometry_msgs/Point of a position (3,) in m."""
    return Point(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


class VizNode(SkynavNode):
    """Publishes the markers, the overlay image, confidence and state of every camera frame."""

    PARAMETERS = PARAMETERS
    INPUT_TOPICS = (*IMAGE_TOPICS, *CAMERA_INFO_TOPICS, SKYLINE_MASK, LOCALIZATION_MATCH, HOME_VECTOR, TF_STATIC)

    def __init__(self, **kwargs) -> None:
        super().__init__(VIZ_NODE, **kwargs)
        self.declare_table(PARAMETERS)
        self.store: MapStore | None = None
        self.route: scene.Route | None = None
        self.overlays: dict[tuple[int, int], overlay.Overlay] = {}  # per image size (height, width): each camera's
        self.frames: dict[int, Frame] = {}
        self.done = -1  # stamp (ns) of the newest frame published
        for topic, message_type in zip(IMAGE_TOPICS, (Image, Image, CompressedImage)):
            self.input(topic, message_type, lambda m: self.take(m, 'uv'), SENSOR_QOS)
        for topic in CAMERA_INFO_TOPICS:
            self.input(topic, CameraInfo, self.on_camera_info, SENSOR_QOS)
        self.input(SKYLINE_MASK, Image, lambda m: self.take(m, 'mask'))
        self.input(LOCALIZATION_MATCH, PlaceMatch, lambda m: self.take(m, 'match'))
        self.input(HOME_VECTOR, HomeVector, lambda m: self.take(m, 'home'))
        self.listen_for_mount()
        self.output(VIZ_MARKERS, MarkerArray)
        self.output(VIZ_OVERLAY, CompressedImage)
        self.output(VIZ_CONFIDENCE, Float64)
        self.output(VIZ_STATE, Int32)
        self.start()

    def configure(self, values: dict) -> None:
        """Open the map and take the sizes (ValueError if unusable)."""
        if not (math.isfinite(values['arrow_length']) and values['arrow_length'] > 0):
            raise ValueError('arrow_length must be a positive number of metres')
        if not (math.isfinite(values['snapshot_size']) and values['snapshot_size'] > 0):
            raise ValueError('snapshot_size must be a positive number of metres')
        if not 1 <= values['jpeg_quality'] <= 100:
            raise ValueError('jpeg_quality must be within 1..100')
        store = map_for_parameter(self.store, values['map'])
        if store is not self.store:
            if self.store is not None:
                self.store.close()
            self.store, self.route = store, scene.route_of(store) if store is not None else None
            if store is not None and self.route is None:
                self.get_logger().warning(f'map {store.name!r} has no poses (odometry or ground truth): no markers')
        self.values = values

    def on_camera_info(self, info: CameraInfo) -> None:
        """Take the camera model the overlay draws the image circle and the home vector with."""
        try:
            camera = EquidistantCamera.from_camera_info(info)
        except ValueError as exc:
            self.reject('camera_info', f'camera info rejected: {exc}')
            return
        size = (camera.height, camera.width)
        if size not in self.overlays or self.overlays[size].camera != camera:
            self.overlays[size] = overlay.Overlay(camera)

    def reset_time(self) -> None:
        """Forget the frames waiting and the last one published."""
        super().reset_time()
        self.frames.clear()
        self.done = -1

    # --- frames ---------------------------------------------------------------------------------

    def take(self, message: Any, part: str) -> None:
        """Keep one part of a frame; publish the frames it completes or shows complete as far as they get."""
        stamp = stamp_ns(message.header)
        self.stamp_jumped(stamp, self.done)
        if stamp <= self.done:
            self.drop('late', 1, f'a {part} came after its frame was published (the viewer shows it without it)')
            return
        setattr(self.frames.setdefault(stamp, Frame()), part, message)
        if part == 'mask':
            for older in sorted(s for s in self.frames if s < stamp):
                self.publish_frame(older)
        if self.complete(self.frames[stamp]):
            self.publish_frame(stamp)
        while len(self.frames) > KEPT_FRAMES:
            oldest = min(self.frames)
            del self.frames[oldest]
            self.drop('no_mask', 1, 'a frame got no skyline mask while newer frames came: it was not drawn')

    def complete(self, frame: Frame) -> bool:
        """Return whether a frame has every part this graph makes: image and mask, with a map its match and home."""
        parts = (frame.uv, frame.mask) + ((frame.match, frame.home) if self.store is not None else ())
        return all(part is not None for part in parts)

    def publish_frame(self, stamp: int) -> None:
        """Publish what a frame has (and forget it and every older one)."""
        frame = self.frames.pop(stamp)
        for older in [s for s in self.frames if s < stamp]:
            del self.frames[older]
        self.done = max(self.done, stamp)
        with self.processing(stamp):
            home = self.home_of(frame.home)
            confidence = scene.confidence(
                float(frame.home.residual) if frame.home is not None and home is not None else None
            )
            image = None  # the overlay and the markers are drawn only while something takes them (watched)
            if frame.uv is not None and frame.mask is not None and self.watched(VIZ_OVERLAY):
                image = self.overlay_image(stamp, frame, home, confidence)
            markers = None
            if frame.match is not None and self.watched(VIZ_MARKERS):
                markers = self.markers(stamp, frame.match, home)
        if image is not None:
            self.emit(VIZ_OVERLAY, image)
        if frame.match is not None:
            if markers is not None:
                self.emit(VIZ_MARKERS, markers)
            self.emit(VIZ_CONFIDENCE, Float64(data=confidence))
            self.emit(VIZ_STATE, Int32(data=scene.state(int(frame.match.index), bool(frame.match.accepted))))

    def home_of(self, message: HomeVector | None) -> tuple[int, np.ndarray, np.ndarray] | None:
        """Return a home vector's (target index, unit direction in camera_link, rotation (3, 3)); None if unusable."""
        if message is None:
            return None
        d, q = message.direction, message.rotation
        direction = np.array([d.x, d.y, d.z])
        quaternion = np.array([q.x, q.y, q.z, q.w])
        if not (np.all(np.isfinite(direction)) and np.linalg.norm(direction) > 0 and np.all(np.isfinite(quaternion))):
            self.reject('non_finite', 'a home vector without a finite direction or rotation')
            return None
        if np.linalg.norm(quaternion) == 0:
            self.reject('malformed', 'a home vector with a zero rotation quaternion')
            return None
        rotation = as_matrix(quaternion / np.linalg.norm(quaternion))
        return int(message.snapshot_index), direction / np.linalg.norm(direction), rotation

    def overlay_image(self, stamp: int, frame: Frame, home: Any, confidence: float) -> CompressedImage | None:
        """Return the frame's overlay image, or None (counted) if its image or mask cannot be read."""
        try:
            uv = self.pixels_of(frame.uv)
            mask = image_to_array(frame.mask, ('mono8',))
        except ImageError as exc:
            self.reject(exc.reason, f'image not drawn: {exc}')
            return None
        label = ''
        if frame.match is not None:
            accepted = 'accepted' if frame.match.accepted else 'not accepted'
            label = f'match {frame.match.index} ({accepted})  confidence {confidence:.2f}'
        drawn = overlay.draw(uv, mask, self.overlays.get(uv.shape[:2]), home[1] if home is not None else None, label)
        message = header_of(CompressedImage(), stamp, CAMERA_FRAME)
        message.format = 'jpeg'
        message.data = overlay.jpeg(drawn, self.values['jpeg_quality'])
        return message

    @staticmethod
    def pixels_of(image: Image | CompressedImage) -> np.ndarray:
        """Return a camera image's pixels: the UV image as it is, a colour frame as uint16 linear RGB."""
        if isinstance(image, CompressedImage):
            return decode_compressed(image)
        return decode_image(image) if image.encoding in COLOUR_ENCODINGS else image_to_array(image)

    # --- markers --------------------------------------------------------------------------------

    def markers(self, stamp: int, match: PlaceMatch, home: Any) -> MarkerArray | None:
        """Return the frame's markers in the route's frame; None when the map has no poses."""
        route = self.route
        if route is None:
            return None
        shown = scene.scene(
            route, int(match.index), bool(match.accepted), home, self.values['arrow_length'], self.mount
        )
        size = self.values['snapshot_size']
        drawn = route.drawn
        markers = [
            self.marker(stamp, 'route', Marker.LINE_STRIP, drawn, (size / 3, 0.0, 0.0)),
            self.marker(stamp, 'snapshots', Marker.SPHERE_LIST, drawn, (size, size, size)),
        ]
        matched = route.positions[shown.matched][None] if shown.matched is not None else None
        colour = 'accepted' if shown.accepted else 'unaccepted'
        markers.append(self.marker(stamp, 'matched', Marker.SPHERE_LIST, matched, (2 * size,) * 3, colour))
        target = route.positions[shown.target][None] if shown.target is not None else None
        markers.append(self.marker(stamp, 'target', Marker.SPHERE_LIST, target, (1.5 * size,) * 3))
        for name, arrow in (('home_vector', shown.home), ('route_direction', shown.route)):
            ends = np.stack([arrow.start, arrow.end]) if arrow is not None else None
            markers.append(self.marker(stamp, name, Marker.ARROW, ends, (size / 2, size, 1.5 * size)))
        return MarkerArray(markers=markers)

    def marker(
        self,
        stamp: int,
        name: str,
        kind: int,
        points: np.ndarray | None,
        scale: tuple[float, float, float],
        colour: str | None = None,
    ) -> Marker:
        """Return one marker of namespace `name` through `points` (M, 3) in the route's frame; DELETE it if None."""
        assert self.route is not None  # markers() is called only with a route
        marker = header_of(Marker(), stamp, self.route.frame_id)
        marker.ns, marker.id = name, 0
        marker.pose.orientation.w = 1.0
        if points is None or len(points) == 0:
            marker.action = Marker.DELETE
            return marker
        marker.type, marker.action = kind, Marker.ADD
        marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in scale)
        r, g, b, a = COLOURS[colour or name]
        marker.color = ColorRGBA(r=r, g=g, b=b, a=a)
        marker.points = [point(p) for p in points]
        return marker

    def destroy_node(self) -> None:
        """Close the map."""
        if self.store is not None:
            self.store.close()
        super().destroy_node()


def main(args=None) -> int:
    """Run the viz node until Ctrl-C."""
    return run_node(VizNode, args)
