# SPDX-License-Identifier: Apache-2.0
"""The skyline node: UV and green images in, the sky/ground mask out.

Subscribes /camera/uv/image_raw, /camera/green/image_raw and /camera/uv/camera_info; pairs the
two channels of an exposure by stamp; publishes /skyline/mask (mono8, 255 sky, 0 ground and
outside the image circle) with the input's stamp. UV-only methods do not wait for green.
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np
from sensor_msgs.msg import CameraInfo, Image

from skynav_core.camera_input import CAMERA_INFO_TOPIC, CameraInput
from skynav_core.images import ImageError, fill_image, image_to_array, stamp_ns
from skynav_core.node import SENSOR_QOS, SkynavNode
from skynav_core.pairing import StampPairer
from skynav_core.ros import run_node
from skynav_skyline.errors import SkylineError

from .geometry import SkylineGeometry
from .parameters import NODE_PARAMETERS, PARAMETERS, skyline_params
from .segment import SkylineSegmenter

UV_TOPIC = '/camera/uv/image_raw'
GREEN_TOPIC = '/camera/green/image_raw'
MASK_TOPIC = '/skyline/mask'
CAMERA_FRAME = 'camera_link'


class SkylineNode(SkynavNode):
    """Segments each UV(/green) exposure into sky and ground."""

    PARAMETERS = NODE_PARAMETERS
    INPUT_TOPICS = (UV_TOPIC, GREEN_TOPIC, CAMERA_INFO_TOPIC)

    def __init__(self, **kwargs) -> None:
        super().__init__('skyline', **kwargs)
        self.declare_table(NODE_PARAMETERS)
        self.camera_input = CameraInput(self.reject, self.drop)
        self.expire_with_time(self.camera_input.expire)
        self.segmenter: SkylineSegmenter | None = None
        self.input(UV_TOPIC, Image, partial(self.on_image, 'uv'), SENSOR_QOS)
        self.input(GREEN_TOPIC, Image, partial(self.on_image, 'green'), SENSOR_QOS)
        self.input(CAMERA_INFO_TOPIC, CameraInfo, self.on_camera_info, SENSOR_QOS)
        self.output(MASK_TOPIC, Image)
        self.start()

    def configure(self, values: dict) -> None:
        """Build the segmentation settings from parameter values (ValueError for unusable ones)."""
        self.params = skyline_params({name: values[name] for name in PARAMETERS})
        if values['pair_tolerance_ms'] < 0:
            raise SkylineError('pair_tolerance_ms must not be negative')
        self.pairer = StampPairer(('uv', 'green'), int(values['pair_tolerance_ms'] * 1e6), on_drop=self.drop_unpaired)
        self.camera_input.set_fov_limit(math.radians(values['field_of_view_deg']))
        self.segmenter = None  # rebuilt for the next frame

    def drop_unpaired(self, count: int) -> None:
        """Count frames whose other channel never came."""
        self.drop('unpaired', count, 'a UV or green frame whose other channel never came (within pair_tolerance_ms)')

    def reset_time(self) -> None:
        """Forget the last stamp, the frames waiting for their other channel and those waiting for camera info."""
        super().reset_time()
        self.pairer.clear()
        self.camera_input.forget('time_restarted')

    def on_camera_info(self, info: CameraInfo) -> None:
        """Adopt the camera geometry; process what waited for it."""
        if self.camera_input.update(info):
            self.segmenter = None
        if self.camera_input.camera is not None:
            for frame in self.camera_input.release():
                self.segment(*frame)

    def on_image(self, channel: str, image: Image) -> None:
        """Collect one channel's frame; segment when the exposure is complete."""
        stamp = stamp_ns(image.header)
        try:
            pixels = image_to_array(image)
        except ImageError as exc:
            self.reject(exc.reason, f'{channel} image stamped {stamp}: {exc}')
            return
        if not self.in_order(stamp, self.last_stamp, f'{channel} image'):
            return
        if not self.params.uses_green:
            if channel == 'uv':
                self.segment(stamp, (pixels, image.encoding), None)
            return
        pair = self.pairer.add(channel, stamp, (pixels, image.encoding))
        if pair is not None:
            self.segment(*pair)

    def segment(self, stamp: int, uv: tuple[np.ndarray, str], green: tuple[np.ndarray, str] | None) -> None:
        """Publish the mask of one exposure (or hold it until the camera is known)."""
        if green is not None and uv[0].shape != green[0].shape:
            self.reject(
                'size_mismatch',
                f'UV {uv[0].shape[::-1]} and green {green[0].shape[::-1]} images stamped {stamp} differ in size',
            )
            return
        if self.camera_input.camera is None:
            self.camera_input.hold((stamp, uv, green), self.now_ns())
            return
        if not self.camera_input.matches(uv[0].shape):
            return
        if self.segmenter is None:
            self.segmenter = SkylineSegmenter(SkylineGeometry.from_camera(self.camera_input.camera), self.params)
        with self.processing(stamp):
            try:
                mask = self.segmenter.segment(
                    uv[0], None if green is None else green[0], uv[1], None if green is None else green[1]
                )
            except ValueError as exc:
                self.reject('invalid_image', f'exposure stamped {stamp}: {exc}')
                return
            message = fill_image(Image(), mask, 'mono8')
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            message.header.frame_id = CAMERA_FRAME
        self.last_stamp = max(self.last_stamp, stamp)
        self.emit(MASK_TOPIC, message)


def main(args=None) -> int:
    """Run the skyline node until Ctrl-C."""
    return run_node(SkylineNode, args)
