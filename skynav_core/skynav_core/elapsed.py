# SPDX-License-Identifier: Apache-2.0
"""Time that passes on a clock which may start at zero and jump: what every timeout of skynav measures.

A node's clock is not always smooth. Under sim time it reads zero until the first /clock message and then jumps to
the simulator's time; a recording replayed with its own clock jumps back when it loops or starts again. A timeout
that compared two readings of such a clock would fire on the jump. `ElapsedTime` reads the clock often (a timer of
the node) and adds up only the steps a running clock makes: a step backwards, or forwards by more than `max_step_ns`,
is a jump and adds nothing, and so is the step from a reading of zero (ROS time zero is a clock not yet started). No
rclpy: it takes the clock's readings in ns.
"""

from __future__ import annotations


class ElapsedTime:
    """Time (ns) that passed on a clock, its jumps left out."""

    def __init__(self, max_step_ns: int) -> None:
        if max_step_ns <= 0:
            raise ValueError('max_step_ns must be positive')
        self.max_step_ns = max_step_ns
        self.total_ns = 0  # ns passed, the jumps left out
        self.jumps = 0  # readings that jumped
        self._last: int | None = None

    def read(self, clock_ns: int) -> int:
        """Take a reading of the clock (ns) and return the time passed since the first one, its jumps left out (ns)."""
        if self._last is not None:
            step = clock_ns - self._last
            if 0 <= step <= self.max_step_ns and (self._last != 0 or step == 0):
                self.total_ns += step
            else:
                self.jumps += 1
        self._last = clock_ns
        return self.total_ns
