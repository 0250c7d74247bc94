# SPDX-License-Identifier: Apache-2.0
"""Compass costs as functions of SO(3) correlations, on an Euler grid and with derivatives at one rotation.

Every cost of a rotation R (d_snapshot = R d_current) is a formula in correlations c_k(R) = <a_k, D(R) b_k>
(a_k a function of the snapshot, b_k of the current view, D(R) b the current view turned by R):
* plain: integral over the sphere of (f_s - D(R) f_c)^2 = |f_s|^2 + |f_c|^2 - 2 <f_s, D(R) f_c> (value^2 sr);
  with illumination invariance both are first cut to c_00 = 0 and unit norm, so the cost is 2 - 2 <.,.> (in [0, 4]);
* masked: the mean of (f_s - f_c)^2 over the directions both views see (value^2), from four correlations
      [<v_s f_s^2, D v_c> - 2 <v_s f_s, D v_c f_c> + <v_s, D v_c f_c^2>] / <v_s, D v_c>;
  with illumination invariance 1 - rho, rho the correlation coefficient of f_s and f_c over that overlap
  (adds <v_s f_s, D v_c> and <v_s, D v_c f_c>), in [0, 2].
The formulas use only + - * / and sqrt, so the same code runs on grid arrays and on Jets (value, gradient and
Hessian with respect to the rotation vector w of R = R0 exp(w)).

Everything that depends on the snapshot alone (its padded and complex coefficients, which of them are zonal, and
the snapshot's derivative matrix for the Jets) lives in a PreparedSnapshot, built once by prepare_snapshot and
shared by every comparison against that snapshot; build_problem accepts it in place of the snapshot view. The
Jets use R0 exp(w) = exp(R0 w) R0: the derivatives are taken on the snapshot side, <exp(-U) a, D(R0) b> with
U = sum u_i G_i, u = R0 w, and turned into the rotation vector w by R0^T.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from skynav_compass.errors import CompassError
from skynav_compass.so3 import EulerGrid, complex_form, so3_correlation_cells, stacked_generators
from skynav_compass.views import CompassView
from skynav_sh.layouts import to_padded
from skynav_sh.rotation import rotate_degree_major
from skynav_sh.spectra import illumination_invariant

COSTS = ('masked', 'plain')


class Jet:
    """A scalar with its gradient (3,) and Hessian (3, 3) with respect to a rotation vector (second-order AD)."""

    __slots__ = ('value', 'grad', 'hess')

    def __init__(self, value: float, grad: np.ndarray, hess: np.ndarray) -> None:
        """Hold value, gradient and Hessian."""
        self.value, self.grad, self.hess = float(value), np.asarray(grad, float), np.asarray(hess, float)

    @staticmethod
    def _lift(other: Jet | float) -> Jet:
        return other if isinstance(other, Jet) else Jet(other, np.zeros(3), np.zeros((3, 3)))

    def __add__(self, other: Jet | float) -> Jet:
        other = Jet._lift(other)
        return Jet(self.value + other.value, self.grad + other.grad, self.hess + other.hess)

    __radd__ = __add__

    def __neg__(self) -> Jet:
        return Jet(-self.value, -self.grad, -self.hess)

    def __sub__(self, other: Jet | float) -> Jet:
        return self + (-Jet._lift(other))

    def __rsub__(self, other: Jet | float) -> Jet:
        return Jet._lift(other) - self

    def __mul__(self, other: Jet | float) -> Jet:
        other = Jet._lift(other)
        cross = np.outer(self.grad, other.grad)
        return Jet(
            self.value * other.value,
            self.value * other.grad + other.value * self.grad,
            self.value * other.hess + other.value * self.hess + cross + cross.T,
        )

    __rmul__ = __mul__

    def reciprocal(self) -> Jet:
        """Return 1 / self."""
        v = self.value
        return Jet(1.0 / v, -self.grad / v**2, -self.hess / v**2 + 2.0 * np.outer(self.grad, self.grad) / v**3)

    def __truediv__(self, other: Jet | float) -> Jet:
        if not isinstance(other, Jet):
            return Jet(self.value / other, self.grad / other, self.hess / other)
        q = self.value / other.value
        grad = (self.grad - q * other.grad) / other.value
        cross = np.outer(grad, other.grad)
        return Jet(q, grad, (self.hess - q * other.hess - cross - cross.T) / other.value)

    def __rtruediv__(self, other: Jet | float) -> Jet:
        return Jet._lift(other) * self.reciprocal()

    def sqrt(self) -> Jet:
        """Return the square root."""
        root = np.sqrt(self.value)
        hess = self.hess / (2 * root) - np.outer(self.grad, self.grad) / (4 * root**3)
        return Jet(root, self.grad / (2 * root), hess)


def _sqrt(x):
    """Return sqrt of an array or a Jet."""
    return x.sqrt() if isinstance(x, Jet) else np.sqrt(x)


def masked_mean_square(c: Sequence) -> object:
    """Return the masked cost from its two channels: squared-difference integral and overlap area."""
    return c[0] / c[1]


def masked_decorrelation(c: Sequence) -> object:
    """Return 1 - correlation coefficient over the overlap from the six masked channels (see build_problem)."""
    area, sum_s, sum_c = c[3], c[4], c[5]
    covariance = c[1] - sum_s * sum_c / area
    variance_s = c[0] - sum_s * sum_s / area
    variance_c = c[2] - sum_c * sum_c / area
    return 1.0 - covariance / _sqrt(variance_s * variance_c)


Channel = tuple[tuple[int, int, float], ...]  # terms (snapshot index, current index, weight) of one linear combination
PLAIN_CHANNELS: tuple[Channel, ...] = (((0, 0, 1.0),),)  # <f_s, D f_c>
# masked: a = (v_s f_s^2, v_s f_s, v_s), b = (v_c, v_c f_c, v_c f_c^2); the squared difference and the overlap area
MASKED_CHANNELS: tuple[Channel, ...] = (((0, 0, 1.0), (1, 1, -2.0), (2, 2, 1.0)), ((2, 0, 1.0),))
# masked, normalised: sum f_s^2, sum f_s f_c, sum f_c^2, area, sum f_s, sum f_c over the overlap
MASKED_NORMALISED_CHANNELS: tuple[Channel, ...] = (
    ((0, 0, 1.0),),
    ((1, 1, 1.0),),
    ((2, 2, 1.0),),
    ((2, 0, 1.0),),
    ((1, 0, 1.0),),
    ((2, 1, 1.0),),
)


@dataclass(eq=False)
class PreparedSnapshot:
    """The snapshot's side of a compass cost, built once (prepare_snapshot) and shared by every comparison.

    Holds the padded snapshot-side functions a of the cost kind and, built on first use and kept, their complex
    form, which of them are zonal, and per channel layout the matrix that turns a rotated current view into the
    channels' values and derivatives. Treat it as read-only.
    """

    kind: str  # 'masked' or 'plain'
    normalise: bool
    max_degree: int
    padded: np.ndarray  # (q, L+1, 2L+1) functions a of the snapshot
    area: float = 0.0  # masked: the solid angle the snapshot sees (sr)
    norm_square: float = 0.0  # plain: |a|^2
    _conjugate: np.ndarray | None = field(default=None, repr=False)
    _zonal: np.ndarray | None = field(default=None, repr=False)
    _jets: np.ndarray | None = field(default=None, repr=False)
    _matrices: dict = field(default_factory=dict, repr=False)
    memo: dict = field(default_factory=dict, repr=False)  # other snapshot-side arrays a method keeps, by its own keys

    def conjugate(self) -> np.ndarray:
        """Return conj(A_lm) of the snapshot's functions, (q, 2L+1, L+1) [m + L, l] complex: the correlation factor."""
        if self._conjugate is None:
            self._conjugate = np.ascontiguousarray(complex_form(self.padded).conj().transpose(0, 2, 1))
            self._conjugate.flags.writeable = False
        return self._conjugate

    def zonal(self) -> np.ndarray:
        """Return per snapshot function (q,) whether only its m = 0 coefficients are non-zero (to rounding)."""
        if self._zonal is None:
            self._zonal = _is_zonal(self.padded)
        return self._zonal

    def _jet_stack(self) -> np.ndarray:
        """Return a, -G_i a and (G_i G_j + G_j G_i) / 2 a of every snapshot function: (q, 13, L+1, 2L+1), cached.

        <a, exp(U) c> = <exp(-U) a, c> (the generators are antisymmetric), to second order in u.
        """
        if self._jets is None:
            shape = self.padded.shape
            q, n = shape[0], shape[1] * shape[2]
            flat = self.padded.reshape(q, n).T  # (n, q)
            stacked = stacked_generators(self.max_degree)  # (3n, n): G_x, G_y, G_z one above the other
            first = stacked @ flat  # (3n, q): rows i n + k hold (G_i a)_k
            second = (stacked @ first.reshape(3, n, q).transpose(1, 0, 2).reshape(n, 3 * q)).reshape(3, n, 3, q)
            second = 0.5 * (second + second.transpose(2, 1, 0, 3))  # [i, :, j] = (G_i G_j + G_j G_i) a / 2
            columns = np.concatenate(
                [flat[None], -first.reshape(3, n, q), second.transpose(0, 2, 1, 3).reshape(9, n, q)]
            )  # (13, n, q)
            self._jets = columns.transpose(2, 0, 1).reshape(q, 13, *shape[1:])
        return self._jets

    def channel_matrix(self, channels: tuple[Channel, ...], derivatives: bool) -> np.ndarray:
        """Return the (r n, channels k) matrix M with channel values (and derivatives) = vec(D(R) b) @ M, cached.

        vec(D(R) b) runs over the current-side functions turned by R laid out degree first, [l, function j, m + L]
        (skynav_sh.rotation.rotate_degree_major); r is the number of them the channels use, n = (L+1)(2L+1); k is 13
        with derivatives (value, gradient and Hessian in u of exp(u) R), else 1.
        """
        key = (channels, derivatives)
        cached = self._matrices.get(key)
        if cached is None:
            jets = self._jet_stack() if derivatives else self.padded[:, None]
            k, rows, columns = jets.shape[1:]
            r = 1 + max(j for channel in channels for _, j, _ in channel)
            combined = np.zeros((len(channels), r, k, rows, columns))
            for c, channel in enumerate(channels):
                for i, j, w in channel:
                    combined[c, j] += w * jets[i]
            cached = np.ascontiguousarray(combined.transpose(3, 1, 4, 0, 2).reshape(rows * r * columns, -1))
            cached.flags.writeable = False
            self._matrices[key] = cached
        return cached


