# SPDX-License-Identifier: Apache-2.0
"""3D-warping in the SH basis: the home vector from the current view to a snapshot's place, for any tilt.

Model (equal-distance assumption): every scene point lies at one distance rho from the current camera. Had the
camera moved by t (in the current camera_link), it would see the current view f_c translated by tau = t / rho,
translate(f_c, tau) (skynav_sh: g(normalise(d - tau)) = f(d)); turned by the rotation R (d_snapshot = R d_current)
that is the snapshot: f_s ~ rotate(translate(f_c, tau), R). The camera must move from the current place to the
snapshot's, so tau points along the home vector: home = tau / |tau| = Q_c^-1 (p_s - p_c) normalised. (A view moved
along +x of camera_link therefore homes along -x; the tests check it.)
A hypothesis is (direction u of tau on the sphere, distance ratio |tau| = |t| / rho, rotation R); its cost is the
masked mean squared difference of prediction and snapshot where both see (views.WarpView terms).

Search:
0. Start rotation R0: the given compass estimate, or without one a rotational pre-alignment (no translation) over
   a cap of tilts and a whole turn of yaw (align_rotation). A ground robot's physics bounds every rotation of the
   search: none tilts the camera further than settings.max_relative_tilt against the snapshot (a compass estimate
   beyond it is not used; the local search never steps beyond it). With a compass estimate the pre-alignment runs too
   (settings.check_compass): where the two disagree by more than the yaw window, both start the coarse search and
   the best hypotheses of either go on, so a compass that took a translated view for a turned one (a yaw flipped
   by half a turn, say) cannot lock the search onto a wrong rotation.
1. Coarse, at a low degree: directions on rings of equal azimuth step delta around the camera's horizontal plane (a
   ground robot moves near it; tilt makes it 3D), a few distance ratios, and yaw corrections q delta about the
   current +z, R = R0 Rz(q delta), within a window. Both views are turned into each direction's frame (u onto +z,
   where T_z acts per order m); a yaw correction then only shifts the azimuth index, so the costs of all
   (direction, yaw) pairs of one ring and ratio are one matrix product.
2. Local, at the full degree: the best few coarse hypotheses (two steps apart at least) are refined by a pattern
   search over direction (2 DoF), ratio (an index on a fine geometric grid) and rotation (small turns about the
   current x, y, z), all moves of a step costed in one batch; after a few steps only the best one goes on.
3. Reference: the best rotation with no translation, refined alongside and then once more, finer, from the best
   hypothesis's rotation. With its cost D0 and the best cost D, confidence = 1 - D / D0: under a pure rotation a
   translation explains nothing, and the result says so (no confident home vector). A best cost at or below zero
   (a mean squared difference never is: the band limit's ringing, where the views share next to nothing) gives
   confidence 0 too.
4. Direction: the best step turned about the current z into the other half of the plane (OPPOSITE_TURNS: 90 to
   270 degrees away), at its length and rotation. The largest share of the best step's cost reduction D0 - D that
   such a step explains is `opposite_share`: well below 0 where the views determine the direction (a step the other
   way makes the prediction worse than standing still), near 1 or above where they do not (a flat residual over
   directions: a step any way explains about as much). A home vector is confident only when the translation
   explains enough (confidence >= confidence_threshold) and its direction is determined (opposite_share below
   max_opposite_share); both tests are relative to the pair of views at hand.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from skynav_core.rotations import MAX_TILT, rotation_angle, within_tilt, yaw_matrix, zyz_angles
from skynav_sh.basis import DEFAULT_DEGREE, degree_order, n_coefficients
from skynav_sh.rotation import (
    apply_sparse,
    quarter_turn_sparse,
    rotate,
    z_phases,
    z_rotation_factors,
    z_rotation_index,
)
from skynav_sh.translation import z_translation_blocks
from skynav_warping.errors import WarpingError
from skynav_warping.shbatch import rotate_columns, rotate_zyz_columns
from skynav_warping.views import WarpView

#: Turns (rad) about the current z of the best step that test its direction: into the other half of the plane.
OPPOSITE_TURNS = np.radians(np.arange(90.0, 270.1, 15.0))
SMALLEST_RATIO = 0.015  # |t| / rho of the shortest step hypothesised: no home vector is confident nearer home
RATIO_STEPS = 18  # ratios on the geometric grid from SMALLEST_RATIO, a factor 2^(1/3) apart (up to 0.76)


def default_ratios() -> tuple[float, ...]:
    """Return the fine distance-ratio grid |t| / rho: 0 (no translation), then geometric 0.015 .. 0.76 (x1.26)."""
    return (0.0,) + tuple(float(x) for x in SMALLEST_RATIO * 2 ** (np.arange(RATIO_STEPS) / 3))


@dataclass(frozen=True)
class WarpingSettings:
    """Search settings of 3D-warping (angles in rad, ratios |t| / rho)."""

    degree: int = DEFAULT_DEGREE  # SH degree L of the local refinement and the reported cost
    coarse_degree: int = 10  # SH degree of the coarse search; at most `degree` (a lower `degree` lowers it too)
    azimuth_steps: int = 48  # coarse directions per ring = yaw corrections per turn (7.5 degrees)
    ring_elevations: tuple[float, ...] = tuple(np.radians([-20.0, -10.0, 0.0, 10.0, 20.0]))
    ratios: tuple[float, ...] = field(default_factory=default_ratios)  # fine grid; ratios[0] must be 0
    coarse_ratios: tuple[int, ...] = (6, 9, 12, 15)  # indices into ratios tried by the coarse search (0.05-0.38)
    yaw_window: float = np.radians(30.0)  # coarse yaw corrections +- this around the start rotation
    max_tilt: float = np.radians(35.0)  # without a given rotation: tilts tried by the pre-alignment, up to this
    max_relative_tilt: float = MAX_TILT  # no rotation of the search tilts the views further apart (the compass's)
    tilt_step: float = np.radians(5.0)  # their spacing
    candidates: int = 3  # coarse hypotheses refined locally
    race_iterations: int = 3  # after these pattern-search steps only the best translating hypothesis goes on
    max_iterations: int = 30  # pattern-search steps
    min_step: float = np.radians(1.0)  # the pattern search stops below this step
    confidence_threshold: float = 0.03  # least relative cost reduction by a translation for a confident vector
    # most of the best step's cost reduction a step turned 90 degrees or more away may explain for a confident vector:
    # past half, the other half of the plane explains the views about as well (the direction is not determined)
    max_opposite_share: float = 0.5
    check_compass: bool = True  # with a start rotation, also search from the own pre-alignment where they disagree

    def __post_init__(self) -> None:
        """Search coarsely at no higher degree than the views are compared at (their terms end at `degree`)."""
        object.__setattr__(self, 'coarse_degree', min(self.coarse_degree, self.degree))


@dataclass(frozen=True)
class WarpResult:
    """A 3D-warping estimate: home vector in the current camera_link, rotation, costs."""

    direction: np.ndarray  # unit home vector (current camera_link); zeros when not confident
    best_direction: np.ndarray  # the optimum's direction, also when not confident
    rotation: np.ndarray  # 3x3 R with d_snapshot = R d_current
    distance_ratio: float  # |t| / rho of the optimum
    residual: float  # masked mean squared difference at the optimum (view units^2)
    residual_no_translation: float  # the same for the best pure rotation
    confidence: float  # 1 - residual / residual_no_translation, in [0, 1]
    confident: bool  # confidence >= the settings' threshold and opposite_share below the settings' bound
    evaluations: int  # hypotheses costed
    start_rotation: np.ndarray  # R0 the best hypothesis started from (the compass estimate, or the pre-alignment)
    # largest share of the best step's cost reduction explained by the step turned 90-270 degrees about z (inf when
    # no step reduces the cost: no direction at all)
    opposite_share: float = np.inf


class DegreeTables:
    """Per-degree tables: quarter turns, order indices and T_z blocks of every distance ratio."""

    def __init__(self, degree: int, ratios: tuple[float, ...], used: tuple[int, ...] | None = None) -> None:
        """Precompute the T_z blocks of the used ratios (default all) at this degree (skynav_sh caches them too)."""

        self.degree = L = int(degree)
        self.n = n_coefficients(L)
        self.forward, self.backward = quarter_turn_sparse(L)
        _, m = degree_order(L)
        # per |m|: flat indices of orders +m and -m (degrees |m|..L), shape (2, L + 1 - |m|); one row for m = 0
        self.order_index = [np.flatnonzero(m == 0)[None]] + [
            np.stack([np.flatnonzero(m == k), np.flatnonzero(m == -k)]) for k in range(1, L + 1)
        ]
        self.blocks = [
            z_translation_blocks(L, float(r)) if r > 0 and (used is None or i in used) else None
            for i, r in enumerate(ratios)
        ]
        # T_z of every ratio also as one stack of per-order blocks, each zero-padded to (L + 1, L + 1): the few
        # columns per ratio that the local search has go through one batched product of 2 L + 1 small blocks
        # (a twentieth of the multiplications of the (n, n) matrix they form, and 76 kB per ratio instead of 670 kB
        # at L = 16, which keeps every ratio's table in cache). Rows of order m (m = 0, 1, -1, 2, -2, ...) in
        # `gather` (index n: a zero row), and each coefficient's row of the stacked result in `scatter`.
        orders = [index for pair in self.order_index for index in pair]
        self.gather = np.full((len(orders), L + 1), self.n)
        self.scatter = np.empty(self.n, dtype=int)
        for b, index in enumerate(orders):
            self.gather[b, : len(index)] = index
            self.scatter[index] = b * (L + 1) + np.arange(len(index))
        self.padded: list[np.ndarray | None] = [None if b is None else self._padded(b) for b in self.blocks]

    def _padded(self, blocks: tuple[np.ndarray, ...]) -> np.ndarray:
        """Return the per-order blocks (one per row of order_index) zero-padded to (2 L + 1, L + 1, L + 1)."""
        size = self.degree + 1
        stack = np.zeros((len(self.gather), size, size))
        b = 0
        for index, block in zip(self.order_index, blocks):
            for _ in index:
                stack[b, : len(block), : len(block)] = block
                b += 1
        stack.flags.writeable = False
        return stack

    def translate_z(self, c: np.ndarray, ratio_index: int) -> np.ndarray:
        """Return c (n, ...) stepped along +z by the ratio of that index (T_z per order m; index 0: unchanged)."""
        blocks = self.blocks[ratio_index]
        if blocks is None:
            return c
        out = np.empty_like(c)
        rest = c.shape[1:]
        for index, block in zip(self.order_index, blocks):
            part = c[index].reshape(index.shape[0], index.shape[1], -1)
            out[index] = np.matmul(block, part).reshape(index.shape + rest)
        return out

    def translate_z_columns(self, c: np.ndarray, ratio_indices: np.ndarray) -> np.ndarray:
        """Return c (n, k, M) with column i stepped along +z by the ratio of ratio_indices[i] (index 0: unchanged)."""
        out = c.copy()
        for index in np.unique(ratio_indices):
            if index == 0:
                continue
            columns = np.flatnonzero(ratio_indices == index)
            part = c[..., columns]
            flat = np.empty((self.n + 1, part[0].size))
            flat[: self.n] = part.reshape(self.n, -1)
            flat[self.n] = 0.0
            blocks = self.padded[int(index)]
            assert blocks is not None  # a ratio the tables were built for
            stacked = np.matmul(blocks, flat[self.gather])  # (2 L + 1, L + 1, columns)
            out[..., columns] = stacked.reshape(-1, flat.shape[1])[self.scatter].reshape(part.shape)
        return out


class WarpingTables:
    """Tables of one WarpingSettings, built once: both degrees, the coarse rings' z-factors."""

    def __init__(self, settings: WarpingSettings) -> None:
        """Precompute translation blocks at both degrees and the coarse grid's rotation factors."""
        if settings.ratios[0] != 0.0:
            raise WarpingError('ratios[0] must be 0 (the no-translation reference)')
        self.settings = settings
        self.ratios = np.asarray(settings.ratios, dtype=float)
        self.fine = DegreeTables(settings.degree, settings.ratios)
        self.coarse = DegreeTables(settings.coarse_degree, settings.ratios, settings.coarse_ratios)
        self.step = 2 * np.pi / settings.azimuth_steps  # rad
        self.azimuths = self.step * np.arange(settings.azimuth_steps)
        self.polar = np.pi / 2 - np.asarray(settings.ring_elevations, dtype=float)
        L = settings.coarse_degree
        self.azimuth_cos, self.azimuth_sin, self.partner = z_rotation_factors(L, -self.azimuths)  # (n, n_az)
        self.ring_cos, self.ring_sin, _ = z_rotation_factors(L, -self.polar)  # (n, n_rings)
        self.yaw = self.step * np.where(
            np.arange(settings.azimuth_steps) > settings.azimuth_steps // 2,
            np.arange(settings.azimuth_steps) - settings.azimuth_steps,
            np.arange(settings.azimuth_steps),
        )  # rad, in (-pi, pi]
        sin_polar = np.sin(self.polar)[:, None]
        self.ring_directions = np.stack(
            np.broadcast_arrays(
                sin_polar * np.cos(self.azimuths),
                sin_polar * np.sin(self.azimuths),
                np.cos(self.polar)[:, None] + 0 * self.azimuths,
            ),
            -1,
        )  # (n_rings, n_az, 3), current camera_link
        cap = min(settings.max_tilt, settings.max_relative_tilt)
        self.tilts = tilt_hypotheses(cap, settings.tilt_step)  # (K, 3, 3)


