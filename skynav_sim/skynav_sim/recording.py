# SPDX-License-Identifier: Apache-2.0
"""Render a scenario and write it as a rosbag2 MCAP recording with the contract's topics and ground truth.

Per frame, all with the same header.stamp (FRAME_RATE apart, starting at the
first frame's time of day on SIMULATED_DATE): the camera's images (UV and green,
or one colour camera's raw or compressed frame: CameraOutput), its camera info,
the ground-truth pose of camera_link in map and the ground-truth sky mask. The
recording's metadata (custom_data 'skynav_sim') says how it was made, with which
camera, and what each frame is; it is marked synthetic there and in its name.
"""

from __future__ import annotations

import datetime
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from skynav_core import names
from skynav_core.camera import EquidistantCamera
from skynav_core.colour import CODECS, COLOUR_ENCODINGS
from skynav_core.names import CAMERA_FRAME, GROUND_TRUTH_MASK, GROUND_TRUTH_POSE, MAP_FRAME
from skynav_core.recording.bag import BagWriter
from skynav_core.recording.typestore import typestore

from .colour_sensor import DEFAULT_JPEG_QUALITY, ColourSensor, bits, compressed, encode
from .errors import SimError
from .render import Renderer, View
from .scenarios import FRAME_RATE, Frame
from .sensor import ENCODINGS, Sensor
from .sky import RGB, UV_GREEN, Sky
from .world import World

SIMULATED_DATE = datetime.datetime(2026, 6, 21, tzinfo=datetime.UTC)  # the sun model's day (172)
GROUND_TRUTH_TOPICS = {
    GROUND_TRUTH_POSE: 'geometry_msgs/msg/PoseStamped',
    GROUND_TRUTH_MASK: 'sensor_msgs/msg/Image',
}
#: The topics of a recording of the UV/green pair.
TOPICS = {
    names.UV_IMAGE: 'sensor_msgs/msg/Image',
    names.GREEN_IMAGE: 'sensor_msgs/msg/Image',
    names.UV_CAMERA_INFO: 'sensor_msgs/msg/CameraInfo',
    **GROUND_TRUTH_TOPICS,
}
#: What the simulated camera can be (docs/interfaces.md, "Cameras as robots have them").
CAMERAS = ('uv-green', 'colour', 'colour-compressed')
#: The encodings of a colour-compressed camera: what it compresses (JPEG: 8-bit sRGB; PNG: that or 16-bit linear).
COMPRESSED_ENCODINGS = ('rgb8', 'rgb16')


@dataclass(frozen=True)
class CameraOutput:
    """What the simulated camera delivers: the UV/green pair, or one colour camera, raw or compressed."""

    kind: str = 'uv-green'  # one of CAMERAS
    encoding: str = 'mono8'  # uv-green: sensor.ENCODINGS; colour: COLOUR_ENCODINGS; compressed: COMPRESSED_ENCODINGS
    codec: str = 'jpeg'  # colour-compressed: one of skynav_core.colour.CODECS
    quality: int = DEFAULT_JPEG_QUALITY  # colour-compressed JPEG: libjpeg quality 1-100

    def __post_init__(self) -> None:
        """Refuse a camera that cannot be (SimError, a ValueError)."""
        if self.kind not in CAMERAS:
            raise SimError(f'unknown camera {self.kind!r} (one of {", ".join(CAMERAS)})')
        allowed = {'uv-green': ENCODINGS, 'colour': COLOUR_ENCODINGS, 'colour-compressed': COMPRESSED_ENCODINGS}
        if self.encoding not in allowed[self.kind]:
            raise SimError(
                f"encoding {self.encoding!r} is not one of the {self.kind} camera's: {', '.join(allowed[self.kind])}"
            )
        if self.kind == 'colour-compressed':
            if self.codec not in CODECS:
                raise SimError(f'unknown codec {self.codec!r} (one of {", ".join(CODECS)})')
            if self.codec == 'jpeg' and bits(self.encoding) != 8:
                raise SimError('JPEG holds 8-bit samples only: a compressed rgb16 camera needs the PNG codec')
            if not 1 <= self.quality <= 100:
                raise SimError(f'JPEG quality {self.quality} is not within 1-100')

    @property
    def bands(self) -> tuple[str, ...]:
        """Return the bands of skynav_sim.sky this camera sees."""
        return UV_GREEN if self.kind == 'uv-green' else RGB

    @property
    def image_topics(self) -> dict[str, str]:
        """Return the camera's image and camera-info topics with their message types."""
        if self.kind == 'uv-green':
            return {k: v for k, v in TOPICS.items() if k not in GROUND_TRUTH_TOPICS}
        image = (
            (names.COLOUR_IMAGE, 'sensor_msgs/msg/Image')
            if self.kind == 'colour'
            else (names.COLOUR_COMPRESSED, 'sensor_msgs/msg/CompressedImage')
        )
        return dict([image, (names.COLOUR_CAMERA_INFO, 'sensor_msgs/msg/CameraInfo')])

    @property
    def topics(self) -> dict[str, str]:
        """Return every topic of a recording through this camera, with its message type."""
        return {**self.image_topics, **GROUND_TRUTH_TOPICS}

    @property
    def info_topic(self) -> str:
        """Return the camera-info topic."""
        return names.UV_CAMERA_INFO if self.kind == 'uv-green' else names.COLOUR_CAMERA_INFO

    def description(self) -> dict:
        """Return what a recording's metadata says about the camera (synthetic, which kind, which encoding)."""
        described: dict = {'synthetic': True, 'kind': self.kind, 'encoding': self.encoding}
        if self.kind != 'uv-green':
            described['white_balance'] = 'daylight (grey under the synthetic clear noon sky)'
            described['srgb'] = '8-bit samples sRGB-encoded, 16-bit linear'
        if self.kind == 'colour-compressed':
            described['codec'] = self.codec
            if self.codec == 'jpeg':
                described['jpeg_quality'] = self.quality
        return described


