# SPDX-License-Identifier: Apache-2.0
"""The compass and its peers as they are evaluated, in one registry: what each method compares, with which compass.

A method compares one view of a frame (VIEWS) with one compass and its settings. The frames of a compass set
(skynav_compass.eval.dataset: images and ground-truth masks) give every view; the SH node's output gives those of
NODE_VIEWS (its coefficients, whatever their fill, with the skyline node's masks and the UV images when recorded), so
`skynav eval compass` offers NODE_METHODS. runner.build_method turns an entry into a runnable Method.

The registry is plain data that imports no compass: the `skynav` command lists it while it builds its parser.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

#: What a method compares of a frame.
VIEWS = {
    'masked': "the skyline mask's SH with the part of the sphere the camera sees (a CompassView: the masked cost)",
    'zero': "the skyline mask's SH, zero where the camera does not see (the plain cost)",
    'mean': "the skyline mask's SH, the unseen part filled with the seen part's mean",
    'mirror': "the skyline mask's SH, the unseen part mirrored from the seen part",
    'uv': "the grey UV image's SH with the part of the sphere the camera sees",
    'mask': 'the skyline mask itself (an image)',
    'image': 'the UV image',
}
NODE_VIEWS = frozenset({'masked', 'zero', 'mask', 'image'})  # what the skyline and SH nodes' output gives
IMAGE_VIEWS = frozenset({'mask', 'image'})  # what only a recorded frame has: a map snapshot is SH coefficients
SNAPSHOT_COMPASSES = frozenset({'fft', 'fft-any-tilt', 'exhaustive'})  # those that prepare a snapshot once
PREPARED = '+prepared'  # name suffix on compass sets: the snapshot prepared once (the SNAPSHOT_COMPASSES' methods)


@dataclass(frozen=True)
class CompassMethod:
    """An entry of the registry: a method's name, the view it compares and its compass (with settings)."""

    name: str
    view: str  # a key of VIEWS
    # 'fft' (compass.Compass within the tilt bound), 'fft-any-tilt' (Compass without the prior), 'exhaustive'
    # (the source method's search), 'yaw' (yaw.YawCompass), 'panorama' (yaw.PanoramicCompass), 'features'
    compass: str
    settings: Mapping[str, Any] = field(default_factory=dict)  # fields of the compass's config

    @property
    def prepares(self) -> bool:
        """Return whether the compass prepares a snapshot once for many estimates."""
        return self.compass in SNAPSHOT_COMPASSES

    @property
    def needs_images(self) -> bool:
        """Return whether the method needs a recorded frame's images (a map snapshot lacks them)."""
        return self.view in IMAGE_VIEWS


METHODS: dict[str, CompassMethod] = {
    m.name: m
    for m in (
        CompassMethod('fft-masked', 'masked', 'fft'),  # skynav's compass (the node's)
        CompassMethod('fft-masked-any-tilt', 'masked', 'fft-any-tilt'),
        CompassMethod('fft-zero', 'zero', 'fft', {'cost': 'plain'}),
        CompassMethod('fft-mean', 'mean', 'fft', {'cost': 'plain'}),
        CompassMethod('fft-mirror', 'mirror', 'fft', {'cost': 'plain'}),
        # grey UV image instead of the mask, gain and offset removed over the overlap (masked correlation coefficient)
        CompassMethod('fft-uv-normalised', 'uv', 'fft', {'normalise': True}),
        CompassMethod('exhaustive-masked', 'masked', 'exhaustive'),
        CompassMethod('exhaustive-zero', 'zero', 'exhaustive', {'cost': 'plain'}),
        CompassMethod('visual-compass-sh', 'masked', 'yaw'),
        CompassMethod('visual-compass-panorama', 'mask', 'panorama'),
        CompassMethod('features-sift', 'image', 'features', {'detector': 'sift'}),
        CompassMethod('features-orb', 'image', 'features', {'detector': 'orb'}),
    )
}
NODE_METHODS = tuple(name for name, m in METHODS.items() if m.view in NODE_VIEWS)  # `skynav eval compass` offers
DEFAULT_METHODS = ('fft-masked', 'exhaustive-masked', 'visual-compass-panorama', 'features-sift')