def tilt_hypotheses(max_tilt: float, step: float) -> np.ndarray:
    """Return turns T (K, 3, 3) about horizontal axes taking +z to a near-uniform cap of points within max_tilt."""
    cap_area = 2 * np.pi * (1 - np.cos(max_tilt))
    count = max(1, int(round(cap_area / step**2)))
    k = np.arange(count) + 0.5
    z = 1 - k / count * (1 - np.cos(max_tilt))  # Fibonacci points, equal area in cos(theta)
    azimuth = np.pi * (1 + 5**0.5) * k
    tilt = np.arccos(z)
    axis_azimuth = azimuth + np.pi / 2  # the horizontal axis z x p
    c, s_ = np.cos(tilt), np.sin(tilt)
    ux, uy = np.cos(axis_azimuth), np.sin(axis_azimuth)
    turns = np.empty((count + 1, 3, 3))
    turns[0] = np.eye(3)
    # Rodrigues for a unit axis (ux, uy, 0)
    turns[1:, 0] = np.stack([c + ux * ux * (1 - c), ux * uy * (1 - c), uy * s_], -1)
    turns[1:, 1] = np.stack([ux * uy * (1 - c), c + uy * uy * (1 - c), -ux * s_], -1)
    turns[1:, 2] = np.stack([-uy * s_, ux * s_, c], -1)
    return turns


