# SPDX-License-Identifier: Apache-2.0
"""Outdoor worlds generated from a seed: terrain, vegetation, buildings, walls, fences, rocks; or a real landscape.

Frame `map`: x east, y north, z up, metres. Every world has a drivable yard
around the origin (radius YARD_RADIUS) where routes and homing grids are laid
out; objects stand inside it sparsely and around it densely, so the skyline
seen from the yard has near and far structure.

A landscape world (LANDSCAPES: a photographed Stellarium panorama, see
landscape.py) has no objects: a lawn with bumps to drive on, and the real
landscape on a backdrop around the yard, which the renderer shows instead of
terrain and objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from skynav_sim.errors import SimError

from .landscape import Backdrop, load
from .materials import Surface
from .names import LANDSCAPES, STYLES, WORLDS
from .noise import FractalNoise
from .primitives import ConvexPolytope, Cylinder, Ellipsoid, Primitive
from .terrain import Terrain

YARD_RADIUS = 10.0  # m: where the robot drives
TERRAIN_EXTENT = 120.0  # m: half side of the terrain grid
TERRAIN_CELL = 0.25  # m
CLEARANCE = 0.7  # m: free space the robot keeps from any object footprint
BODY_RADIUS = 0.35  # m: the mower's body (its bumper) reaches this far from its centre
BOUNDARY_WIRE = YARD_RADIUS + 0.5  # m from the yard's centre: the mower's boundary wire stops it beyond this


@dataclass(frozen=True)
class StyleParameters:
    """What distinguishes one world style from another."""

    hill_amplitude: float  # m, large-scale relief
    hill_scale: float  # m, feature size of the relief
    bumps: int  # small bumps in the yard that tilt the robot
    bump_amplitude: tuple[float, float]  # m
    bump_radius: tuple[float, float]  # m (Gaussian sigma)
    ground: Surface
    patches: tuple[tuple[Surface, float], ...]  # (material, share of the ground it covers)
    trees: int
    far_trees: int
    bushes: int
    buildings: int
    walls: int
    fences: int
    hedges: int
    rocks: int
    rock_materials: tuple[Surface, ...]
    wall_materials: tuple[Surface, ...]
    trunk_height: tuple[float, float]  # m, ground to crown
    crown_radius: tuple[float, float]  # m
    building_distance: tuple[float, float]  # m from the yard centre
    building_height: tuple[float, float]  # m, walls (a roof adds 1.5-3.5 m)


STYLE_PARAMETERS = {
    'garden': StyleParameters(
        hill_amplitude=0.8,
        hill_scale=40.0,
        bumps=60,
        bump_amplitude=(0.08, 0.30),
        bump_radius=(0.6, 1.4),
        ground=Surface.GRASS,
        patches=((Surface.GRAVEL, 0.08), (Surface.LIMESTONE, 0.05), (Surface.SOIL, 0.05)),
        trees=8,
        far_trees=25,
        bushes=10,
        buildings=4,
        walls=2,
        fences=6,
        hedges=3,
        rocks=2,
        rock_materials=(Surface.GRANITE,),
        wall_materials=(Surface.BRICK, Surface.LIME_PLASTER, Surface.CONCRETE),
        trunk_height=(2.0, 5.0),
        crown_radius=(1.5, 3.5),
        building_distance=(YARD_RADIUS + 4, 24.0),
        building_height=(4.5, 8.0),
    ),
    'park': StyleParameters(
        hill_amplitude=2.5,
        hill_scale=35.0,
        bumps=70,
        bump_amplitude=(0.10, 0.35),
        bump_radius=(0.6, 1.5),
        ground=Surface.GRASS,
        patches=((Surface.DRY_GRASS, 0.25), (Surface.GRAVEL, 0.06), (Surface.SOIL, 0.04)),
        trees=16,
        far_trees=70,
        bushes=12,
        buildings=2,
        walls=0,
        fences=0,
        hedges=2,
        rocks=3,
        rock_materials=(Surface.GRANITE, Surface.LIMESTONE),
        wall_materials=(Surface.BRICK,),
        trunk_height=(3.0, 8.0),
        crown_radius=(2.5, 5.0),
        building_distance=(30.0, 45.0),
        building_height=(5.0, 10.0),
    ),
    'mineral': StyleParameters(
        hill_amplitude=1.5,
        hill_scale=25.0,
        bumps=110,
        bump_amplitude=(0.12, 0.45),
        bump_radius=(0.5, 1.2),
        ground=Surface.SAND,
        patches=((Surface.GRAVEL, 0.25), (Surface.LIMESTONE, 0.20), (Surface.DRY_GRASS, 0.06)),
        trees=3,
        far_trees=12,
        bushes=5,
        buildings=2,
        walls=4,
        fences=1,
        hedges=0,
        rocks=35,
        rock_materials=(Surface.LIMESTONE, Surface.GRANITE, Surface.LIMESTONE),
        wall_materials=(Surface.LIMESTONE, Surface.CONCRETE, Surface.LIME_PLASTER),
        trunk_height=(1.5, 3.5),
        crown_radius=(1.0, 2.5),
        building_distance=(YARD_RADIUS + 5, 22.0),
        building_height=(3.0, 6.0),
    ),
}

#: The ground of a landscape world: a lawn with the garden's bumps and no relief (the landscape shows the rest).
LAWN = StyleParameters(
    hill_amplitude=0.0,
    hill_scale=40.0,
    bumps=60,
    bump_amplitude=(0.08, 0.30),
    bump_radius=(0.6, 1.4),
    ground=Surface.GRASS,
    patches=(),
    trees=0,
    far_trees=0,
    bushes=0,
    buildings=0,
    walls=0,
    fences=0,
    hedges=0,
    rocks=0,
    rock_materials=(),
    wall_materials=(),
    trunk_height=(0.0, 0.0),
    crown_radius=(0.0, 0.0),
    building_distance=(0.0, 0.0),
    building_height=(0.0, 0.0),
)


@dataclass
class Footprint:
    """Ground outline of an object for free-space planning and the top view: a disc or a rotated rectangle."""

    center: np.ndarray  # (2,) m
    half_sizes: np.ndarray  # (2,) m; equal for a disc
    yaw: float
    disc: bool
    kind: str  # 'tree', 'bush', 'building', 'wall', 'fence', 'hedge', 'rock'
    canopy: float = 0.0  # m, radius of a tree's crown (drawn in top views; the robot drives under it)


@dataclass
class World:
    """Terrain plus solid objects, generated from (style, seed)."""

    style: str
    seed: int
    terrain: Terrain
    primitives: list[Primitive]
    footprints: list[Footprint]
    groups: list[np.ndarray]  # primitive indices of each object (a tree: trunk and crown lumps)
    free: np.ndarray = field(repr=False)  # (n, n) bool, drivable grid over [-YARD_RADIUS, YARD_RADIUS]^2
    free_cell: float = TERRAIN_CELL
    backdrop: Backdrop | None = None  # a real landscape seen instead of terrain and objects (landscape worlds)

    def __post_init__(self) -> None:
        self.centers = np.array([p.bounding_center for p in self.primitives]).reshape(-1, 3)
        self.radii = np.array([p.bounding_radius for p in self.primitives], float)
        # A bounding sphere per object, enclosing its primitives' spheres.
        self.group_centers = np.array([self.centers[g].mean(axis=0) for g in self.groups]).reshape(-1, 3)
        self.group_radii = np.array(
            [
                np.max(np.linalg.norm(self.centers[g] - c, axis=1) + self.radii[g])
                for g, c in zip(self.groups, self.group_centers)
            ],
            float,
        )

    def collides(self, x: float, y: float) -> bool:
        """Return whether the mower at (x, y) (m) touches an object with its body or is beyond the boundary wire.

        Routes are planned with CLEARANCE to spare (is_free); the bumper only hits at BODY_RADIUS.
        """
        if math.hypot(x, y) > BOUNDARY_WIRE:
            return True
        for f in self.footprints:
            dx, dy = x - f.center[0], y - f.center[1]
            if f.disc:
                outside = math.hypot(dx, dy) - f.half_sizes[0]
            else:
                c, s = math.cos(f.yaw), math.sin(f.yaw)
                u, v = abs(c * dx + s * dy), abs(-s * dx + c * dy)
                outside = math.hypot(max(u - f.half_sizes[0], 0.0), max(v - f.half_sizes[1], 0.0))
            if outside < BODY_RADIUS:
                return True
        return False

    def is_free(self, x: npt.ArrayLike, y: npt.ArrayLike) -> np.ndarray:
        """Return whether the robot may stand at world points (x, y)."""
        n = self.free.shape[0]
        i = np.round((np.asarray(x) + YARD_RADIUS) / self.free_cell).astype(int)
        j = np.round((np.asarray(y) + YARD_RADIUS) / self.free_cell).astype(int)
        inside = (i >= 0) & (i < n) & (j >= 0) & (j < n)
        return inside & self.free[np.clip(j, 0, n - 1), np.clip(i, 0, n - 1)]


def generate(style: str, seed: int) -> World:
    """Return the world of a style or landscape (WORLDS) for a seed; equal inputs give equal worlds.

    A landscape is fetched on first use (landscape.LandscapeUnavailable says why it could not be).
    """
    if style in LANDSCAPES:
        rng = np.random.default_rng([seed, len(STYLES) + LANDSCAPES.index(style)])
        return World(style, seed, _terrain(LAWN, rng), [], [], [], _free_space([]), backdrop=Backdrop(load(style)))
    if style not in STYLE_PARAMETERS:
        raise SimError(f'unknown world style {style!r} (known: {", ".join(WORLDS)})')
    params = STYLE_PARAMETERS[style]
    rng = np.random.default_rng([seed, STYLES.index(style)])
    terrain = _terrain(params, rng)
    builder = _Builder(terrain, rng)
    builder.place_all(params)
    free = _free_space(builder.footprints)
    return World(style, seed, terrain, builder.primitives, builder.footprints, builder.groups, free)


def _terrain(params: StyleParameters, rng: np.random.Generator) -> Terrain:
    """Return the height field and ground materials of a style."""
    n = int(round(2 * TERRAIN_EXTENT / TERRAIN_CELL)) + 1
    axis = np.linspace(-TERRAIN_EXTENT, TERRAIN_EXTENT, n)
    x, y = np.meshgrid(axis, axis)
    hills = FractalNoise(int(rng.integers(2**31)), params.hill_scale, octaves=3)
    heights = params.hill_amplitude * hills(x, y)
    # Bumps where the robot drives: these tilt it by 10-30 degrees.
    centers = rng.uniform(-YARD_RADIUS - 2, YARD_RADIUS + 2, (params.bumps, 2))
    amplitudes = rng.uniform(*params.bump_amplitude, params.bumps) * rng.choice([-1, 1], params.bumps, p=[0.3, 0.7])
    sigmas = rng.uniform(*params.bump_radius, params.bumps)
    near = (np.abs(x) < YARD_RADIUS + 8) & (np.abs(y) < YARD_RADIUS + 8)
    xs, ys = x[near], y[near]
    bumps = np.zeros(xs.shape)
    for (cx, cy), a, s in zip(centers, amplitudes, sigmas):
        bumps += a * np.exp(-((xs - cx) ** 2 + (ys - cy) ** 2) / (2 * s * s))
    heights[near] += bumps
    heights -= heights[n // 2, n // 2]
    materials = np.full((n, n), params.ground, dtype=np.uint8)
    for surface, share in params.patches:
        patch = FractalNoise(int(rng.integers(2**31)), scale=rng.uniform(6, 14), octaves=3)(x, y)
        materials[patch > np.quantile(patch[near], 1 - share)] = surface
    return Terrain(heights, materials, TERRAIN_EXTENT)


class _Builder:
    """Places the objects of a world, keeping each one's footprint clear of the others."""

    def __init__(self, terrain: Terrain, rng: np.random.Generator) -> None:
        self.terrain = terrain
        self.rng = rng
        self.primitives: list[Primitive] = []
        self.footprints: list[Footprint] = []
        self.groups: list[np.ndarray] = []

    def add_footprint(self, footprint: Footprint) -> None:
        """Close the object being built: its primitives since the last footprint form one group."""
        first = int(self.groups[-1][-1]) + 1 if self.groups else 0
        self.groups.append(np.arange(first, len(self.primitives)))
        self.footprints.append(footprint)

    def ground(self, x: float, y: float) -> float:
        return float(self.terrain.height(np.array(x), np.array(y)))

    def spot(self, r_min: float, r_max: float, radius: float, tries: int = 60) -> np.ndarray | None:
        """Return a point at a distance in [r_min, r_max] from the origin whose disc of `radius` is free."""
        for _ in range(tries):
            r = np.sqrt(self.rng.uniform(r_min**2, r_max**2))
            a = self.rng.uniform(0, 2 * np.pi)
            p = np.array([r * np.cos(a), r * np.sin(a)])
            if all(np.linalg.norm(p - f.center) > radius + max(f.half_sizes) for f in self.footprints):
                return p
        return None

    def place_all(self, params: StyleParameters) -> None:
        rng = self.rng
        for _ in range(params.buildings):
            self.building(rng.uniform(*params.building_distance), params)
        for _ in range(params.walls):
            self.wall(rng.uniform(YARD_RADIUS + 1, YARD_RADIUS + 6), rng.choice(params.wall_materials))
        for _ in range(params.fences):
            self.fence(rng.uniform(YARD_RADIUS + 1, YARD_RADIUS + 4))
        for _ in range(params.hedges):
            self.hedge(rng.uniform(YARD_RADIUS + 0.5, YARD_RADIUS + 5))
        for i in range(params.trees):
            # A third of the near trees stand inside the yard, the rest around it.
            inside = i % 3 == 0
            self.tree(
                0.4 * YARD_RADIUS if inside else YARD_RADIUS + 1, YARD_RADIUS if inside else YARD_RADIUS + 12, params
            )
        for _ in range(params.far_trees):
            self.tree(YARD_RADIUS + 12, 75, params)
        for i in range(params.bushes):
            inside = i % 2 == 0
            self.bush(0.3 * YARD_RADIUS if inside else YARD_RADIUS, YARD_RADIUS if inside else YARD_RADIUS + 8)
        for i in range(params.rocks):
            inside = i % 2 == 0
            self.rock(
                0.2 * YARD_RADIUS if inside else YARD_RADIUS,
                YARD_RADIUS if inside else YARD_RADIUS + 15,
                rng.choice(params.rock_materials),
                big=not inside,
            )

    def tree(self, r_min: float, r_max: float, params: StyleParameters) -> None:
        rng = self.rng
        crown = rng.uniform(*params.crown_radius)
        p = self.spot(r_min, r_max, 0.6 * crown)
        if p is None:
            return
        z = self.ground(*p)
        trunk_height = rng.uniform(*params.trunk_height)
        trunk_radius = rng.uniform(0.08, 0.3)
        self.primitives.append(
            Cylinder(np.array([p[0], p[1], z - 0.3]), trunk_radius, trunk_height + 0.3 + crown * 0.5, Surface.BARK)
        )
        top = np.array([p[0], p[1], z + trunk_height + crown * 0.8])
        # A crown of several lumps gives a ragged outline against the sky, as real foliage does.
        for _ in range(int(rng.integers(5, 9))):
            offset = rng.normal(0, 0.45 * crown, 3) * np.array([1.0, 1.0, 0.6])
            radii = crown * rng.uniform(0.45, 0.8, 3) * np.array([1.0, 1.0, rng.uniform(0.7, 1.1)])
            self.primitives.append(Ellipsoid(top + offset, radii, rng.uniform(0, np.pi), Surface.FOLIAGE))
        self.add_footprint(Footprint(p, np.array([trunk_radius, trunk_radius]) + 0.05, 0.0, True, 'tree', crown))

    def bush(self, r_min: float, r_max: float) -> None:
        rng = self.rng
        size = rng.uniform(0.4, 1.2)
        p = self.spot(r_min, r_max, size)
        if p is None:
            return
        z = self.ground(*p)
        for _ in range(int(rng.integers(1, 4))):
            offset = np.append(rng.normal(0, 0.3 * size, 2), 0.0)
            radii = size * rng.uniform(0.6, 1.0, 3) * np.array([1.0, 1.0, 0.8])
            self.primitives.append(
                Ellipsoid(
                    np.array([p[0], p[1], z + 0.6 * radii[2]]) + offset, radii, rng.uniform(0, np.pi), Surface.HEDGE
                )
            )
        self.add_footprint(Footprint(p, np.array([size, size]) * 1.2, 0.0, True, 'bush'))

    def rock(self, r_min: float, r_max: float, material: Surface, big: bool) -> None:
        rng = self.rng
        size = rng.uniform(0.5, 1.6) if big else rng.uniform(0.2, 0.6)
        p = self.spot(r_min, r_max, size)
        if p is None:
            return
        radii = size * rng.uniform(0.6, 1.0, 3) * np.array([1.0, 1.0, rng.uniform(0.5, 0.9)])
        z = self.ground(*p) + radii[2] * rng.uniform(-0.3, 0.3)
        self.primitives.append(Ellipsoid(np.array([p[0], p[1], z]), radii, rng.uniform(0, np.pi), material))
        self.add_footprint(Footprint(p, radii[:2].max() * np.ones(2), 0.0, True, 'rock'))

    def _segment(self, r_min: float, r_max: float, length: float, thickness: float) -> tuple[np.ndarray, float] | None:
        """Return centre and yaw of a straight element tangent to a circle around the yard, if free."""
        for _ in range(40):
            r = self.rng.uniform(r_min, r_max)
            a = self.rng.uniform(0, 2 * np.pi)
            center = np.array([r * np.cos(a), r * np.sin(a)])
            yaw = a + np.pi / 2
            half = np.array([length / 2, thickness / 2])
            if self._rectangle_free(center, half, yaw):
                return center, yaw
        return None

    def _rectangle_free(self, center: np.ndarray, half: np.ndarray, yaw: float) -> bool:
        c, s = np.cos(yaw), np.sin(yaw)
        samples = np.stack(np.meshgrid(np.linspace(-1, 1, 9), np.linspace(-1, 1, 3)), -1).reshape(-1, 2) * half
        points = center + samples @ np.array([[c, s], [-s, c]])
        for f in self.footprints:
            if np.min(np.linalg.norm(points - f.center, axis=1)) < max(f.half_sizes) + 0.3:
                return False
        return True

    def _box_on_ground(self, center: np.ndarray, half: np.ndarray, height: float, yaw: float, material: int) -> float:
        """Add a box standing on the terrain (its base below the lowest ground point); return its top z."""
        c, s = np.cos(yaw), np.sin(yaw)
        corners = center + np.array([[sx * half[0], sy * half[1]] for sx in (-1, 1) for sy in (-1, 1)]) @ np.array(
            [[c, s], [-s, c]]
        )
        base = min(self.ground(*q) for q in corners) - 0.2
        top = max(self.ground(*q) for q in corners) + height
        middle = np.array([center[0], center[1], (base + top) / 2])
        self.primitives.append(
            ConvexPolytope.box(middle, np.array([half[0], half[1], (top - base) / 2]), yaw, material)
        )
        return top

    def building(self, distance: float, params: StyleParameters) -> None:
        rng = self.rng
        length, width = rng.uniform(6, 12), rng.uniform(5, 9)
        placed = self._segment(distance, distance + 4, length, width)
        if placed is None:
            return
        center, yaw = placed
        half = np.array([length / 2, width / 2])
        material = rng.choice([Surface.BRICK, Surface.LIME_PLASTER, Surface.CONCRETE])
        top = self._box_on_ground(center, half, rng.uniform(*params.building_height), yaw, material)
        roof = ConvexPolytope.gable_roof(
            np.array([center[0], center[1], top]),
            half[0] + 0.3,
            half[1] + 0.4,
            rng.uniform(1.5, 3.5),
            yaw,
            Surface.ROOF_TILE,
        )
        self.primitives.append(roof)
        self.add_footprint(Footprint(center, half, yaw, False, 'building'))

    def wall(self, distance: float, material: Surface) -> None:
        length, thickness = self.rng.uniform(4, 12), self.rng.uniform(0.2, 0.45)
        placed = self._segment(distance, distance + 1, length, thickness)
        if placed is None:
            return
        center, yaw = placed
        half = np.array([length / 2, thickness / 2])
        self._box_on_ground(center, half, self.rng.uniform(1.0, 2.4), yaw, material)
        self.add_footprint(Footprint(center, half, yaw, False, 'wall'))

    def fence(self, distance: float) -> None:
        length = self.rng.uniform(4, 10)
        placed = self._segment(distance, distance + 1, length, 0.05)
        if placed is None:
            return
        center, yaw = placed
        height = self.rng.uniform(1.0, 1.8)
        half = np.array([length / 2, 0.025])
        self._box_on_ground(center, half, height, yaw, Surface.WOOD)
        direction = np.array([np.cos(yaw), np.sin(yaw)])
        for k in np.linspace(-0.5, 0.5, max(2, int(length / 2.5) + 1)):
            post = center + k * length * direction
            z = self.ground(*post)
            self.primitives.append(Cylinder(np.array([post[0], post[1], z - 0.2]), 0.06, height + 0.35, Surface.WOOD))
        self.add_footprint(Footprint(center, half + 0.06, yaw, False, 'fence'))

    def hedge(self, distance: float) -> None:
        length, thickness = self.rng.uniform(5, 12), self.rng.uniform(0.6, 1.2)
        placed = self._segment(distance, distance + 1, length, thickness)
        if placed is None:
            return
        center, yaw = placed
        half = np.array([length / 2, thickness / 2])
        self._box_on_ground(center, half, self.rng.uniform(1.2, 2.2), yaw, Surface.HEDGE)
        self.add_footprint(Footprint(center, half, yaw, False, 'hedge'))


def _free_space(footprints: list[Footprint]) -> np.ndarray:
    """Return the drivable grid over the yard: inside YARD_RADIUS and CLEARANCE away from every footprint."""
    n = int(round(2 * YARD_RADIUS / TERRAIN_CELL)) + 1
    axis = np.linspace(-YARD_RADIUS, YARD_RADIUS, n)
    x, y = np.meshgrid(axis, axis)
    free = np.hypot(x, y) <= YARD_RADIUS
    for f in footprints:
        c, s = np.cos(f.yaw), np.sin(f.yaw)
        dx, dy = x - f.center[0], y - f.center[1]
        if f.disc:
            free &= np.hypot(dx, dy) > f.half_sizes[0] + CLEARANCE
        else:
            u, v = np.abs(c * dx + s * dy), np.abs(-s * dx + c * dy)
            outside = np.hypot(np.maximum(u - f.half_sizes[0], 0), np.maximum(v - f.half_sizes[1], 0))
            free &= outside > CLEARANCE
    return free
