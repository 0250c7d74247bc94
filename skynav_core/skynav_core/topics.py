# SPDX-License-Identifier: Apache-2.0
"""The contract's camera topics: where a robot's cameras publish (docs/interfaces.md, "Topics" and "Cameras")."""

from __future__ import annotations

#: The UV/green pair: two pixel-aligned mono images of one exposure and the geometry of both.
UV_IMAGE = '/camera/uv/image_raw'
GREEN_IMAGE = '/camera/green/image_raw'
UV_CAMERA_INFO = '/camera/uv/camera_info'
#: One colour camera: raw (colour or Bayer), the same through image_transport's `compressed`, and its geometry.
COLOUR_IMAGE = '/camera/image_raw'
COLOUR_COMPRESSED = '/camera/image_raw/compressed'
COLOUR_CAMERA_INFO = '/camera/camera_info'