def cost_channels(kind: str, normalise: bool) -> tuple[Channel, ...]:
    """Return the correlation channels of a cost kind ('masked' or 'plain')."""
    if kind == 'plain':
        return PLAIN_CHANNELS
    if kind != 'masked':
        raise CompassError(f'unknown cost {kind!r}; expected one of {COSTS}')
    return MASKED_NORMALISED_CHANNELS if normalise else MASKED_CHANNELS


def prepare_snapshot(
    snapshot: CompassView | np.ndarray | PreparedSnapshot,
    max_degree: int,
    kind: str = 'masked',
    normalise: bool = False,
) -> PreparedSnapshot:
    """Return the snapshot's side of a cost kind ('masked' or 'plain') at degree L (a PreparedSnapshot as it is)."""
    if isinstance(snapshot, PreparedSnapshot):
        if (snapshot.kind, snapshot.normalise, snapshot.max_degree) != (kind, bool(normalise), int(max_degree)):
            raise CompassError(
                f'the snapshot was prepared for the {snapshot.kind} cost (normalise '
                f'{snapshot.normalise}) at degree {snapshot.max_degree}, not for the {kind} cost '
                f'(normalise {bool(normalise)}) at degree {int(max_degree)}'
            )
        return snapshot
    if kind == 'plain':
        f_s = _plain_terms(snapshot)
        if normalise:
            f_s = illumination_invariant(f_s[: (max_degree + 1) ** 2])
        a = to_padded(f_s, max_degree)
        return PreparedSnapshot('plain', bool(normalise), int(max_degree), a[None], norm_square=float(np.sum(a * a)))
    if kind != 'masked':
        raise CompassError(f'unknown cost {kind!r}; expected one of {COSTS}')
    if not isinstance(snapshot, CompassView):
        raise TypeError('the masked cost needs CompassView inputs (v f, v f^2 and v)')
    # a = (v_s f_s^2, v_s f_s, v_s)
    a = to_padded(np.stack([snapshot.weighted_square, snapshot.weighted, snapshot.visibility]), max_degree)
    return PreparedSnapshot('masked', bool(normalise), int(max_degree), a, area=snapshot.area)


