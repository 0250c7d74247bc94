# SPDX-License-Identifier: Apache-2.0
"""A lawn mowed lane after lane: the pattern, the scripted operator who teaches it, and the coverage of a drive.

A *lawn* is `lanes` parallel straight lanes of `length` m, `gap` m apart (about a cutting width), driven back and
forth (a boustrophedon): at a lane's end the mower turns in place a quarter turn, drives the gap across, turns in
place again and drives the next lane the other way. Positions are in the world's map frame (m), headings in rad.

The *swath* of a drive is the ground within half a cutting width of its path; the coverage of a repeat is the
share of the taught drive's swath the repeat's swath holds, and the widest uncut strip is the width of the widest
band of the taught swath the repeat left uncut (twice the largest distance of an uncut cell from cut or untaught
ground). Pure numpy and scipy; synthetic worlds only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt

from skynav_core.rotations import wrap_angle

from .world import YARD_RADIUS, World

LANE_GAP = 0.4  # m between neighbouring lanes' centre lines
CUT_WIDTH = 0.5  # m: the mower's cutting width
COVERAGE_CELL = 0.01  # m: the side of a cell of the coverage grid
LAWN_MARGIN = 0.6  # m of free ground a lawn keeps around its lanes (the mower's body and its turns)
OPERATOR_SPEED = 0.3  # m/s: the scripted operator's speed along a lane
OPERATOR_LOOKAHEAD = 0.5  # m: it steers towards the lane's point this far beyond its nearest one
OPERATOR_GAIN = 2.0  # rad/s of turn rate per rad of heading error
OPERATOR_MAX_TURN = 1.0  # rad/s: the joystick's largest turn rate
TURN_TOLERANCE = math.radians(2.0)  # rad: a point turn ends once the heading is this close to the next lane's
LANE_END_TOLERANCE = 0.03  # m: a lane (or the gap across) is driven once this close to its end


@dataclass(frozen=True)
class Lawn:
    """Parallel lanes from `origin` along `heading` (rad), each `length` m, the next `gap` m to the `side`."""

    origin: tuple[float, float]
    heading: float
    lanes: int
    length: float
    gap: float = LANE_GAP
    side: int = 1  # +1: the next lane lies to the left of the first lane's direction, -1: to the right

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the unit (x, y) directions along the lanes (the first lane's) and across them (to the next lane)."""
        along = np.array([math.cos(self.heading), math.sin(self.heading)])
        return along, self.side * np.array([-along[1], along[0]])

    def corners(self) -> np.ndarray:
        """Return the pattern's corners (2 lanes, 2) in driving order: each lane's start and end."""
        along, across = self.axes()
        points: list[np.ndarray] = []
        for lane in range(self.lanes):
            start = np.asarray(self.origin, float) + lane * self.gap * across
            ends = (start, start + self.length * along)
            points.extend(ends if lane % 2 == 0 else ends[::-1])
        return np.array(points)

    @property
    def path_length(self) -> float:
        """Return the length (m) of the pattern's path: every lane and every gap across."""
        return self.lanes * self.length + (self.lanes - 1) * self.gap

    def fits(self, world: World, margin: float = LAWN_MARGIN, step: float = 0.1) -> bool:
        """Return whether the lawn and `margin` m of ground around it are free in `world`."""
        # the rectangle around the lanes, turned with them: sample it on a grid of `step` m
        along, across = self.axes()
        u = np.arange(-margin, self.length + margin + step, step)
        v = np.arange(-margin, (self.lanes - 1) * self.gap + margin + step, step)
        grid = np.asarray(self.origin, float) + u[:, None, None] * along + v[None, :, None] * across
        return bool(np.all(world.is_free(grid[..., 0], grid[..., 1])))


def place_lawn(
    world: World, lanes: int, length: float, gap: float = LANE_GAP, tries: int = 20000, seed: int = 0
) -> Lawn | None:
    """Return a lawn of that many lanes that fits in `world` (free with a margin), None if none was found."""
    rng = np.random.default_rng([seed, lanes, round(length * 100), round(gap * 1000)])
    free = np.argwhere(world.free)
    if not len(free):
        return None
    for _ in range(tries):
        j, i = free[rng.integers(len(free))]
        origin = (float(i * world.free_cell - YARD_RADIUS), float(j * world.free_cell - YARD_RADIUS))
        lawn = Lawn(origin, float(rng.uniform(-math.pi, math.pi)), lanes, length, gap, int(rng.choice([-1, 1])))
        if lawn.fits(world):
            return lawn
    return None


