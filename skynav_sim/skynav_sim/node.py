# SPDX-License-Identifier: Apache-2.0
"""A simulated camera: publishes a synthetic scenario on the contract's camera and ground-truth topics, live.

It renders frame after frame of a scenario (looping) and publishes each as a
camera driver would, stamped with the node's clock: the camera's images (parameter
`camera`: `uv-green`, UV and green images; `colour`, one colour camera's frame on
/camera/image_raw in `encoding`; `colour-compressed`, the same through image_transport's
compressed transport, `codec` jpeg or png at `jpeg_quality`), camera info, and the
ground-truth pose and sky mask. Rendering takes about 0.1 s at 320x240 and 0.5 s at
640x480 per frame on one core, which bounds the rate; `rate` caps it. Everything it
publishes is synthetic.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from skynav_core.images import fill_image
from skynav_core.names import CAMERA_FRAME, GROUND_TRUTH_MASK, GROUND_TRUTH_POSE, MAP_FRAME
from skynav_core.namespaces import relative
from skynav_core.ros import message_class, run_node

from . import recording
from .cli import options
from .colour_sensor import DEFAULT_JPEG_QUALITY

IMAGE = message_class('sensor_msgs/msg/Image')
COMPRESSED_IMAGE = message_class('sensor_msgs/msg/CompressedImage')
CAMERA_INFO = message_class('sensor_msgs/msg/CameraInfo')
POSE = message_class('geometry_msgs/msg/PoseStamped')


class SimCameraNode(Node):
    """Renders a synthetic scenario and publishes it frame by frame."""

    def __init__(self) -> None:
        super().__init__('sim_camera')
        declared = {
            'scenario': 'teach',
            'world': 'garden',
            'seed': 0,
            'time': 'forenoon',
            'clouds': 0.0,
            'size': '320x240',
            'fov': 200.0,
            'distortion': options.DEFAULT_DISTORTION,
            'camera': 'uv-green',
            'encoding': '',  # empty: the camera's default (mono16 of the UV/green pair, rgb8 of a colour camera)
            'codec': 'jpeg',
            'jpeg_quality': DEFAULT_JPEG_QUALITY,
            'length': 20.0,
            'speed': 0.5,
            'rate': 10.0,
        }
        values = {name: self.declare_parameter(name, default).value for name, default in declared.items()}
        args = _namespace(values)
        self.camera = options.camera(args)
        world, frames, _ = options.scenario(args)
        kind = values['camera']
        self.output = recording.CameraOutput(
            kind,
            values['encoding'] or options.DEFAULT_ENCODING.get(kind, ''),
            values['codec'],
            int(values['jpeg_quality']),
        )
        self.frames = frames
        self._source = _looping_captures(world, self.camera, frames, self.output, int(values['seed']))
        qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
        classes = {
            'sensor_msgs/msg/Image': IMAGE,
            'sensor_msgs/msg/CompressedImage': COMPRESSED_IMAGE,
            'sensor_msgs/msg/CameraInfo': CAMERA_INFO,
            'geometry_msgs/msg/PoseStamped': POSE,
        }
        self.outputs = {
            topic: self.create_publisher(classes[msgtype], relative(topic), qos)
            for topic, msgtype in self.output.topics.items()
        }
        self.info = self._camera_info()
        self.timer = self.create_timer(1.0 / float(values['rate']), self.publish_next)
        self.get_logger().info(
            f'publishing synthetic {values["scenario"]} frames of the {values["world"]} world '
            f'(seed {values["seed"]}, {self.camera.width}x{self.camera.height}, {kind} camera, {self.output.encoding})'
        )

    def _camera_info(self) -> Any:
        fields = self.camera.camera_info_fields()
        info = CAMERA_INFO()
        info.width, info.height = fields['width'], fields['height']
        info.distortion_model = fields['distortion_model']
        info.d, info.k, info.r, info.p = fields['d'], fields['k'], fields['r'], fields['p']
        info.header.frame_id = CAMERA_FRAME
        return info

    def _image(self, pixels: np.ndarray, encoding: str, stamp) -> object:
        """Return a sensor_msgs/Image of camera_link pixels ((H, W) or (H, W, channels)) stamped `stamp`."""
        message = fill_image(IMAGE(), pixels, encoding)
        message.header.stamp = stamp
        message.header.frame_id = CAMERA_FRAME
        return message

    def _compressed(self, format_text: str, data: bytes, stamp) -> object:
        """Return a sensor_msgs/CompressedImage of camera_link stamped `stamp`."""
        message = COMPRESSED_IMAGE()
        message.header.stamp = stamp
        message.header.frame_id = CAMERA_FRAME
        message.format = format_text
        message.data = data
        return message

    def publish_next(self) -> None:
        """Render the next frame and publish it on every topic with one stamp."""
        capture = next(self._source)
        stamp = self.get_clock().now().to_msg()
        self.info.header.stamp = stamp
        pose = POSE()
        pose.header.stamp = stamp
        pose.header.frame_id = MAP_FRAME
        (pose.pose.position.x, pose.pose.position.y, pose.pose.position.z) = (
            float(v) for v in capture.frame.pose.position
        )
        (pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z, pose.pose.orientation.w) = (
            float(v) for v in capture.frame.pose.quaternion
        )
        for topic, pixels in capture.exposure.images.items():
            self.outputs[topic].publish(self._image(pixels, self.output.encoding, stamp))
        for topic, (format_text, data) in capture.exposure.compressed.items():
            self.outputs[topic].publish(self._compressed(format_text, data, stamp))
        self.outputs[self.output.info_topic].publish(self.info)
        self.outputs[GROUND_TRUTH_POSE].publish(pose)
        mask = capture.view.sky.astype(np.uint8) * 255
        self.outputs[GROUND_TRUTH_MASK].publish(self._image(mask, 'mono8', stamp))


def _looping_captures(world, camera, frames, output, seed):
    """Yield the captures of `frames` through the camera `output`, again and again."""
    while True:
        yield from recording.captures(world, camera, frames, output, seed)


def _namespace(values: dict) -> argparse.Namespace:
    """Return scenario options as `skynav sim bag` would parse them, from node parameters."""
    defaults = {
        'route_seed': 0,
        'offset': 0.0,
        'shake': 0.0,
        'wobble': 0.0,
        'spacing': 0.5,
        'grid_radius': 3.0,
        'count': 40,
        'max_tilt': 30.0,
        'max_translation': 0.5,
        'bump_tilt': 0.0,
        'detour': 0.0,
    }
    return argparse.Namespace(**{**defaults, **values})


def main(args=None) -> int:
    """Run the simulated camera until Ctrl-C."""
    return run_node(SimCameraNode, args)