@dataclass
class CostProblem:
    """A snapshot and a current view prepared for one cost: padded terms, correlation channels and the formula.

    Channel k is the linear combination sum w <a_i, D(R) b_j> over its terms; the cost is formula(channels).
    The snapshot's side (`side`) may be shared with other problems against the same snapshot.
    """

    snapshot: np.ndarray  # (q, L+1, 2L+1) padded snapshot-side functions a
    current: np.ndarray  # (r, L+1, 2L+1) padded current-side functions b (turned by R)
    channels: tuple[Channel, ...]
    formula: Callable[[Sequence], Any]  # arrays in, arrays out; Jets in, a Jet out
    kind: str
    area_channel: int | None = None  # channel holding the overlap area (masked)
    min_area: float = 0.0  # sr; rotations whose overlap is smaller are rejected
    side: PreparedSnapshot | None = field(default=None, repr=False)
    _current_by_degree: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.side is None:
            L = self.snapshot.shape[-2] - 1
            self.side = PreparedSnapshot(self.kind, False, L, self.snapshot)

    @property
    def max_degree(self) -> int:
        """Return the SH degree L of the problem."""
        return self.snapshot.shape[-2] - 1

    def mask_invalid(self, values: Sequence, cost):
        """Return the cost with inf where it is not finite or the overlap is too small."""
        cost = np.where(np.isfinite(cost), cost, np.inf)
        if self.area_channel is not None:
            cost = np.where(values[self.area_channel] > self.min_area, cost, np.inf)
        return cost

    def grid_costs(self, grid: EulerGrid) -> np.ndarray:
        """Return the cost at every rotation of an Euler grid, (n_beta, n, n) [beta, alpha, gamma]; inf if invalid."""
        # a channel of zonal functions only (centred fish-eye visibilities) depends on beta alone:
        # sum_l a_l0 d^l_00(beta) b_l0, with d^l_00 = P_l(cos beta); the others go through the FFT
        L = self.max_degree
        assert self.side is not None  # set by __post_init__
        zonal_s, zonal_c = self.side.zonal(), _is_zonal(self.current)
        zonal = [all(zonal_s[i] and zonal_c[j] for i, j, _ in channel) for channel in self.channels]
        general = [channel for channel, z in zip(self.channels, zonal) if not z]
        correlated = iter(())
        if general:
            # spectrum of sum w <a_i, D b_j>: sum w conj(A_i,lm) B_j,ln for n >= 0 (see so3.correlation_products),
            # built per cell [m, n, l, channel] as so3_correlation_cells takes it
            conjugate = self.side.conjugate()  # (q, m, l)
            big_b = complex_form(self.current)[..., L:].transpose(0, 2, 1)  # (r, n, l), n >= 0 only
            products = np.empty((2 * L + 1, L + 1, L + 1, len(general)), dtype=complex)
            for k, channel in enumerate(general):
                out = products[..., k]
                (i, j, w), *rest = channel
                np.multiply((w * conjugate[i])[:, None, :], big_b[j][None, :, :], out=out)
                for i, j, w in rest:
                    out += (w * conjugate[i])[:, None, :] * big_b[j][None, :, :]
            correlated = iter(so3_correlation_cells(products, grid))
        legendre = grid.half_table()[L * (L + 1)] if any(zonal) else None  # cell (m, n) = (0, 0): (n_beta, L+1)
        values = []
        for channel, z in zip(self.channels, zonal):
            if z:
                per_degree = sum(w * self.snapshot[i, :, L] * self.current[j, :, L] for i, j, w in channel)
                values.append(np.broadcast_to((legendre @ per_degree)[:, None, None], grid.shape))
            else:
                values.append(next(correlated))
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.mask_invalid(values, self.formula(values))

    def _channel_values(self, rotation: np.ndarray, derivatives: bool) -> np.ndarray:
        """Return every channel's value (and 3 + 9 derivatives) at R (3x3, or K of them): (..., channels, 1 or 13)."""
        # <a, D(R exp w) b> = <a, D(exp(R w)) D(R) b> = <exp(-U) a, D(R) b>, U = sum u_i G_i, u = R w: the
        # derivatives in u come from the snapshot's side (prepared once), those in w are R^T grad, R^T H R
        rotation = np.asarray(rotation, dtype=float)
        if self._current_by_degree is None:
            self._current_by_degree = np.ascontiguousarray(self.current.transpose(1, 0, 2))  # (L+1, r, 2L+1)
        turned = rotate_degree_major(self._current_by_degree, rotation)  # (..., L+1, r, 2L+1)
        assert self.side is not None  # set by __post_init__
        flat = turned.reshape(rotation.shape[:-2] + (-1,))
        values = (flat @ self.side.channel_matrix(self.channels, derivatives)).reshape(
            rotation.shape[:-2] + (len(self.channels), -1)
        )
        if derivatives:
            r = rotation[..., None, :, :]  # (..., 1, 3, 3) against (..., channels, ...)
            values[..., 1:4] = (values[..., None, 1:4] @ r)[..., 0, :]  # (R^T g)^T = g^T R
            hessian = values[..., 4:].reshape(values.shape[:-1] + (3, 3))
            values[..., 4:] = (np.swapaxes(r, -1, -2) @ hessian @ r).reshape(values.shape[:-1] + (9,))
        return values

    def _jet_of_values(self, values: np.ndarray) -> Jet:
        """Return the cost's Jet from the channels' values and derivatives (channels, 13)."""
        if self.area_channel is not None and values[self.area_channel, 0] <= self.min_area:
            return Jet(np.inf, np.zeros(3), np.zeros((3, 3)))
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.formula([Jet(v[0], v[1:4], v[4:].reshape(3, 3)) for v in values])

    def jet(self, rotation: np.ndarray) -> Jet:
        """Return the cost at R (3x3) with gradient and Hessian in the rotation vector w of R exp(w)."""
        return self._jet_of_values(self._channel_values(rotation, True))

    def jets(self, rotations: np.ndarray) -> list[Jet]:
        """Return the Jets of the cost at K rotations (K, 3, 3) in one pass."""
        return [self._jet_of_values(values) for values in self._channel_values(rotations, True)]

    def cost(self, rotation: np.ndarray) -> float:
        """Return the cost at R (3x3); inf where the overlap is too small (masked) or the cost undefined."""
        values = list(self._channel_values(rotation, False)[:, 0])
        with np.errstate(divide='ignore', invalid='ignore'):
            return float(self.mask_invalid(values, self.formula(values)))


