# SPDX-License-Identifier: Apache-2.0
"""Ray casting of a fish-eye view: radiance per band, ground-truth sky mask and depth per pixel.

A renderer shades only the bands its camera needs: ultraviolet and green for the UV/green pair, red, green
and blue for a colour camera (skynav_sim.sky).

Each pixel centre inside the image circle is cast as one ray through the
camera model; pixels on the sky/ground boundary get four more rays at the
centres of their quarters, so that the ground truth labels a pixel by the
majority of its area (five samples: docs/interfaces.md) and the radiance there is
the area average. Surfaces are Lambertian, lit by the sun
(with the shadows that objects cast on the ground) and by the sky.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from skynav_core.camera import EquidistantCamera

from .materials import BAND_RANGES, TEXTURE_SCALE, Surface
from .noise import FractalNoise
from .sky import BANDS, UV_GREEN, Sky

if TYPE_CHECKING:  # world.py builds on the robot, which builds on this module
    from .world import World

MAX_DISTANCE = 250.0  # m: rays that have hit nothing by then are sky, or far ground if they point down
PRIMITIVE_BLOCK = 48  # primitives culled per matrix product
SHADOW_EXTENT = 40.0  # m: half side of the ground region where cast shadows are computed
SHADOW_CELL = 0.1  # m
FAR_GROUND = Surface.SOIL  # what a downward ray that left the terrain is taken to hit
_TEXTURE = FractalNoise(seed=20170701, scale=1.0, octaves=3)
# A second texture moves a surface's colour within its ranges: where it is positive, red lies higher in its range
# and blue lower (warmer), where negative the other way (cooler), as patches of a lawn or a wall differ in hue.
_HUE_TEXTURE = FractalNoise(seed=20260621, scale=3.0, octaves=2)  # patches 3 feature sizes wide
HUE_VARIATION = 0.3  # share of a band's range the hue texture moves red and blue at most (opposite ways)
HUE_SHIFT = {'red': 1.0, 'blue': -1.0}  # direction each visible band moves with the hue texture


@dataclass
class CameraPose:
    """Pose of camera_link in map: position (m) and rotation taking camera_link vectors to map vectors."""

    position: np.ndarray  # (3,)
    rotation: Rotation

    @property
    def quaternion(self) -> np.ndarray:
        """Return the orientation as (x, y, z, w), as geometry_msgs/Quaternion orders it."""
        return self.rotation.as_quat()


@dataclass
class View:
    """One rendered frame."""

    radiance: dict[str, np.ndarray]  # band -> (H, W) float32 radiance, W m^-2 sr^-1 nm^-1; 0 outside the circle
    sky: np.ndarray  # (H, W) bool, sky by majority of the pixel's area; False outside the image circle
    depth: np.ndarray  # (H, W) float32 distance to the surface seen (m), inf for sky and outside
    inside: np.ndarray  # (H, W) bool, pixel centre inside the image circle

    @property
    def uv(self) -> np.ndarray:
        """Return the ultraviolet radiance (H, W)."""
        return self.radiance['uv']

    @property
    def green(self) -> np.ndarray:
        """Return the green radiance (H, W)."""
        return self.radiance['green']

    def rgb(self) -> np.ndarray:
        """Return the red, green and blue radiance as one (H, W, 3) float32 array."""
        return np.stack([self.radiance[band] for band in ('red', 'green', 'blue')], axis=-1)


class Renderer:
    """Renders views of one world through one camera, in the bands the camera sees."""

    def __init__(self, world: World, camera: EquidistantCamera, bands: tuple[str, ...] = UV_GREEN) -> None:
        """Prepare rays of every pixel; `bands` are those of skynav_sim.sky.BANDS to shade."""
        if unknown := [band for band in bands if band not in BANDS]:
            raise ValueError(f'unknown band {", ".join(unknown)} (known: {", ".join(BANDS)})')
        self.world = world
        self.camera = camera
        self.bands = tuple(bands)
        self.inside = camera.image_circle()
        self.pixels = np.argwhere(self.inside)  # (N, 2) rows v, u
        self.directions = camera.pixel_directions()[self.inside]
        # Quarter centres of a pixel as (du, dv); with the centre itself, five samples decide the majority.
        self.subpixel_offsets = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])
        self._shadow_maps: dict[tuple, ShadowMap] = {}

    def render(self, pose: CameraPose, sky: Sky) -> View:
        """Return the view from `pose` under `sky`."""
        shape = self.inside.shape
        origin = np.asarray(pose.position, float)
        directions = pose.rotation.apply(self.directions)
        shadows = self.shadow_map(sky)
        radiance, sky_hit, depth = self._shade(origin, directions, sky, shadows)

        label = np.zeros(shape, bool)
        label[self.inside] = sky_hit
        edges = _boundary(label) & self.inside
        if edges.any():
            edge_index = np.flatnonzero(edges[self.inside])
            rows_cols = self.pixels[edge_index]
            samples = rows_cols[:, None, ::-1] + self.subpixel_offsets[None]  # (E, S, 2) as (u, v)
            sub_directions = pose.rotation.apply(self.camera.unproject(samples.reshape(-1, 2)))
            sub_radiance, sub_sky, _ = self._shade(origin, sub_directions, sky, shadows)
            count = len(self.subpixel_offsets)
            for band in self.bands:
                radiance[band][edge_index] = (
                    radiance[band][edge_index] + sub_radiance[band].reshape(-1, count).sum(axis=1)
                ) / (count + 1)
            sky_hit[edge_index] = (sky_hit[edge_index] + sub_sky.reshape(-1, count).sum(axis=1)) > (count + 1) / 2

        def image(values: np.ndarray, fill: float) -> np.ndarray:
            out = np.full(shape, fill, np.float32)
            out[self.inside] = values
            return out

        mask = np.zeros(shape, bool)
        mask[self.inside] = sky_hit
        return View({band: image(radiance[band], 0.0) for band in self.bands}, mask, image(depth, np.inf), self.inside)

    def shadow_map(self, sky: Sky) -> ShadowMap | None:
        """Return the cached map of cast shadows on the ground for the sun of `sky` (None without sun)."""
        if sky.elevation <= 0 or self.world.backdrop is not None:
            return None
        key = tuple(np.round(sky.sun, 6))
        if key not in self._shadow_maps:
            self._shadow_maps[key] = ShadowMap(self.world, sky.sun)
        return self._shadow_maps[key]

    def _shade(
        self, origin: np.ndarray, directions: np.ndarray, sky: Sky, shadows: ShadowMap | None
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """Return radiance per band, whether each ray sees sky, and the distance to what it sees."""
        if self.world.backdrop is not None:
            return self.world.backdrop.shade(origin, directions, sky, self.bands)
        distance, primitive = trace(self.world, origin, directions)
        downward_escape = ~np.isfinite(distance) & (directions[:, 2] < 0)
        distance = np.where(downward_escape, MAX_DISTANCE, distance)
        sky_hit = ~np.isfinite(distance)
        radiance = {band: np.zeros(len(directions)) for band in self.bands}
        if sky_hit.any():
            clouds = sky.cloud_density(directions[sky_hit], origin)
            for band in self.bands:
                radiance[band][sky_hit] = sky.radiance(band, directions[sky_hit], origin, clouds)
        ground = ~sky_hit
        if ground.any():
            points = origin + distance[ground, None] * directions[ground]
            normals, materials = self._surface(points, primitive[ground], downward_escape[ground])
            lit = np.ones(len(points))
            on_terrain = primitive[ground] < 0
            if shadows is not None and on_terrain.any():
                lit[on_terrain] = shadows.lit(points[on_terrain])
            lit *= sky.sun_visibility(origin)
            texture = 0.5 + 0.5 * np.clip(
                _TEXTURE(
                    points[:, 0] / TEXTURE_SCALE[materials] + 0.37 * points[:, 2],
                    points[:, 1] / TEXTURE_SCALE[materials] - 0.61 * points[:, 2],
                )
                / 0.6,
                -1,
                1,
            )
            facing_sun = np.clip(normals @ sky.sun, 0.0, None) * lit
            sky_view = 0.5 * (1.0 + normals[:, 2])
            hue = None
            if any(band in HUE_SHIFT for band in self.bands):
                hue = np.clip(
                    _HUE_TEXTURE(
                        points[:, 0] / TEXTURE_SCALE[materials] - 0.53 * points[:, 2],
                        points[:, 1] / TEXTURE_SCALE[materials] + 0.29 * points[:, 2],
                    )
                    / 0.6,
                    -1,
                    1,
                )
            for band in self.bands:
                low, high = BAND_RANGES[band][materials, 0], BAND_RANGES[band][materials, 1]
                shade = texture
                if hue is not None and band in HUE_SHIFT:
                    shade = np.clip(texture + HUE_VARIATION * HUE_SHIFT[band] * hue, 0.0, 1.0)
                albedo = low + (high - low) * shade
                irradiance = sky.direct[band] * facing_sun + sky.diffuse[band] * sky_view
                radiance[band][ground] = albedo * irradiance / np.pi
        return radiance, sky_hit, distance

    def _surface(
        self, points: np.ndarray, primitive: np.ndarray, far_ground: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return unit normals and Surface indices at hit points (primitive index, -1 = terrain)."""
        normals = np.empty_like(points)
        materials = np.empty(len(points), np.int64)
        terrain = primitive < 0
        normals[terrain] = self.world.terrain.normal(points[terrain, 0], points[terrain, 1])
        materials[terrain] = self.world.terrain.material(points[terrain, 0], points[terrain, 1])
        normals[far_ground] = (0.0, 0.0, 1.0)
        materials[far_ground] = FAR_GROUND
        on_objects = np.flatnonzero(~terrain)
        order = on_objects[np.argsort(primitive[on_objects], kind='stable')]
        indices, starts = np.unique(primitive[order], return_index=True)
        for index, rows in zip(indices, np.split(order, starts[1:])):
            shape = self.world.primitives[index]
            normals[rows] = shape.normal(points[rows])
            materials[rows] = shape.material
        return normals, materials