class LaneOperator:
    """The scripted operator who teaches a lawn: drives each lane and gap straight, turns in place at the corners.

    It sees the mower and the pattern (the teacher, not skynav), as a person with a joystick would.
    """

    def __init__(self, lawn: Lawn, speed: float = OPERATOR_SPEED) -> None:
        self.corners, self.speed = lawn.corners(), speed
        self.segment = 0  # the leg being driven: from corner `segment` to the next
        self.turning = True  # a point turn onto the leg comes first

    @property
    def done(self) -> bool:
        """Return whether every leg was driven."""
        return self.segment >= len(self.corners) - 1

    def command(self, x: float, y: float, heading: float) -> tuple[float, float]:
        """Return the operator's command (m/s, rad/s) for the mower at (x, y) heading `heading` (map frame)."""
        while not self.done:
            start, end = self.corners[self.segment], self.corners[self.segment + 1]
            leg = end - start
            length = float(np.linalg.norm(leg))
            direction = leg / length
            error = wrap_angle(math.atan2(direction[1], direction[0]) - heading)
            if self.turning:
                if abs(error) > TURN_TOLERANCE:
                    return 0.0, float(np.clip(OPERATOR_GAIN * error, -OPERATOR_MAX_TURN, OPERATOR_MAX_TURN))
                self.turning = False
            offset = np.array([x, y]) - start
            along = float(offset @ direction)
            if along >= length - LANE_END_TOLERANCE:
                self.segment += 1
                self.turning = True
                continue
            across = float(direction[0] * offset[1] - direction[1] * offset[0])  # m, left of the leg positive
            target = error - math.atan2(across, OPERATOR_LOOKAHEAD)
            target = wrap_angle(target)
            remaining = length - along
            speed = min(self.speed, max(remaining / 0.5, 0.1) * self.speed)  # slow into the corner
            return speed * max(0.0, math.cos(target)), float(
                np.clip(OPERATOR_GAIN * target, -OPERATOR_MAX_TURN, OPERATOR_MAX_TURN)
            )
        return 0.0, 0.0


@dataclass(frozen=True)
class CoverageGrid:
    """A square-celled grid over the ground (map frame): `origin` (m) is the centre of cell (0, 0)."""

    origin: np.ndarray
    cell: float
    shape: tuple[int, int]  # (rows along y, columns along x)

    @classmethod
    def around(cls, points: np.ndarray, margin: float, cell: float = COVERAGE_CELL) -> CoverageGrid:
        """Return the grid over the bounding box of `points` (N, 2) grown by `margin` m."""
        low = np.min(points, axis=0) - margin
        high = np.max(points, axis=0) + margin
        columns, rows = np.ceil((high - low) / cell).astype(int) + 1
        return cls(low, cell, (int(rows), int(columns)))

    def swath(self, path: np.ndarray, width: float) -> np.ndarray:
        """Return the cells (rows, columns) bool within width/2 m of the polyline `path` (N, 2)."""
        path = np.asarray(path, float).reshape(-1, 2)
        track = np.zeros(self.shape, bool)
        if len(path) == 1:
            samples = path
        else:
            legs = np.diff(path, axis=0)
            counts = np.maximum(np.ceil(np.linalg.norm(legs, axis=1) / (self.cell / 2)).astype(int), 1)
            share = np.concatenate([np.arange(c) / c for c in counts])
            starts = np.repeat(path[:-1], counts, axis=0)
            samples = np.vstack([starts + np.repeat(legs, counts, axis=0) * share[:, None], path[-1:]])
        cells = np.round((samples - self.origin) / self.cell).astype(int)
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < self.shape[1]) & (cells[:, 1] >= 0) & (cells[:, 1] < self.shape[0])
        track[cells[inside, 1], cells[inside, 0]] = True
        if not track.any():
            return track
        return distance_transform_edt(~track) * self.cell <= width / 2


@dataclass(frozen=True)
class Coverage:
    """How much of a taught lawn a repeat cut: the share (0..1) and the widest uncut strip (m)."""

    share: float
    widest_uncut: float
    taught: np.ndarray  # the taught swath (bool grid)
    repeated: np.ndarray  # the repeat's swath (bool grid)
    grid: CoverageGrid

    @property
    def uncut(self) -> np.ndarray:
        """Return the cells the teach cut and the repeat did not."""
        return self.taught & ~self.repeated


def coverage(taught: np.ndarray, repeats: list[np.ndarray], width: float = CUT_WIDTH) -> Coverage:
    """Return the coverage of the taught path (N, 2) by the repeat paths (one or more, each (M, 2)), in m."""
    grid = CoverageGrid.around(np.vstack([taught, *repeats]), width)
    taught_swath = grid.swath(taught, width)
    repeated = np.zeros(grid.shape, bool)
    for path in repeats:
        if len(path):
            repeated |= grid.swath(path, width)
    uncut = taught_swath & ~repeated
    share = float((taught_swath & repeated).sum() / max(int(taught_swath.sum()), 1))
    # a band n cells wide has cells (n + 1) / 2 cells from the nearest cut or untaught one at its middle
    widest = (2.0 * float(distance_transform_edt(uncut).max()) - 1.0) * grid.cell if uncut.any() else 0.0
    return Coverage(share, widest, taught_swath, repeated, grid)
