# SPDX-License-Identifier: Apache-2.0
"""The skyline node: camera frames in, the sky/ground mask out.

Takes one camera (parameter `camera`; docs/interfaces.md, "Cameras as robots have them"): the UV/green pair on
/camera/uv/image_raw and /camera/green/image_raw, paired by stamp, with /camera/uv/camera_info; or one colour
camera on /camera/image_raw (raw or Bayer) or /camera/image_raw/compressed (JPEG/PNG), with /camera/camera_info.
Publishes /skyline/mask (mono8, the input's size, 255 sky, 0 ground and outside the image circle) with the input's
stamp. UV-only methods do not wait for green; colour frames are segmented by `colour_method`. An exposure so
largely saturated or dark that the rules, not the image, would decide its mask (skynav_skyline.exposure) gets no
mask (so no /skyline/sh either): one log line, and /diagnostics counts it as `overexposed` or `underexposed`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from skynav_core.camera_input import CAMERA_INFO_TOPICS, CameraInput
from skynav_core.colour import decode_compressed, decode_image
from skynav_core.images import ImageError, fill_image, image_to_array, stamp_ns
from skynav_core.names import (
    CAMERA_FRAME,
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    GREEN_IMAGE,
    SKYLINE_MASK,
    SKYLINE_NODE,
    UV_IMAGE,
)
from skynav_core.node import SENSOR_QOS, SkynavNode
from skynav_core.pairing import StampPairer
from skynav_core.ros import run_node
from skynav_skyline.errors import SkylineError
from skynav_skyline.exposure import ExposureError

from .geometry import SkylineGeometry
from .parameters import NODE_PARAMETERS, PARAMETERS, colour_params, skyline_params
from .segment import FitCheckSchedule, SkylineSegmenter


class SkylineNode(SkynavNode):
    """Segments each camera exposure into sky and ground."""

    PARAMETERS = NODE_PARAMETERS
    INPUT_TOPICS = (UV_IMAGE, GREEN_IMAGE, COLOUR_IMAGE, COLOUR_COMPRESSED, *CAMERA_INFO_TOPICS)

    def __init__(self, **kwargs) -> None:
        super().__init__(SKYLINE_NODE, **kwargs)
        self.declare_table(NODE_PARAMETERS)
        self.camera_input = CameraInput(self.reject, self.drop)
        self.expire_with_time(self.camera_input.expire)
        self.segmenter: SkylineSegmenter | None = None
        self.colour_segmenter: SkylineSegmenter | None = None
        self.input(UV_IMAGE, Image, partial(self.on_image, 'uv'), SENSOR_QOS)
        self.input(GREEN_IMAGE, Image, partial(self.on_image, 'green'), SENSOR_QOS)
        self.input(COLOUR_IMAGE, Image, partial(self.on_colour, 'colour', decode_image), SENSOR_QOS)
        self.input(
            COLOUR_COMPRESSED,
            CompressedImage,
            partial(self.on_colour, 'colour-compressed', decode_compressed),
            SENSOR_QOS,
        )
        for topic in CAMERA_INFO_TOPICS:
            self.input(topic, CameraInfo, partial(self.on_camera_info, topic), SENSOR_QOS)
        self.output(SKYLINE_MASK, Image)
        self.start()

    def configure(self, values: dict) -> None:
        """Build the segmentation settings from parameter values (ValueError for unusable ones)."""
        segmentation = {name: values[name] for name in PARAMETERS}
        self.params, self.colour = skyline_params(segmentation), colour_params(segmentation)
        if values['pair_tolerance_ms'] < 0:
            raise SkylineError('pair_tolerance_ms must not be negative')
        self.pairer = StampPairer(('uv', 'green'), int(values['pair_tolerance_ms'] * 1e6), on_drop=self.drop_unpaired)
        self.fit_checks = FitCheckSchedule(values['fit_check_period'], self.params.max_disagreement)
        fov = math.radians(values['field_of_view_deg'])
        self.camera_input.configure(values['camera'], values['camera_info_url'], fov)
        self.segmenter = self.colour_segmenter = None  # rebuilt for the next frame

    def drop_unpaired(self, count: int) -> None:
        """Count frames whose other channel never came."""
        self.drop('unpaired', count, 'a UV or green frame whose other channel never came (within pair_tolerance_ms)')

    def reset_time(self) -> None:
        """Forget the last stamp, the frames waiting for their other channel and those waiting for camera info."""
        super().reset_time()
        self.pairer.clear()
        self.camera_input.forget('time_restarted')

    def on_camera_info(self, topic: str, info: CameraInfo) -> None:
        """Adopt the camera geometry; process what waited for it."""
        if self.camera_input.update(info, topic):
            self.segmenter = self.colour_segmenter = None
        if self.camera_input.camera is not None:
            for segment in self.camera_input.release():
                segment()

    def on_image(self, channel: str, image: Image) -> None:
        """Collect one channel's frame of the UV/green pair; segment when the exposure is complete."""
        stamp = stamp_ns(image.header)
        try:
            pixels = image_to_array(image)
        except ImageError as exc:
            self.reject(exc.reason, f'{channel} image stamped {stamp}: {exc}')
            return
        if not self.camera_input.admits('uv-green') or not self.in_order(stamp, self.last_stamp, f'{channel} image'):
            return
        if not self.params.uses_green:
            if channel == 'uv':
                self.taken(partial(self.segment, stamp, (pixels, image.encoding), None))
            return
        pair = self.pairer.add(channel, stamp, (pixels, image.encoding))
        if pair is not None:
            self.taken(partial(self.segment, *pair))

    def on_colour(self, source: str, decode: Callable, image: Image | CompressedImage) -> None:
        """Decode one colour camera frame (raw, Bayer or compressed) to linear RGB and segment it."""
        stamp = stamp_ns(image.header)
        try:
            rgb = decode(image)
        except ImageError as exc:
            self.reject(exc.reason, f'{source} frame stamped {stamp}: {exc}')
            return
        if self.camera_input.admits(source) and self.in_order(stamp, self.last_stamp, f'{source} frame'):
            self.taken(partial(self.segment_colour, stamp, rgb))

    def taken(self, segment: Callable[[], None]) -> None:
        """Segment an exposure now, or hold it until the camera is known."""
        if self.camera_input.camera is None:
            self.camera_input.hold(segment, self.elapsed_ns())
        else:
            segment()

    def geometry(self) -> SkylineGeometry:
        """Return the skyline geometry of the camera in use."""
        assert self.camera_input.camera is not None  # exposures wait until a camera is known
        return SkylineGeometry.from_camera(self.camera_input.camera)

    def segment(self, stamp: int, uv: tuple[np.ndarray, str], green: tuple[np.ndarray, str] | None) -> None:
        """Publish the mask of one UV/green exposure."""
        if green is not None and uv[0].shape != green[0].shape:
            self.reject(
                'size_mismatch',
                f'UV {uv[0].shape[::-1]} and green {green[0].shape[::-1]} images stamped {stamp} differ in size',
            )
            return
        if not self.camera_input.matches(uv[0].shape):
            return
        if self.segmenter is None:
            self.segmenter = SkylineSegmenter(self.geometry(), self.params)
        segmenter, check = self.segmenter, self.fit_checks.due()

        def segment() -> np.ndarray:
            mask = segmenter.segment(
                uv[0], None if green is None else green[0], uv[1], None if green is None else green[1], check
            )
            self.fit_checks.done(segmenter.disagreement)
            return mask

        self.publish_mask(stamp, segment)

    def segment_colour(self, stamp: int, rgb: np.ndarray) -> None:
        """Publish the mask of one colour exposure (uint16 linear RGB)."""
        if not self.camera_input.matches(rgb.shape):
            return
        if self.colour_segmenter is None:
            self.colour_segmenter = SkylineSegmenter(self.geometry(), self.colour)
        self.publish_mask(stamp, partial(self.colour_segmenter.segment_colour, rgb))

    def publish_mask(self, stamp: int, segment: Callable[[], np.ndarray]) -> None:
        """Publish the mask `segment` makes of the exposure stamped `stamp`; reject the exposure if it cannot."""
        with self.processing(stamp):
            try:
                mask = segment()
            except ExposureError as exc:  # its classes are not measured: no mask rather than one decided by rule
                self.reject(exc.reason, f'exposure stamped {stamp} is not segmented: {exc}')
                return
            except ValueError as exc:
                self.reject('invalid_image', f'exposure stamped {stamp}: {exc}')
                return
            message = fill_image(Image(), mask, 'mono8')
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            message.header.frame_id = CAMERA_FRAME
        self.last_stamp = max(self.last_stamp, stamp)
        self.emit(SKYLINE_MASK, message)


def main(args=None) -> int:
    """Run the skyline node until Ctrl-C."""
    return run_node(SkylineNode, args)
