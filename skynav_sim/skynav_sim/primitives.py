# SPDX-License-Identifier: Apache-2.0
"""Solid primitives of the world and vectorised ray intersection with them.

Every primitive answers, for a batch of rays (origins (N, 3), unit directions
(N, 3)), the distance to its first surface in front of the origin (inf when
missed) and the outward unit normal at a point on its surface. Each has a
bounding sphere (bounding_center, bounding_radius) so that a renderer can skip
it for rays that pass far away.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Hits closer than this to the ray origin are ignored (m); keeps shadow rays off their own surface.
SELF_HIT_EPSILON = 1e-4


@dataclass
class Ellipsoid:
    """Axis-aligned (after a yaw about z) ellipsoid: tree crowns, bushes, boulders."""

    center: np.ndarray  # (3,) m
    radii: np.ndarray  # (3,) semi-axes along the yawed x, y and z (m)
    yaw: float  # rotation about z (rad)
    material: int

    def __post_init__(self) -> None:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        self._to_local = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        self.bounding_center = self.center
        self.bounding_radius = float(np.max(self.radii))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Return the distance to the surface along each ray (inf when missed)."""
        o = ((origins - self.center) @ self._to_local.T) / self.radii
        d = (directions @ self._to_local.T) / self.radii
        a = np.einsum('ij,ij->i', d, d)
        b = np.einsum('ij,ij->i', o, d)
        c = np.einsum('ij,ij->i', o, o) - 1.0
        disc = b * b - a * c
        root = np.sqrt(np.maximum(disc, 0.0))
        near = (-b - root) / a
        far = (-b + root) / a
        t = np.where(near > SELF_HIT_EPSILON, near, far)
        return np.where((disc >= 0) & (t > SELF_HIT_EPSILON), t, np.inf)

    def normal(self, points: np.ndarray) -> np.ndarray:
        """Return the outward unit normal at surface points (N, 3)."""
        local = ((points - self.center) @ self._to_local.T) / self.radii**2
        n = local @ self._to_local
        return n / np.linalg.norm(n, axis=-1, keepdims=True)


@dataclass
class Cylinder:
    """Vertical finite cylinder: tree trunks, posts."""

    center: np.ndarray  # (3,) centre of the base disc (m)
    radius: float  # m
    height: float  # m
    material: int

    def __post_init__(self) -> None:
        self.bounding_center = self.center + np.array([0.0, 0.0, self.height / 2])
        self.bounding_radius = float(np.hypot(self.radius, self.height / 2))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Return the distance to the mantle or top disc along each ray (inf when missed)."""
        o = origins - self.center
        dxy = directions[:, :2]
        a = np.einsum('ij,ij->i', dxy, dxy)
        b = np.einsum('ij,ij->i', o[:, :2], dxy)
        c = np.einsum('ij,ij->i', o[:, :2], o[:, :2]) - self.radius**2
        disc = b * b - a * c
        with np.errstate(divide='ignore', invalid='ignore'):
            root = np.sqrt(np.maximum(disc, 0.0))
            candidates = []
            for t in ((-b - root) / a, (-b + root) / a):
                z = o[:, 2] + t * directions[:, 2]
                candidates.append(
                    np.where((disc >= 0) & (t > SELF_HIT_EPSILON) & (z >= 0) & (z <= self.height), t, np.inf)
                )
            t_top = (self.height - o[:, 2]) / directions[:, 2]
            p = o[:, :2] + t_top[:, None] * dxy
            on_top = (t_top > SELF_HIT_EPSILON) & (np.einsum('ij,ij->i', p, p) <= self.radius**2)
            candidates.append(np.where(on_top, t_top, np.inf))
        return np.min(candidates, axis=0)

    def normal(self, points: np.ndarray) -> np.ndarray:
        """Return the outward unit normal at surface points (N, 3)."""
        local = points - self.center
        radial = np.concatenate([local[:, :2], np.zeros((len(points), 1))], axis=1)
        radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-12)
        on_top = local[:, 2] > self.height - 1e-6
        return np.where(on_top[:, None], np.array([0.0, 0.0, 1.0]), radial)


@dataclass
class ConvexPolytope:
    """Intersection of half-spaces n_k . x <= h_k: boxes (walls, fences, buildings) and gable roofs."""

    normals: np.ndarray  # (P, 3) outward unit normals
    offsets: np.ndarray  # (P,) m
    corners: np.ndarray  # (V, 3) its vertices, for the bounding sphere and drawing
    material: int

    def __post_init__(self) -> None:
        self.bounding_center = self.corners.mean(axis=0)
        self.bounding_radius = float(np.max(np.linalg.norm(self.corners - self.bounding_center, axis=1)))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Return the distance to the surface along each ray (slab method; inf when missed)."""
        denominators = directions @ self.normals.T  # (N, P)
        numerators = self.offsets - origins @ self.normals.T
        with np.errstate(divide='ignore', invalid='ignore'):
            t = numerators / denominators
        entering = denominators < 0
        exiting = denominators > 0
        parallel_outside = (denominators == 0) & (numerators < 0)
        t_enter = np.max(np.where(entering, t, -np.inf), axis=1)
        t_exit = np.min(np.where(exiting, t, np.inf), axis=1)
        t_hit = np.where(t_enter > SELF_HIT_EPSILON, t_enter, t_exit)
        valid = (t_enter <= t_exit) & (t_hit > SELF_HIT_EPSILON) & ~parallel_outside.any(axis=1)
        return np.where(valid, t_hit, np.inf)

    def normal(self, points: np.ndarray) -> np.ndarray:
        """Return the normal of the face each surface point lies on (N, 3)."""
        distance = points @ self.normals.T - self.offsets
        return self.normals[np.argmax(distance, axis=1)]

    @classmethod
    def box(cls, center: np.ndarray, half_sizes: np.ndarray, yaw: float, material: int) -> ConvexPolytope:
        """Return a box with the given centre, half side lengths (m) along its yawed axes, and yaw (rad)."""
        c, s = np.cos(yaw), np.sin(yaw)
        axes = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        normals = np.concatenate([axes, -axes])
        offsets = normals @ center + np.concatenate([half_sizes, half_sizes])
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing='ij')).reshape(3, -1).T
        corners = center + (signs * half_sizes) @ axes
        return cls(normals, offsets, corners, material)

    @classmethod
    def gable_roof(
        cls, center: np.ndarray, half_length: float, half_width: float, height: float, yaw: float, material: int
    ) -> ConvexPolytope:
        """Return a triangular prism roof: ridge along the yawed x axis, eaves at centre z, ridge `height` above."""
        c, s = np.cos(yaw), np.sin(yaw)
        ex, ey, ez = np.array([c, s, 0.0]), np.array([-s, c, 0.0]), np.array([0.0, 0.0, 1.0])
        slope = np.array([height, half_width])
        side = slope / np.linalg.norm(slope)
        normals = np.array([ex, -ex, -ez, side[0] * ey + side[1] * ez, -side[0] * ey + side[1] * ez])
        corners = np.array(
            [center + sx * half_length * ex + sy * half_width * ey for sx in (-1, 1) for sy in (-1, 1)]
            + [center + sx * half_length * ex + height * ez for sx in (-1, 1)]
        )
        eave = center + half_width * ey
        offsets = np.array(
            [
                ex @ center + half_length,
                -ex @ center + half_length,
                -ez @ center,
                normals[3] @ eave,
                normals[4] @ (center - half_width * ey),
            ]
        )
        return cls(normals, offsets, corners, material)


Primitive = Ellipsoid | Cylinder | ConvexPolytope