@dataclass
class Exposure:
    """What one exposure of the simulated camera delivers: images per topic, and the colour camera's signal."""

    images: dict[str, np.ndarray]  # raw image topic -> pixels in the output's encoding
    compressed: dict[str, tuple[str, bytes]]  # compressed image topic -> (format, data)
    signal: np.ndarray | None = None  # colour: the white-balanced linear RGB signal (H, W, 3), 0..1 of full scale


def expose(
    view: View,
    output: CameraOutput,
    rng: np.random.Generator,
    sensor: Sensor | None = None,
    colour_sensor: ColourSensor | None = None,
) -> Exposure:
    """Return what the camera `output` describes delivers of a rendered view (its noise drawn from `rng`)."""
    if output.kind == 'uv-green':
        sensor = sensor or Sensor()
        uv = sensor.capture(view.uv, view.inside, output.encoding, rng)
        green = sensor.capture(view.green, view.inside, output.encoding, rng)
        return Exposure({names.UV_IMAGE: uv, names.GREEN_IMAGE: green}, {})
    signal = (colour_sensor or ColourSensor()).capture(view.rgb(), view.inside, rng)
    if output.kind == 'colour':
        return Exposure({names.COLOUR_IMAGE: encode(signal, output.encoding)}, {}, signal)
    packed = compressed(signal, output.codec, output.quality, bits(output.encoding))
    return Exposure({}, {names.COLOUR_COMPRESSED: packed}, signal)


@dataclass
class Capture:
    """One rendered and captured frame."""

    stamp: int  # ns since the epoch
    frame: Frame
    view: View
    exposure: Exposure

    @property
    def uv(self) -> np.ndarray:
        """Return the UV image of a UV/green camera in its encoding."""
        return self.exposure.images[names.UV_IMAGE]

    @property
    def green(self) -> np.ndarray:
        """Return the green image of a UV/green camera in its encoding."""
        return self.exposure.images[names.GREEN_IMAGE]


def start_stamp(hours: float) -> int:
    """Return the stamp (ns) of a recording's first frame taken at `hours` local solar time."""
    return int(round((SIMULATED_DATE + datetime.timedelta(hours=hours)).timestamp() * 1e9))


def stamps(frames: list[Frame]) -> list[int]:
    """Return the header stamps (ns) of frames: FRAME_RATE apart from the first frame's time of day."""
    first = start_stamp(frames[0].hours)
    period = int(round(1e9 / FRAME_RATE))
    return [first + k * period for k in range(len(frames))]


def camera_output(output: str | CameraOutput) -> CameraOutput:
    """Return the camera of `output`: itself, or the UV/green pair in the encoding it names."""
    return output if isinstance(output, CameraOutput) else CameraOutput('uv-green', output)