@lru_cache(maxsize=8)
def warping_tables(settings: WarpingSettings) -> WarpingTables:
    """Return the cached tables of these settings."""
    return WarpingTables(settings)


#: Least overlap (integral of v_p v_s) of a hypothesis, as a share of the snapshot's own (integral of v_s^2).
#: The terms are band-limited, so where prediction and snapshot hardly overlap (a step that moves the whole view
#: off the snapshot's cap) their ringing dominates both integrals and the cost can even come out negative; such a
#: hypothesis compares next to nothing and is refused. The optima on the bundled synthetic grids, level and bumpy,
#: keep 0.82 of it or more.
MIN_OVERLAP_SHARE = 0.25


def _overlap_floor(snapshot: np.ndarray) -> float:
    """Return the least overlap a hypothesis needs against the snapshot's terms (3, n) (MIN_OVERLAP_SHARE)."""
    return MIN_OVERLAP_SHARE * float(snapshot[0] @ snapshot[0])


def _costs(num: np.ndarray, den: np.ndarray, floor: float) -> np.ndarray:
    """Return num / den where the overlap den reaches `floor` (and is positive), +inf elsewhere."""
    good = den > max(floor, 1e-9)
    return np.where(good, num / np.where(good, den, 1.0), np.inf)


def _pair(c: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the term sums whose products give the masked squared difference and overlap, per hypothesis.

    c: current terms (n, 3, ...) after the warp, b: snapshot terms (n, 3, ...) in the same frame; returns (left, b)
    with left = [X2, -2 X1, X0] so that sum over (term, coefficient) of left * b = integral v_p v_s (p - s)^2.
    """
    # integral v_p v_s (p - s)^2 = <X2, S0> - 2 <X1, S1> + <X0, S2>; the overlap is <X0, S0>
    return np.stack([c[:, 2], -2.0 * c[:, 1], c[:, 0]], axis=1), b


def _ring_frames(tables: WarpingTables, stack: np.ndarray) -> np.ndarray:
    """Return Ry(-theta_i) Rz(-phi_j) stack for every ring i and azimuth j: stack (n, k) -> (n, k, rings, n_az)."""
    z = (
        tables.azimuth_cos[:, None] * stack[:, :, None]
        + tables.azimuth_sin[:, None] * stack[tables.partner][:, :, None]
    )  # Z(-phi_j)
    u = apply_sparse(tables.coarse.backward, z, axis=0)  # J^T, (n, k, n_az)
    y = (
        tables.ring_cos[:, None, :, None] * u[:, :, None]
        + tables.ring_sin[:, None, :, None] * u[tables.partner][:, :, None]
    )  # Z(-theta_i)
    return apply_sparse(tables.coarse.forward, y, axis=0)  # J


def coarse_costs(
    tables: WarpingTables, current: np.ndarray, snapshot_turned: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return costs [ratio slot, ring, azimuth j, yaw q] and no-translation costs [q] on the coarse grid.

    current: terms (3, n) of the current view; snapshot_turned: the snapshot's terms turned by R0^T into the
    current camera_link; both at the coarse degree. Yaw slot q means R = R0 Rz(tables.yaw[q]).
    """
    frames = _ring_frames(tables, np.concatenate([current, snapshot_turned]).T)  # (n, 6, rings, n_az)
    a, b = frames[:, :3], frames[:, 3:]
    n, _, n_rings, n_az = a.shape
    shift = (np.arange(n_az)[:, None] + np.arange(n_az)[None, :]) % n_az  # [j, q] -> j + q
    right = np.ascontiguousarray(b.transpose(2, 1, 0, 3)).reshape(n_rings, 3 * n, n_az)  # (rings, 3n, n_az)
    b0 = right[:, :n]
    floor = _overlap_floor(snapshot_turned)
    costs = []
    for index in tables.settings.coarse_ratios:
        c = tables.coarse.translate_z(a, index)
        left, _ = _pair(c, b)
        left = np.ascontiguousarray(left.transpose(2, 3, 1, 0)).reshape(n_rings, n_az, 3 * n)
        num = left @ right
        den = left[..., 2 * n :] @ b0
        costs.append(np.take_along_axis(_costs(num, den, floor), shift[None], axis=-1))
    # no translation: the same for every direction; one azimuth of the first ring suffices
    left0 = _pair(a[..., 0, :1], b)[0].transpose(2, 1, 0).reshape(1, 3 * n)
    still = _costs(left0 @ right[0], left0[:, 2 * n :] @ b0[0], floor)[0]
    return np.stack(costs), still


def _direction_frames(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return polar angle, azimuth (rad) and R_u = Rz(phi) Ry(theta) (turns +z onto u) of unit vectors (M, 3)."""
    theta = np.arctan2(np.hypot(directions[:, 0], directions[:, 1]), directions[:, 2])
    phi = np.arctan2(directions[:, 1], directions[:, 0])
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(phi), np.sin(phi)
    r = np.empty((len(theta), 3, 3))
    r[:, 0] = np.stack([cp * ct, -sp, cp * st], -1)
    r[:, 1] = np.stack([sp * ct, cp, sp * st], -1)
    r[:, 2] = np.stack([-st, np.zeros_like(st), ct], -1)
    return theta, phi, r


def hypothesis_costs(
    tables: DegreeTables,
    current: np.ndarray,
    snapshot: np.ndarray,
    directions: np.ndarray,
    ratio_indices: np.ndarray,
    rotations: np.ndarray,
) -> np.ndarray:
    """Return the masked costs of hypotheses: unit directions (M, 3), ratio indices (M,), rotations (M, 3, 3).

    current, snapshot: terms (3, n) in their own camera_link; the prediction is rotate(translate(current, tau), R).
    """
    m = len(directions)
    rows = np.arange(m)
    return paired_costs(
        tables,
        current,
        snapshot,
        np.asarray(directions, dtype=float),
        rows,
        np.asarray(ratio_indices, dtype=int),
        rows,
        np.asarray(rotations, dtype=float),
        rows,
        rows,
    )


def paired_costs(
    tables: DegreeTables,
    current: np.ndarray,
    snapshot: np.ndarray,
    directions: np.ndarray,
    warp_direction: np.ndarray,
    warp_ratio: np.ndarray,
    turn_direction: np.ndarray,
    turn_rotation: np.ndarray,
    warp_of: np.ndarray,
    turn_of: np.ndarray,
) -> np.ndarray:
    """Return masked costs of hypotheses that share work: each pairs one warped current view with one turned snapshot.

    directions (P, 3): distinct unit directions (current camera_link); warps: (direction index, ratio index) per
    warped current view; turns: (direction index, rotation (3, 3)) per turned snapshot; hypothesis h compares warp
    warp_of[h] with turn turn_of[h]. Both sides are taken into the direction's frame (u onto +z), where T_z acts.
    """
    p = len(directions)
    theta, phi, frame = _direction_frames(directions)
    # one batch of rotations: the current view by R_u^T for every direction, the snapshot by R_u^T R^T per turn
    alpha, beta, gamma = zyz_angles(np.swapaxes(frame[turn_direction], 1, 2) @ np.swapaxes(turn_rotation, 1, 2))
    n_turns = len(turn_rotation)
    stack = np.concatenate(
        [
            np.broadcast_to(current.T[:, :, None], (tables.n, 3, p)),
            np.broadcast_to(snapshot.T[:, :, None], (tables.n, 3, n_turns)),
        ],
        axis=-1,
    )
    turned = rotate_zyz_columns(
        stack, np.concatenate([np.zeros(p), alpha]), np.concatenate([-theta, beta]), np.concatenate([-phi, gamma])
    )
    warped = tables.translate_z_columns(turned[..., warp_direction], warp_ratio)
    left, right = _pair(warped[..., warp_of], turned[..., p:][..., turn_of])
    return _costs(
        np.einsum('ktm,ktm->m', left, right), np.einsum('km,km->m', left[:, 2], right[:, 0]), _overlap_floor(snapshot)
    )


def _axis_turns(angle: float) -> np.ndarray:
    """Return the six turns by +-angle (rad) about x, y and z, (6, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    out = []
    for t in (s, -s):
        out += [
            [[1, 0, 0], [0, c, -t], [0, t, c]],
            [[c, 0, t], [0, 1, 0], [-t, 0, c]],
            [[c, -t, 0], [t, c, 0], [0, 0, 1]],
        ]
    return np.array(out, dtype=float)


def _tangent_basis(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return two unit vectors orthogonal to the unit vector u and to each other."""
    x, y, z = u
    if abs(z) < 0.9:  # e1 = normalise(z_axis x u), e2 = u x e1
        e1 = np.array([-y, x, 0.0]) / np.hypot(x, y)
    else:
        e1 = np.array([0.0, -z, y]) / np.hypot(y, z)
    e2 = np.array([y * e1[2] - z * e1[1], z * e1[0] - x * e1[2], x * e1[1] - y * e1[0]])
    return e1, e2


@dataclass
class Hypothesis:
    """One hypothesis under local refinement (direction in the current camera_link, ratio index, R, cost)."""

    direction: np.ndarray
    ratio: int
    rotation: np.ndarray
    cost: float
    step: float  # rad
    translate: bool = True  # False: rotation only, ratio 0 (the no-translation reference)
    done: bool = False
    start: np.ndarray | None = None  # the start rotation R0 of the coarse search it came from


def refine(
    tables: DegreeTables,
    current: np.ndarray,
    snapshot: np.ndarray,
    hypotheses: list[Hypothesis],
    n_ratios: int,
    max_iterations: int,
    min_step: float,
    race_iterations: int | None = None,
    max_tilt: float | None = None,
) -> int:
    """Refine hypotheses in place by a pattern search, all moves of a step in one batch; return the costs spent.

    Moves of a hypothesis: its direction turned by +-step about two tangent axes, its ratio index +-1, its rotation
    followed by turns of +-step about the current x, y, z (none that tilts z further than max_tilt, rad); a
    hypothesis without translation turns only. After race_iterations steps only the best translating hypothesis
    (and those without translation) go on.
    """
    spent = 0
    for iteration in range(max_iterations):
        if race_iterations is not None and iteration == race_iterations:
            moving = [h for h in hypotheses if h.translate]
            for h in moving:
                h.done = h.done or h is not min(moving, key=lambda g: g.cost)
        active = [h for h in hypotheses if not h.done]
        if not active:
            break
        directions: list[np.ndarray] = []  # warp directions in the current camera_link
        warps: list[tuple[int, int]] = []  # (index into directions, ratio index)
        turns: list[tuple[int, np.ndarray]] = []  # (index into directions, rotation)
        pairs: list[tuple[int, int]] = []  # (index into warps, index into turns) of every cost to evaluate
        moves: list[tuple[Hypothesis, np.ndarray, int, np.ndarray]] = []  # (hypothesis, direction, ratio, rotation)
        for h in active:
            centre = len(directions)
            directions.append(h.direction)
            first_warp = len(warps)
            warps.append((centre, h.ratio))
            for rotation in h.rotation[None] @ _axis_turns(h.step):  # R exp(omega): turns in the current frame
                pairs.append((first_warp, len(turns)))
                turns.append((centre, rotation))
                moves.append((h, h.direction, h.ratio, rotation))
            if h.translate:
                e1, e2 = _tangent_basis(h.direction)
                for e in (e1, -e1, e2, -e2):
                    u = np.cos(h.step) * h.direction + np.sin(h.step) * e
                    pairs.append((len(warps), len(turns)))
                    warps.append((len(directions), h.ratio))
                    turns.append((len(directions), h.rotation))
                    directions.append(u)
                    moves.append((h, u, h.ratio, h.rotation))
                centre_turn = len(turns)
                turns.append((centre, h.rotation))
                for delta in (1, -1):
                    if 0 < h.ratio + delta < n_ratios:
                        pairs.append((len(warps), centre_turn))
                        warps.append((centre, h.ratio + delta))
                        moves.append((h, h.direction, h.ratio + delta, h.rotation))
        warp_direction, warp_ratio = (np.array(v) for v in zip(*warps))
        pair_warp, pair_turn = (np.array(v) for v in zip(*pairs))
        costs = paired_costs(
            tables,
            current,
            snapshot,
            np.array(directions),
            warp_direction,
            warp_ratio,
            np.array([t[0] for t in turns]),
            np.array([t[1] for t in turns]),
            pair_warp,
            pair_turn,
        )
        spent += len(costs)
        if max_tilt is not None:  # a turn beyond the tilt bound is no move
            costs = np.where([within_tilt(move[3], max_tilt) for move in moves], costs, np.inf)
        for h in active:
            rows = [i for i, move in enumerate(moves) if move[0] is h]
            best = rows[int(np.argmin(costs[rows]))]
            if costs[best] < h.cost:
                _, u, ratio, rotation = moves[best]
                h.direction, h.ratio, h.rotation = u / np.linalg.norm(u), int(ratio), rotation
                h.cost = float(costs[best])
            else:
                h.step *= 0.5
                h.done = h.step < min_step
    return spent


def align_rotation(
    tables: WarpingTables, current: np.ndarray, snapshot: np.ndarray, rotation: np.ndarray
) -> tuple[np.ndarray, float]:
    """Return the best pure rotation R = rotation T Rz(psi) over the tilt cap T and a turn of yaw psi, and its cost.

    current, snapshot: terms (3, n) at the coarse degree in their own camera_link; no translation (a rotational
    pre-alignment, like a visual compass, for when no compass estimate is given).
    """
    turns = rotation[None] @ tables.tilts  # R0 T, (K, 3, 3)
    c = rotate_columns(
        np.broadcast_to(snapshot.T[:, :, None], snapshot.T.shape + (len(turns),)), np.swapaxes(turns, 1, 2)
    )  # the snapshot turned by (R0 T)^T: (n, 3, K)
    # <a, Z(-psi) c> = sum over |m| of cos(|m| psi) P_|m| + sin(|m| psi) Q_|m| with
    # P = sum a_i c_i and Q = sum sign(m_i) a_i c_partner(i) over the indices of that |m|
    order, sign, partner = z_rotation_index(tables.coarse.degree)
    group = (order[None, :] == np.arange(tables.coarse.degree + 1)[:, None]).astype(float)  # (L + 1, n)
    left = np.stack([current[2], -2.0 * current[1], current[0]], axis=1)  # as _pair: [X2, -2 X1, X0] vs [S0, S1, S2]
    m_sign = -sign  # +1 for m > 0, -1 for m < 0 (0 for m = 0, whose partner is itself)
    m_sign[order == 0] = 0.0
    p_num = group @ np.einsum('it,itk->ik', left, c)
    q_num = group @ np.einsum('it,itk->ik', left * m_sign[:, None], c[partner])
    p_den = group @ (current[0][:, None] * c[:, 0])
    q_den = group @ ((current[0] * m_sign)[:, None] * c[partner, 0])
    cos, sin = z_phases(tables.coarse.degree, tables.azimuths)  # cos, sin(|m| psi): (L + 1, n_az)
    costs = _costs(p_num.T @ cos + q_num.T @ sin, p_den.T @ cos + q_den.T @ sin, _overlap_floor(snapshot))  # (K, n_az)
    k, q = np.unravel_index(np.argmin(costs), costs.shape)
    return turns[k] @ yaw_matrix(tables.azimuths[q]), float(costs[k, q])


def warp_home_vector(
    current: WarpView,
    snapshot: WarpView,
    rotation: np.ndarray | None = None,
    settings: WarpingSettings = WarpingSettings(),
    full_turn: bool | None = None,
) -> WarpResult:
    """Return the 3D-warping home vector (current camera_link) to the snapshot's place, the rotation R and costs.

    rotation: start R (d_snapshot = R d_current), e.g. a compass estimate, refined in the search; None: start from a
    rotational pre-alignment over tilt and a whole turn of yaw. full_turn: coarse yaw corrections over the whole
    turn instead of +- settings.yaw_window.
    """
    tables = warping_tables(settings)
    L, Lc = settings.degree, settings.coarse_degree
    if min(current.degree, snapshot.degree) < L:
        raise WarpingError(f"views of degree {min(current.degree, snapshot.degree)} < the settings' degree {L}")
    x, s = current.truncated(L).terms, snapshot.truncated(L).terms
    full = False if full_turn is None else bool(full_turn)
    nc = n_coefficients(Lc)
    starts = [] if rotation is None else [np.asarray(rotation, dtype=float)]
    starts = [r0 for r0 in starts if within_tilt(r0, settings.max_relative_tilt)]  # no camera turned over
    if not starts or settings.check_compass:
        aligned, _ = align_rotation(tables, x[:, :nc], s[:, :nc], np.eye(3))
        if not starts or rotation_angle(aligned, starts[0]) > settings.yaw_window:
            starts.append(aligned)
    hypotheses: list[Hypothesis] = []
    reference: Hypothesis | None = None
    evaluations = 0
    for r0 in starts:
        found, still_best, spent = _coarse_hypotheses(tables, x[:, :nc], s[:, :nc], r0, full)
        hypotheses += found
        evaluations += spent
        if reference is None or still_best.cost < reference.cost:
            reference = still_best
    assert reference is not None  # starts holds at least one rotation
    # the best coarse hypotheses of every start go on (each start's at least two steps apart); the race of the
    # local search soon leaves the best one
    everyone = hypotheses + [reference]
    start = hypothesis_costs(
        tables.fine,
        x,
        s,
        np.array([h.direction for h in everyone]),
        np.array([h.ratio for h in everyone]),
        np.array([h.rotation for h in everyone]),
    )
    for h, cost in zip(everyone, start):
        h.cost = float(cost)
    evaluations += len(start) + refine(
        tables.fine,
        x,
        s,
        everyone,
        len(tables.ratios),
        settings.max_iterations,
        settings.min_step,
        settings.race_iterations,
        settings.max_relative_tilt,
    )
    # the no-translation reference once more, from the best translating hypothesis's rotation and finer: a pure
    # rotation must not look like a step only because the reference stopped a fraction of a degree short (only
    # needed near the confidence threshold; far from it the decision stands)
    best_moving = min(hypotheses, key=lambda h: h.cost) if hypotheses else None
    if best_moving is not None and best_moving.cost > (1 - 3 * settings.confidence_threshold) * reference.cost:
        second = Hypothesis(
            np.array([0.0, 0.0, 1.0]),
            0,
            best_moving.rotation,
            np.inf,
            settings.min_step,
            translate=False,
            start=best_moving.start,
        )
        second.cost = float(
            hypothesis_costs(tables.fine, x, s, second.direction[None], np.array([0]), second.rotation[None])[0]
        )
        reference.done, reference.step = False, max(reference.step, settings.min_step)
        evaluations += 1 + refine(
            tables.fine,
            x,
            s,
            [reference, second],
            len(tables.ratios),
            settings.max_iterations,
            0.25 * settings.min_step,
            max_tilt=settings.max_relative_tilt,
        )
        reference = min([reference, second], key=lambda h: h.cost)
    best = min(hypotheses, key=lambda h: h.cost) if hypotheses else reference
    if reference.cost <= best.cost:  # no step explains the views better than a pure rotation
        best = Hypothesis(best.direction, 0, reference.rotation, reference.cost, 0.0, start=reference.start)
    assert best.start is not None  # every hypothesis carries the start rotation of its coarse search
    # views overlap, and the costs are comparisons: a mean squared difference is never below 0, so a cost at or below
    # it is the band limit's ringing (views that share too little, e.g. nearly all sky), whose ratio means nothing
    usable = np.isfinite(best.cost) and np.isfinite(reference.cost) and reference.cost > 0 and best.cost > 0
    confidence = float(np.clip(1.0 - best.cost / reference.cost, 0.0, 1.0)) if usable else 0.0
    opposite = np.inf
    if confidence > 0 and best.ratio > 0:
        opposite, spent = opposite_share(tables, x, s, best, reference.cost)
        evaluations += spent
    confident = bool(
        confidence >= settings.confidence_threshold and best.ratio > 0 and opposite < settings.max_opposite_share
    )
    return WarpResult(
        direction=best.direction.copy() if confident else np.zeros(3),
        best_direction=best.direction.copy(),
        rotation=np.array(best.rotation),
        distance_ratio=float(tables.ratios[best.ratio]),
        residual=float(best.cost),
        residual_no_translation=float(reference.cost),
        confidence=confidence,
        confident=confident,
        evaluations=int(evaluations),
        start_rotation=best.start,
        opposite_share=float(opposite),
    )


def opposite_share(
    tables: WarpingTables, current: np.ndarray, snapshot: np.ndarray, best: Hypothesis, still: float
) -> tuple[float, int]:
    """Return the largest share of the best hypothesis's cost reduction (still - best.cost, still: the best pure
    rotation's cost) that the same step turned by OPPOSITE_TURNS about the current z explains, and the costs spent.

    current, snapshot: terms (3, n) at the full degree; best.cost < still.
    """
    turned = np.array([yaw_matrix(angle) @ best.direction for angle in OPPOSITE_TURNS])
    costs = hypothesis_costs(
        tables.fine,
        current,
        snapshot,
        turned,
        np.full(len(turned), best.ratio),
        np.repeat(np.asarray(best.rotation, float)[None], len(turned), axis=0),
    )
    return float(np.max(still - costs) / (still - best.cost)), len(turned)


def _coarse_hypotheses(
    tables: WarpingTables, current: np.ndarray, snapshot: np.ndarray, r0: np.ndarray, full: bool
) -> tuple[list[Hypothesis], Hypothesis, int]:
    """Return the best coarse hypotheses from start rotation r0 and the best pure rotation, both with their coarse
    cost, and the number of costs spent; current, snapshot: terms (3, n) at the coarse degree."""

    settings = tables.settings
    costs, still = coarse_costs(tables, current, rotate(snapshot, r0.T))
    if not full:
        allowed = np.abs(tables.yaw) <= settings.yaw_window + 1e-9
        costs, still = np.where(allowed, costs, np.inf), np.where(allowed, still, np.inf)
    # best (ratio, yaw) per coarse direction; then the best directions at least two steps apart
    n_slots, n_rings, n_az, _ = costs.shape
    per_direction = costs.transpose(1, 2, 0, 3).reshape(n_rings, n_az, -1)
    best_cell = np.argmin(per_direction, axis=-1)
    best_cost = np.take_along_axis(per_direction, best_cell[..., None], -1)[..., 0]
    hypotheses: list[Hypothesis] = []
    for index in np.argsort(best_cost, axis=None):
        if len(hypotheses) >= settings.candidates or not np.isfinite(best_cost.flat[index]):
            break
        ring, j = np.unravel_index(index, best_cost.shape)
        u = tables.ring_directions[ring, j]
        if any(np.dot(u, h.direction) > np.cos(1.5 * tables.step) for h in hypotheses):
            continue
        slot, q = np.unravel_index(best_cell[ring, j], (n_slots, n_az))
        hypotheses.append(
            Hypothesis(
                u.copy(),
                settings.coarse_ratios[slot],
                r0 @ yaw_matrix(tables.yaw[q]),
                float(best_cost.flat[index]),
                0.5 * tables.step,
                start=r0,
            )
        )
    q0 = int(np.argmin(still))
    reference = Hypothesis(
        np.array([0.0, 0.0, 1.0]),
        0,
        r0 @ yaw_matrix(tables.yaw[q0]),
        float(still[q0]),
        0.5 * tables.step,
        translate=False,
        start=r0,
    )
    return hypotheses, reference, costs.size + still.size
