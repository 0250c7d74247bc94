# SPDX-License-Identifier: Apache-2.0
"""The structure of an upward view: two corrections of a thresholded mask that no per-pixel threshold can make.

Ground stands on the horizon. In an upward fish-eye view every piece of ground therefore
reaches the rim of the image circle (or hangs from something that does), and along a ray
outwards from the sky, the sky ends where the ground that stands on the horizon begins.

- Enclosed ground. A region classified ground (8-connected) that neither reaches the rim nor
  holds a pixel clearly ground (contrast at least `hole_margin` below its threshold, or UV dark) is sky
  the threshold missed: the dim sky opposite a low sun, when a thin ring of ground leaves the
  histogram without a second mode. A crown or a branch over the camera is enclosed by sky
  too, but it lies far below the threshold, so it stays ground.
- Ground ring. Along each ray, sky beyond the outermost band of ground (at least
  `ring_width` wide along the ray, with sky before it) is bright ground below the horizon:
  snow, sand, pale paving or a sunlit wall seen beyond a forest edge or a hedge. It is cut
  only when such bands ring at least `ring_share` of the azimuths: sky below a single crown
  or beside a tree is real, and a camera tilted by the ground sees far above the horizon
  on one side.

Both use per-camera tables built once (geometry.py): the first labels the ground of one
image per frame (only the part that can hold an enclosed region), the second reads the
mask at fixed samples along RAY_COUNT rays.
"""

from __future__ import annotations

import cv2
import numpy as np

from skynav_skyline.errors import SkylineError

#: Rays of the ground-ring step: one per degree of azimuth.
RAY_COUNT = 360
#: Off-axis angle (rad) between samples along a ray: one degree (but at least a pixel).
RAY_STEP = np.radians(1.0)
#: Neighbourhood of 8-connectivity, for dilating the clearly ground pixels onto their neighbours.
_NEIGHBOURS = np.ones((3, 3), np.uint8)


def unanchored_ground(state: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """Return the flat indices of the ground pixels in 8-connected regions of ground with no anchor.

    `state` (uint8 image) is 0 where not ground, 1 where ground and 2 where clearly ground;
    `inner` (bool image) is False on the rim of the image circle. A region is
    anchored when it holds a clearly ground pixel or a rim pixel. Only regions of plain
    ground alone, none of it next to a clearly ground pixel or on the rim (the candidates),
    can be unanchored; they are labelled in the candidates' bounding box grown by one pixel,
    where a plain ground pixel that is not a candidate anchors its region (a region leaving
    the box crosses its border, which holds no candidate).
    """
    weak = state == 1
    # a candidate: plain ground with no clearly ground pixel among its 8 neighbours, off the rim
    candidate = weak & inner & (cv2.dilate(state, _NEIGHBOURS) == 1)
    if not candidate.any():
        return np.zeros(0, np.intp)
    left, top, width, height = cv2.boundingRect(candidate.view(np.uint8))
    rows = slice(max(top - 1, 0), min(top + height + 1, state.shape[0]))
    columns = slice(max(left - 1, 0), min(left + width + 1, state.shape[1]))
    box_weak = np.ascontiguousarray(weak[rows, columns])
    box_candidate = np.ascontiguousarray(candidate[rows, columns])
    count, labels = cv2.connectedComponents(box_weak.view(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    anchored = np.zeros(count, bool)
    anchored[0] = True  # the background: not plain ground
    anchored[labels[box_weak & ~box_candidate]] = True  # plain ground that is not a candidate
    found = np.flatnonzero(box_candidate)
    free = found[~anchored[labels.reshape(-1)[found]]]
    row, column = np.divmod(free, box_candidate.shape[1])
    return (row + rows.start) * state.shape[1] + column + columns.start


def outermost_band_end(ground: np.ndarray, inside: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (end, cut) per ray of ray samples (rays, steps): where the outermost band of ground ends.

    `ground` and `inside` (bool, same shape) say which samples are ground and which lie in the
    image circle; samples inside and not ground are sky. A band is a run of at least `width`
    ground samples with a sky sample somewhere before it. `end` is the index just past the
    outermost band (`steps` if the ray has none); `cut` says whether sky samples lie beyond it.
    """
    width = int(width)
    if width < 1:
        raise SkylineError(f'band width must be at least 1 sample, got {width}')
    inside = np.asarray(inside, bool)
    ground = np.asarray(ground, bool) & inside
    sky = inside & ~ground
    rays, steps = ground.shape
    if width > steps:
        return np.full(rays, steps), np.zeros(rays, bool)
    # whole[:, k]: samples k .. k + width - 1 are all ground (windows past the last sample are not)
    whole = cv2.erode(
        ground.view(np.uint8),
        np.ones((1, width), np.uint8),
        anchor=(0, 0),
        borderType=cv2.BORDER_CONSTANT,
        borderValue=0,
    ).view(bool)
    has_sky = sky.any(axis=1)
    first_sky = np.where(has_sky, np.argmax(sky, axis=1), steps)
    band = whole & (np.arange(steps) > first_sky[:, None])  # windows with sky before them
    has_band = band.any(axis=1)
    last = steps - 1 - np.argmax(band[:, ::-1], axis=1)  # the outermost band's last window
    end = np.where(has_band, last + width, steps)
    last_sky = steps - 1 - np.argmax(sky[:, ::-1], axis=1)
    return end, has_band & has_sky & (last_sky >= end)