def captures(
    world: World,
    camera: EquidistantCamera,
    frames: list[Frame],
    output: str | CameraOutput,
    seed: int,
    sensor: Sensor | None = None,
    colour_sensor: ColourSensor | None = None,
) -> Iterator[Capture]:
    """Render and capture each frame in turn through the camera `output` (a UV/green encoding's name, or any
    CameraOutput); noise is seeded per frame, so output depends only on inputs."""
    output = camera_output(output)
    renderer = Renderer(world, camera, output.bands)
    skies: dict[tuple[float, float], Sky] = {}
    for index, (frame, stamp) in enumerate(zip(frames, stamps(frames))):
        key = (frame.hours, frame.cloud_cover)
        if key not in skies:
            skies[key] = Sky(frame.hours, frame.cloud_cover, cloud_seed=seed)
        view = renderer.render(frame.pose, skies[key])
        rng = np.random.default_rng([seed, index, 31])
        yield Capture(stamp, frame, view, expose(view, output, rng, sensor, colour_sensor))


def write(
    path: str | Path,
    world: World,
    camera: EquidistantCamera,
    frames: list[Frame],
    output: str | CameraOutput,
    seed: int,
    description: dict,
    progress: Callable[[int], None] | None = None,
) -> Path:
    """Render `frames` through the camera `output` (as captures takes it) into a recording at `path` (written
    atomically); return the path. A colour camera's recording says which camera it is in its metadata."""

    output = camera_output(output)
    if output.kind != 'uv-green':
        description = {**description, 'camera': output.description()}
    store = typestore()
    T = store.types
    info_fields = camera.camera_info_fields()
    writer = BagWriter(path)
    try:
        writer.set_custom_data('skynav_sim', yaml.safe_dump(description, sort_keys=False))
        for topic, msgtype in output.topics.items():
            writer.add_topic(topic, msgtype)
        for capture in captures(world, camera, frames, output, seed):
            sec, nanosec = divmod(capture.stamp, 10**9)
            time = T['builtin_interfaces/msg/Time'](sec, nanosec)
            header = T['std_msgs/msg/Header'](time, CAMERA_FRAME)
            messages = {
                **{
                    topic: image_message(T, header, pixels, output.encoding)
                    for topic, pixels in capture.exposure.images.items()
                },
                **{
                    topic: compressed_message(T, header, *packed)
                    for topic, packed in capture.exposure.compressed.items()
                },
                output.info_topic: camera_info_message(T, header, info_fields),
                GROUND_TRUTH_POSE: pose_message(T, T['std_msgs/msg/Header'](time, MAP_FRAME), capture.frame),
                GROUND_TRUTH_MASK: image_message(T, header, capture.view.sky.astype(np.uint8) * 255, 'mono8'),
            }
            for topic, message in messages.items():
                writer.write(topic, capture.stamp, store.serialize_cdr(message, output.topics[topic]))
            if progress is not None:
                progress(1)
    except BaseException:
        writer.abort()  # an interrupted scenario must not pass for a whole one
        raise
    return writer.close()


def image_message(T: dict, header: object, pixels: np.ndarray, encoding: str) -> object:
    """Return a sensor_msgs/Image (rosbags) of an (H, W) or (H, W, channels) image."""
    height, width = pixels.shape[:2]
    step = width * (pixels.size // (height * width)) * pixels.itemsize
    return T['sensor_msgs/msg/Image'](
        header, height, width, encoding, 0, step, np.ascontiguousarray(pixels).view(np.uint8).ravel()
    )


def compressed_message(T: dict, header: object, format_text: str, data: bytes) -> object:
    """Return a sensor_msgs/CompressedImage (rosbags) of compressed bytes in image_transport's `format`."""
    return T['sensor_msgs/msg/CompressedImage'](header, format_text, np.frombuffer(data, np.uint8))


def camera_info_message(T: dict, header: object, fields: dict) -> object:
    """Return a sensor_msgs/CameraInfo (rosbags) of the simulated camera."""
    roi = T['sensor_msgs/msg/RegionOfInterest'](0, 0, 0, 0, False)
    return T['sensor_msgs/msg/CameraInfo'](
        header,
        fields['height'],
        fields['width'],
        fields['distortion_model'],
        np.array(fields['d'], float),
        np.array(fields['k'], float),
        np.array(fields['r'], float),
        np.array(fields['p'], float),
        0,
        0,
        roi,
    )


def pose_message(T: dict, header: object, frame: Frame) -> object:
    """Return the geometry_msgs/PoseStamped (rosbags) of camera_link in map."""
    x, y, z = frame.pose.position
    qx, qy, qz, qw = frame.pose.quaternion
    pose = T['geometry_msgs/msg/Pose'](
        T['geometry_msgs/msg/Point'](x, y, z), T['geometry_msgs/msg/Quaternion'](qx, qy, qz, qw)
    )
    return T['geometry_msgs/msg/PoseStamped'](header, pose)
