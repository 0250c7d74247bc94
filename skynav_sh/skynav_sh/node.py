# SPDX-License-Identifier: Apache-2.0
"""The SH node: the skyline mask in, its real spherical-harmonic coefficients out.

Subscribes /skyline/mask (mono8, 255 sky) and the camera info of the camera the masks come from (/camera/uv/camera_info
or /camera/camera_info, parameter `camera`; with `auto` the one whose size fits the masks); publishes /skyline/sh
(skynav_msgs/ShCoefficients: degree L, (L+1)^2 coefficients of the mask as a function on the
sphere with sky = 1, the fill used outside the field of view, the field of view) with the mask's stamp.
"""

from __future__ import annotations

import math
from functools import partial

from sensor_msgs.msg import CameraInfo, Image

from skynav_core.camera_input import CAMERA_INFO_TOPICS, CameraInput
from skynav_core.images import ImageError, image_to_array, stamp_ns
from skynav_core.names import CAMERA_FRAME, SH_NODE, SKYLINE_MASK, SKYLINE_SH
from skynav_core.node import SENSOR_QOS, SkynavNode
from skynav_core.ros import run_node
from skynav_msgs.msg import ShCoefficients
from skynav_sh.errors import ShError

from .fisheye import FILLS, FisheyeTransform
from .parameters import PARAMETERS

MAX_DEGREE_LIMIT = 128


class ShNode(SkynavNode):
    """Transforms each skyline mask into SH coefficients."""

    PARAMETERS = PARAMETERS
    INPUT_TOPICS = (SKYLINE_MASK, *CAMERA_INFO_TOPICS)

    def __init__(self, **kwargs) -> None:
        super().__init__(SH_NODE, **kwargs)
        self.declare_table(PARAMETERS)
        self.camera_input = CameraInput(self.reject, self.drop)
        self.expire_with_time(self.camera_input.expire)
        self.transform: FisheyeTransform | None = None
        self.input(SKYLINE_MASK, Image, self.on_mask)
        for topic in CAMERA_INFO_TOPICS:
            self.input(topic, CameraInfo, partial(self.on_camera_info, topic), SENSOR_QOS)
        self.output(SKYLINE_SH, ShCoefficients)
        self.start()

    def configure(self, values: dict) -> None:
        """Check the settings (ValueError for unusable ones); the transform is rebuilt for the next mask."""
        if not 0 <= values['max_degree'] <= MAX_DEGREE_LIMIT:
            raise ShError(f'max_degree must be between 0 and {MAX_DEGREE_LIMIT}')
        if values['fill'] not in FILLS:
            raise ShError(f'fill must be one of {", ".join(FILLS)}')
        if values['supersampling'] < 1:
            raise ShError('supersampling must be at least 1')
        self.settings = values
        self.camera_input.configure(
            values['camera'], values['camera_info_url'], math.radians(values['field_of_view_deg'])
        )
        self.transform = None

    def on_camera_info(self, topic: str, info: CameraInfo) -> None:
        """Adopt the camera geometry; transform the masks that waited for it."""
        if self.camera_input.update(info, topic):
            self.transform = None
        if self.camera_input.camera is not None:
            for stamp, mask in self.camera_input.release():
                self.publish_coefficients(stamp, mask)

    def on_mask(self, image: Image) -> None:
        """Transform one mask (or hold it until the camera is known)."""
        stamp = stamp_ns(image.header)
        try:
            mask = image_to_array(image, encodings=('mono8',))
        except ImageError as exc:
            self.reject(exc.reason, f'mask stamped {stamp}: {exc}')
            return
        if self.camera_input.camera is None:
            self.camera_input.hold((stamp, mask), self.elapsed_ns())
            return
        self.publish_coefficients(stamp, mask)

    def publish_coefficients(self, stamp: int, mask) -> None:
        """Publish the coefficients of one mask."""
        if not self.camera_input.matches(mask.shape):
            return
        camera = self.camera_input.camera
        assert camera is not None  # masks wait until a camera is known
        if self.transform is None or self.transform.camera != camera:
            s = self.settings
            self.transform = FisheyeTransform(camera, s['max_degree'], s['fill'], s['supersampling'])
        with self.processing(stamp):
            coefficients = self.transform.coefficients(mask)
            message = ShCoefficients(
                max_degree=self.transform.max_degree,
                coefficients=coefficients.tolist(),
                fill=self.transform.fill,
                field_of_view=float(camera.field_of_view),
            )
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            message.header.frame_id = CAMERA_FRAME
        self.emit(SKYLINE_SH, message)


def main(args=None) -> int:
    """Run the SH node until Ctrl-C."""
    return run_node(ShNode, args)
