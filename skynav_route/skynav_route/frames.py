# SPDX-License-Identifier: Apache-2.0
"""The route node's camera frames: each frame's inputs kept by its stamp, and which frame is due an answer.

A frame is processed when its home vector comes (warping is the last stage), or, when none comes, once a view
`frame_wait` s newer arrives on /skyline/sh (in the in-process graph, where every node has answered a view before
the next subscriber hears it, at the frame's own /skyline/sh). A frame input stamped over `max_stamp_jump_s` before
the newest of its topic restarts the frames' time (the frames kept by stamp are forgotten; a stage that lags
restarts nothing). No rclpy: the node (skynav_route.node) hands the messages in and answers the frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from nav_msgs.msg import Odometry

from skynav_core.images import stamp_ns
from skynav_core.names import HOME_VECTOR, SKYLINE_SH
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients

from .controller import View
from .inputs import frame_view

KEPT_FRAMES = 8  # recent frames whose match and compass estimate are kept, by stamp


class Frames:
    """The place matches, compass estimates and home vectors of recent frames by stamp (ns), and the odometry."""

    def __init__(self, restart: Callable[[int, int], object], reject: Callable[[str, str], None]) -> None:
        self.restart = restart  # the node's stamp_jumped(stamp, last): its time restarts (reset) over the jump
        self.reject = reject  # the node's reject(reason, detail)
        self.matches: dict[int, PlaceMatch] = {}
        self.compass: dict[int, CompassEstimate] = {}
        self.homes: dict[int, HomeVector] = {}
        self.last = -1  # stamp (ns) of the last frame processed
        self.odom: np.ndarray | None = None  # latest base_link position in odom (x, y), m
        self.odom_at_frame: np.ndarray | None = None
        self.newest: dict[str, int] = {}  # per frame input topic, its newest stamp (ns) since the time restarted

    def frame_input(self, topic: str, stamp: int) -> None:
        """Take the stamp (ns) of a frame's input on `topic`, against the newest of that topic alone."""
        # one over max_stamp_jump_s before the newest restarts the frames' time (a camera clock that jumped back, a
        # recording played again), or its frames would be refused as late; a stage that lags (home vectors a second
        # behind the views) restarts nothing, and a jump forward needs no restart
        newest = self.newest.get(topic, -1)
        if stamp < newest:  # stamp_jumped restarts the time only if it lies over max_stamp_jump_s back
            self.restart(stamp, newest)
        self.newest[topic] = max(self.newest.get(topic, -1), stamp)

    def reset(self) -> None:
        """Forget the frames kept by stamp and the last frame answered: the frames' time restarted."""
        self.matches.clear()
        self.compass.clear()
        self.homes.clear()
        self.last = -1
        self.newest.clear()

    def keep(self, topic: str, kept: dict[int, Any], message: Any) -> None:
        """Keep a frame's message of `topic` by stamp (the last KEPT_FRAMES frames)."""
        stamp = stamp_ns(message.header)
        self.frame_input(topic, stamp)
        kept[stamp] = message
        while len(kept) > KEPT_FRAMES:
            del kept[min(kept)]

    def on_odom(self, message: Odometry) -> None:
        """Remember the latest odometry position (m, frame odom)."""
        p = message.pose.pose.position
        if math.isfinite(p.x) and math.isfinite(p.y):
            self.odom = np.array([p.x, p.y])
        else:
            self.reject('non_finite', 'an /odom pose is not finite')

    def home_vector(self, message: HomeVector) -> int | None:
        """Keep a home vector; return its frame's stamp (ns) to process, None if that frame was answered already."""
        self.keep(HOME_VECTOR, self.homes, message)
        stamp = stamp_ns(message.header)
        if stamp <= self.last:
            self.reject('late', 'a home vector came after its frame was answered without it')
            return None
        return stamp

    def due(self, message: ShCoefficients, wait: int, in_process: bool) -> int | None:
        """Return the stamp (ns) of the newest frame a view makes due, `wait` ns before it (None: none is)."""
        # frames that got no home vector; in process the view's own frame too
        stamp = stamp_ns(message.header)
        self.frame_input(SKYLINE_SH, stamp)
        waiting = [s for s in set(self.matches) | set(self.compass) if self.last < s <= stamp - wait and s < stamp]
        if in_process and stamp > self.last:
            waiting.append(stamp)
        return max(waiting) if waiting else None

    def answer(self, stamp: int) -> int | None:
        """Answer the frame stamped `stamp` (ns): return the previous one's stamp (-1: none), None if not newer."""
        if stamp <= self.last:  # a jump in the frames' time restarted it already (frame_input)
            self.reject('out_of_order', f'frame stamped {stamp} is not newer than the last one')
            return None
        previous, self.last = self.last, stamp
        return previous

    def view(self, stamp: int, mount: np.ndarray, home_expected: bool) -> View:
        """Return what the controller knows of the frame stamped `stamp` (ns), in base_link (by `mount`)."""
        match, compass, home = self.matches.get(stamp), self.compass.get(stamp), self.homes.get(stamp)
        view = frame_view(stamp, match, compass, home, mount)
        view.home_expected = home_expected
        if self.odom is not None:
            previous = self.odom_at_frame if self.odom_at_frame is not None else self.odom
            view.odometry = float(np.linalg.norm(self.odom - previous))
            self.odom_at_frame = self.odom.copy()
        return view
