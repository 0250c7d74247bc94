# SPDX-License-Identifier: Apache-2.0
"""Terrain: a height field with a surface material per cell, and rays cast against it.

Heights z(x, y) in metres in the `map` frame (x east, y north, z up) on a
regular grid; bilinear between grid points. Beyond the grid the terrain
continues at the height of its border.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter

# Ray marching: first step length (m), growth factor per step, refinement bisections.
MARCH_FIRST_STEP = 0.03
MARCH_GROWTH = 1.02
MARCH_BISECTIONS = 10
# Block widths (cells, powers of two) of the levels of the max-height pyramid.
PYRAMID_WIDTHS = (1, 4, 16, 64)
# Downward rays start marching where they may first reach the highest terrain within this radius (m).
NEAR_RADIUS = 4.0
# Horizon profile: azimuth bins, samples along each bin's line (first step m, growth), and the margin
# (rad) by which a ray must clear the profile to skip marching.
HORIZON_BINS = 1440
HORIZON_FIRST_STEP = 0.05
HORIZON_GROWTH = 1.06
HORIZON_MARGIN = np.radians(1.0)


@dataclass
class Terrain:
    """Height field z = height(x, y) and material per cell over [-extent, extent]^2 (m)."""

    heights: np.ndarray  # (n, n) z in metres at grid points
    materials: np.ndarray  # (n, n) uint8 Surface index per grid point
    extent: float  # half side length of the grid (m)

    def __post_init__(self) -> None:
        self.n = self.heights.shape[0]
        self.cell = 2 * self.extent / (self.n - 1)
        gy, gx = np.gradient(self.heights, self.cell)
        self._flat = {'height': self.heights.ravel(), 'gx': gx.ravel(), 'gy': gy.ravel()}
        self.max_height = float(self.heights.max())
        self._horizon_cache: tuple = (None, None)
        # Pyramid for marching: each level holds, per block of `width` cells, the highest terrain in
        # that block and its eight neighbours, i.e. everywhere within one block width of any point in it.
        # Stored as (reach in m, log2 of the width, blocks per side, flat ceilings), coarsest first.
        self._levels: list[tuple[float, int, int, np.ndarray]] = []
        for width in PYRAMID_WIDTHS:
            size = -(-self.n // width)
            padded = np.full((size * width, size * width), -np.inf)
            padded[: self.n, : self.n] = self.heights
            blocks = padded.reshape(size, width, size, width).max(axis=(1, 3))
            ceiling = maximum_filter(blocks, size=3, mode='nearest')
            self._levels.insert(0, (width * self.cell, int(np.log2(width)), size, ceiling.ravel()))

    def _grid_coordinates(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return flat index of the lower-left grid point and the fractions, clamped to the grid."""
        gx = np.clip((np.asarray(x, float) + self.extent) * (1 / self.cell), 0, self.n - 1.000001)
        gy = np.clip((np.asarray(y, float) + self.extent) * (1 / self.cell), 0, self.n - 1.000001)
        i = gx.astype(np.int64)
        j = gy.astype(np.int64)
        return j * self.n + i, gx - i, gy - j

    def _bilinear(self, name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        flat = self._flat[name]
        index, fx, fy = self._grid_coordinates(x, y)
        top = flat.take(index) * (1 - fx) + flat.take(index + 1) * fx
        bottom = flat.take(index + self.n) * (1 - fx) + flat.take(index + self.n + 1) * fx
        return top * (1 - fy) + bottom * fy

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the terrain height (m) at world points (x, y)."""
        return self._bilinear('height', x, y)

    def normal(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the unit surface normal (..., 3) at world points (x, y)."""
        gx, gy = self._bilinear('gx', x, y), self._bilinear('gy', x, y)
        n = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def material(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the Surface index of the nearest grid point to world points (x, y)."""
        index, fx, fy = self._grid_coordinates(x, y)
        return self.materials.ravel().take(index + (fx > 0.5) + self.n * (fy > 0.5))

    def horizon(self, origin: np.ndarray, max_distance: float) -> np.ndarray:
        """Return the highest elevation angle (rad) of the terrain seen from `origin`, per azimuth bin.

        Bin k covers azimuths around 2 pi k / HORIZON_BINS (from +x towards +y); each value is
        the largest of the bin and its two neighbours, so it bounds the rays between bin centres.
        """
        key = (tuple(np.round(origin, 9)), max_distance)
        if self._horizon_cache[0] == key:
            return self._horizon_cache[1]
        azimuth = np.linspace(0, 2 * np.pi, HORIZON_BINS, endpoint=False)
        steps = HORIZON_FIRST_STEP * HORIZON_GROWTH ** np.arange(
            int(np.log(1 + max_distance * (HORIZON_GROWTH - 1) / HORIZON_FIRST_STEP) / np.log(HORIZON_GROWTH)) + 1
        )
        reach = np.cumsum(steps)
        x = origin[0] + np.outer(np.cos(azimuth), reach)
        y = origin[1] + np.outer(np.sin(azimuth), reach)
        elevation = np.arctan2(self.height(x, y) - origin[2], reach).max(axis=1)
        profile = np.maximum(np.maximum(elevation, np.roll(elevation, 1)), np.roll(elevation, -1))
        self._horizon_cache = (key, profile)  # the boundary pass of a frame asks again from the same place
        return profile

    def may_hit(self, origin: np.ndarray, directions: np.ndarray, max_distance: float) -> np.ndarray:
        """Return, for rays from one `origin`, whether each may meet the terrain (False: it surely does not)."""
        horizon = self.horizon(origin, max_distance)
        azimuth = np.arctan2(directions[:, 1], directions[:, 0]) % (2 * np.pi)
        bins = np.round(azimuth / (2 * np.pi) * HORIZON_BINS).astype(int) % HORIZON_BINS
        elevation = np.arcsin(np.clip(directions[:, 2], -1, 1))
        return elevation <= horizon[bins] + HORIZON_MARGIN

    def first_contact(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Return, for rays from one `origin`, a distance (m) before which none can meet the terrain.

        A downward ray stays above the highest terrain point within NEAR_RADIUS until it descends
        to that height; if that happens within the radius, the march may start there.
        """
        index, _, _ = self._grid_coordinates(origin[0], origin[1])
        reach = int(np.ceil(NEAR_RADIUS / self.cell)) + 1
        j, i = divmod(int(index), self.n)
        patch = self.heights[max(j - reach, 0) : j + reach + 2, max(i - reach, 0) : i + reach + 2]
        clearance = origin[2] - float(patch.max())
        down = -directions[:, 2]
        with np.errstate(divide='ignore'):
            start = np.where(down > 0, clearance / down, 0.0)
        horizontal = start * np.sqrt(np.clip(1 - directions[:, 2] ** 2, 0, 1))
        return np.where((clearance > 0) & (horizontal < NEAR_RADIUS), start, 0.0)

    def intersect(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_distance: float | np.ndarray,
        start: np.ndarray | None = None,
    ) -> np.ndarray:
        """Return the distance (m) along each ray to the terrain, inf where it misses within max_distance.

        Marches over a pyramid of maximum heights: where a ray is above every terrain point within
        a block's reach it takes the step that keeps it so; near the ground it takes small steps
        (MARCH_FIRST_STEP, growing with distance) and bisects the first crossing. Rays stop when
        they climb above the highest terrain point or pass their own max_distance (scalar or per
        ray). Rays may begin at per-ray `start` distances known to be above ground (first_contact).
        """
        count = directions.shape[0]
        limit = np.broadcast_to(np.asarray(max_distance, float), (count,))
        along = np.zeros(count) if start is None else np.asarray(start, float)
        shared_origin = np.ndim(origins) == 1
        rays = np.flatnonzero(along <= limit)
        # The rays still marching, kept compact: every array below is indexed like `rays`.
        o = origins if shared_origin else origins[rays]
        d = directions[rays]
        horizontal = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        s, lim = along[rays], limit[rays]
        previous = s.copy()
        found: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (rays, above, below) per step
        n, flat = self.n, self._flat['height']
        while rays.size:
            ox, oy, oz = o if shared_origin else o.T
            px, py, pz = ox + s * d[:, 0], oy + s * d[:, 1], oz + s * d[:, 2]
            gx = np.clip((px + self.extent) * (1 / self.cell), 0, n - 1.000001)
            gy = np.clip((py + self.extent) * (1 / self.cell), 0, n - 1.000001)
            i, j = gx.astype(np.int64), gy.astype(np.int64)
            fx, fy = gx - i, gy - j
            index = j * n + i
            height = (flat.take(index) * (1 - fx) + flat.take(index + 1) * fx) * (1 - fy) + (
                flat.take(index + n) * (1 - fx) + flat.take(index + n + 1) * fx
            ) * fy
            below = pz < height
            if below.any():
                found.append((rays[below], previous[below], s[below]))
            step = np.maximum(MARCH_FIRST_STEP, (MARCH_GROWTH - 1) * s)
            descending = d[:, 2] < 0
            for reach, shift, size, ceiling in self._levels:
                clearance = pz - ceiling.take((j >> shift) * size + (i >> shift))
                with np.errstate(divide='ignore', invalid='ignore'):
                    safe = np.minimum(reach / horizontal, np.where(descending, clearance / -d[:, 2], np.inf))
                step = np.where(clearance > 0, np.maximum(step, safe), step)
            escaped = ((~descending) & (pz > self.max_height)) | (s >= lim)
            keep = ~below & ~escaped
            rays, d, horizontal, lim, previous = rays[keep], d[keep], horizontal[keep], lim[keep], s[keep]
            if not shared_origin:
                o = o[keep]
            s = np.minimum(previous + step[keep], lim)
        hit = np.full(count, np.inf)
        if found:
            crossed, above, beneath = (np.concatenate(parts) for parts in zip(*found))
            o_crossed = np.broadcast_to(origins, (count, 3))[crossed]
            hit[crossed] = self._bisect(o_crossed, directions[crossed], above, beneath)
        return hit

    def _bisect(self, o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Return the crossing distance between `lo` (above ground) and `hi` (below ground), per ray."""
        lo = np.array(lo, float)
        hi = np.array(hi, float)
        for _ in range(MARCH_BISECTIONS):
            mid = 0.5 * (lo + hi)
            p = o + mid[:, None] * d
            below = p[:, 2] < self.height(p[:, 0], p[:, 1])
            hi = np.where(below, mid, hi)
            lo = np.where(below, lo, mid)
        return 0.5 * (lo + hi)
