# SPDX-License-Identifier: Apache-2.0
"""What stops the route node's goals whatever the controller says: the emergency stop, the IMU's tilt, the bumper.

Emergency stop: when /emergency_stop says true, the node publishes a zero command at once and an active goal aborts
with EMERGENCY_STOP; then nothing is published (no goal is active) until a new goal comes, and a goal that comes
while the stop is still true is refused with EMERGENCY_STOP and never moves. An IMU (/camera/imu, sensor_msgs/Imu,
optional) that shows the robot leaning more than `max_tilt_deg` from the vertical for TILT_HOLD s (by its stamps)
stops it the same way, until it is level again (inputs.imu_tilt; the IMU frame's rotation in base_link from
/tf_static, base_link's own axes while it gives none). A lift that does not tilt the robot is not seen. The stops
are counted in /diagnostics (emergency_stops; emergency_stop says whether it is engaged, and the status is WARN
while it is). No rclpy: the node (skynav_route.node) hands the inputs in and stops its goal when told.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from skynav_core.images import stamp_ns

from .goals import EMERGENCY_INPUT
from .inputs import TILT_HOLD, imu_tilt

INPUT_STOP, TILT_STOP = 'input', 'tilt'  # what may engage the emergency stop


class Safety:
    """The emergency stop's causes and count, the robot's lean (IMU stamps, ns) and the bumper's word."""

    def __init__(self, logger: Any, driving: Callable[[], bool], stop: Callable[[], None]) -> None:
        self.logger = logger  # the node's
        self.driving = driving  # whether a goal is active
        self.stop = stop  # stops the robot and aborts the active goal (EMERGENCY_STOP)
        self.bumped = False  # the bumper's latest word: in contact
        self.reasons: dict[str, str] = {}  # what engages the emergency stop now (INPUT_STOP, TILT_STOP): why
        self.stops = 0  # times it was engaged
        self.tilted_since: int | None = None  # ns, IMU stamp since which the robot leans over max_tilt_deg

    @property
    def engaged(self) -> bool:
        """Return whether the emergency stop is engaged (by its input or the IMU's tilt)."""
        return bool(self.reasons)

    def reason(self) -> str:
        """Return why the emergency stop is engaged (each cause's reason, '; ' between them)."""
        return '; '.join(self.reasons.values())

    def engage(self, cause: str, reason: str | None) -> None:
        """Engage the emergency stop for `cause` (INPUT_STOP, TILT_STOP) because of `reason` (None: release it)."""
        # engaged, it stops the robot at once and aborts the active goal (EMERGENCY_STOP); goals are refused meanwhile
        if reason is None:
            if self.reasons.pop(cause, None) is not None and not self.reasons:
                self.logger.info('emergency stop released: a new goal may drive')
            return
        if cause not in self.reasons:
            self.stops += 1
            doing = 'the robot stops and the goal aborts' if self.driving() else 'no goal drives'
            self.logger.error(
                f'emergency stop engaged ({reason}): {doing} (EMERGENCY_STOP) until it is released and a new goal '
                'comes; counted in /diagnostics as emergency_stops'
            )
        self.reasons[cause] = reason
        if self.driving():
            self.stop()

    def on_emergency_stop(self, engaged: bool) -> None:
        """Take the emergency stop input's word: true engages the stop, false releases it."""
        self.engage(INPUT_STOP, EMERGENCY_INPUT if engaged else None)

    def on_imu(self, message: Any, rotation: np.ndarray | None, limit: float) -> bool:
        """Take an IMU reading (`rotation`: its frame's in base_link) against `limit` deg; False if unusable."""
        tilt = imu_tilt(message, np.eye(3) if rotation is None else rotation)
        if tilt is None:
            return False
        self.lean(stamp_ns(message.header), math.degrees(tilt), limit)
        return True

    def lean(self, stamp: int, degrees: float, limit: float) -> None:
        """Take the robot's lean (deg from the vertical) at an IMU stamp (ns) against `limit` deg for TILT_HOLD s."""
        if degrees <= limit:
            self.tilted_since = None
            self.engage(TILT_STOP, None)
            return
        if self.tilted_since is None or stamp < self.tilted_since:
            self.tilted_since = stamp
        if stamp - self.tilted_since >= TILT_HOLD * 1e9:
            self.engage(TILT_STOP, f'the robot leans {degrees:.0f} deg from the vertical, over max_tilt_deg {limit:g}')