def _is_zonal(stack: np.ndarray) -> np.ndarray:
    """Return per padded function (q, L+1, 2L+1) whether only its m = 0 coefficients are non-zero (to rounding)."""
    L = stack.shape[-2] - 1
    off_axis = np.delete(stack, L, axis=-1).reshape(stack.shape[0], -1)
    scale = np.max(np.abs(stack.reshape(stack.shape[0], -1)), axis=1)
    return np.max(np.abs(off_axis), axis=1, initial=0.0) <= 1e-12 * np.maximum(scale, 1e-300)


def _plain_terms(view: CompassView | np.ndarray) -> np.ndarray:
    """Return the filled coefficients of a view for the plain cost (a CompassView counts as zero-filled)."""
    return np.asarray(view.weighted if isinstance(view, CompassView) else view, dtype=float)


def build_problem(
    snapshot: CompassView | np.ndarray | PreparedSnapshot,
    current: CompassView | np.ndarray,
    max_degree: int,
    kind: str = 'masked',
    normalise: bool = False,
    min_overlap: float = 0.25,
) -> CostProblem:
    """Return the CostProblem of a cost kind ('masked' or 'plain') for two views cut to degree L.

    The snapshot may come prepared (prepare_snapshot with the same kind, normalise and L): its side is then reused.
    min_overlap (masked): reject rotations whose overlap is below this share of the smaller view's area.
    """
    side = prepare_snapshot(snapshot, max_degree, kind, normalise)
    a = side.padded
    if kind == 'plain':
        f_c = _plain_terms(current)
        if normalise:
            f_c = illumination_invariant(f_c[: (max_degree + 1) ** 2])
        b = to_padded(f_c, max_degree)
        constant = side.norm_square + float(np.sum(b * b))
        return CostProblem(a, b[None], PLAIN_CHANNELS, lambda c: constant - 2.0 * c[0], 'plain', side=side)
    if not isinstance(current, CompassView):
        raise TypeError('the masked cost needs CompassView inputs (v f, v f^2 and v)')
    # a = (v_s f_s^2, v_s f_s, v_s), b = (v_c, v_c f_c, v_c f_c^2)
    b = to_padded(np.stack([current.visibility, current.weighted, current.weighted_square]), max_degree)
    min_area = min_overlap * min(side.area, current.area)
    if not normalise:
        return CostProblem(a, b, MASKED_CHANNELS, masked_mean_square, 'masked', 1, min_area, side=side)
    return CostProblem(a, b, MASKED_NORMALISED_CHANNELS, masked_decorrelation, 'masked', 3, min_area, side=side)