def _cone_candidates(origin: np.ndarray, centers: np.ndarray, radii: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Return (spheres, rays) bool: which rays from `origin` may meet each bounding sphere (all, if inside it)."""
    to_centers = centers - origin
    distance = np.linalg.norm(to_centers, axis=1)
    axes = (to_centers / distance[:, None]).astype(np.float32)
    cos_cone = np.cos(np.arcsin(np.clip(radii / distance, 0, 1)))
    cos_cone = np.where(distance <= radii, -1.0, cos_cone).astype(np.float32)
    return (axes @ directions.T) >= cos_cone[:, None]


def trace(world: World, origin: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return, per ray from `origin`, the distance to the first surface (inf: none) and its primitive (-1: terrain).

    Objects are culled by their bounding spheres first, their primitives only among the object's rays.
    """
    distance = np.full(len(directions), np.inf)
    primitive = np.full(len(directions), -1)
    directions32 = directions.astype(np.float32)
    # Objects nearest first: a ray that already hit something closer than an object's bounding sphere
    # need not be tested against it.
    reach = np.linalg.norm(world.group_centers - origin, axis=1) - world.group_radii
    near = np.flatnonzero(reach < MAX_DISTANCE)
    near = near[np.argsort(reach[near])]
    for start in range(0, len(near), PRIMITIVE_BLOCK):
        block = near[start : start + PRIMITIVE_BLOCK]
        candidates = _cone_candidates(origin, world.group_centers[block], world.group_radii[block], directions32)
        for row, group in enumerate(block):
            group_rays = np.flatnonzero(candidates[row])
            group_rays = group_rays[distance[group_rays] > reach[group]]
            if not group_rays.size:
                continue
            members = world.groups[group]
            member_candidates = _cone_candidates(
                origin, world.centers[members], world.radii[members], directions32[group_rays]
            )
            for member_row, index in enumerate(members):
                rays = group_rays[member_candidates[member_row]]
                if not rays.size:
                    continue
                t = world.primitives[index].intersect(np.broadcast_to(origin, (rays.size, 3)), directions[rays])
                closer = t < distance[rays]
                distance[rays[closer]] = t[closer]
                primitive[rays[closer]] = index
    # The terrain, only for rays below its horizon and only up to the object each ray already hit.
    rays = np.flatnonzero(world.terrain.may_hit(origin, directions, MAX_DISTANCE))
    if rays.size:
        contact = world.terrain.first_contact(origin, directions[rays])
        t = world.terrain.intersect(origin, directions[rays], np.minimum(distance[rays], MAX_DISTANCE), contact)
        closer = t < distance[rays]
        distance[rays[closer]] = t[closer]
        primitive[rays[closer]] = -1
    return distance, primitive


def _boundary(label: np.ndarray) -> np.ndarray:
    """Return the pixels whose 8-neighbourhood holds both labels."""
    padded = np.pad(label, 1, mode='edge')
    neighbours = [
        padded[1 + dv : padded.shape[0] - 1 + dv, 1 + du : padded.shape[1] - 1 + du]
        for dv in (-1, 0, 1)
        for du in (-1, 0, 1)
    ]
    stack = np.stack(neighbours)
    return np.any(stack, axis=0) & ~np.all(stack, axis=0)


class ShadowMap:
    """Which ground points near the yard lie in the shadow an object casts, for one sun direction."""

    def __init__(self, world: World, sun: np.ndarray) -> None:
        n = int(round(2 * SHADOW_EXTENT / SHADOW_CELL)) + 1
        axis = np.linspace(-SHADOW_EXTENT, SHADOW_EXTENT, n)
        x, y = np.meshgrid(axis, axis)
        z = world.terrain.height(x, y)
        self.lit_grid = np.ones((n, n), bool)
        self.n = n
        # Each primitive's shadow: the ground cells whose ray toward the sun passes its bounding sphere.
        for primitive, center, radius in zip(world.primitives, world.centers, world.radii):
            reach = max(center[2] + radius - min(z.min(), center[2] - radius), 0.0)
            lo = np.minimum(center[:2] - radius, center[:2] - radius - sun[:2] / max(sun[2], 0.05) * reach)
            hi = np.maximum(center[:2] + radius, center[:2] + radius - sun[:2] / max(sun[2], 0.05) * reach)
            i0, j0 = np.floor((lo + SHADOW_EXTENT) / SHADOW_CELL).astype(int)
            i1, j1 = np.ceil((hi + SHADOW_EXTENT) / SHADOW_CELL).astype(int)
            i0, j0, i1, j1 = max(i0, 0), max(j0, 0), min(i1, n - 1), min(j1, n - 1)
            if i0 > i1 or j0 > j1:
                continue
            points = np.stack(
                [x[j0 : j1 + 1, i0 : i1 + 1], y[j0 : j1 + 1, i0 : i1 + 1], z[j0 : j1 + 1, i0 : i1 + 1] + 1e-3], axis=-1
            ).reshape(-1, 3)
            # Bounding-sphere test first: distance from the centre to each shadow ray.
            w = center - points
            along = w @ sun
            near = (along > -radius) & (np.einsum('ij,ij->i', w, w) - along**2 <= radius**2)
            if not near.any():
                continue
            t = primitive.intersect(points[near], np.broadcast_to(sun, (int(near.sum()), 3)))
            blocked = np.zeros(len(points), bool)
            blocked[np.flatnonzero(near)[np.isfinite(t)]] = True
            self.lit_grid[j0 : j1 + 1, i0 : i1 + 1] &= ~blocked.reshape(j1 - j0 + 1, i1 - i0 + 1)

    def lit(self, points: np.ndarray) -> np.ndarray:
        """Return 1 where ground points (N, 3) are in sunlight, 0 in a cast shadow (outside the map: lit)."""
        i = np.round((points[:, 0] + SHADOW_EXTENT) / SHADOW_CELL).astype(int)
        j = np.round((points[:, 1] + SHADOW_EXTENT) / SHADOW_CELL).astype(int)
        inside = (i >= 0) & (i < self.n) & (j >= 0) & (j < self.n)
        lit = np.ones(len(points))
        lit[inside] = self.lit_grid[j[inside], i[inside]]
        return lit
