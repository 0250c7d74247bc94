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
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence, Union

import numpy as np

from skynav_compass.so3 import (EulerGrid, correlation_products, rotate_by_matrix, so3_correlation,
                                stacked_generators, to_padded)
from skynav_compass.views import CompassView

COSTS = ('masked', 'plain')


class Jet:
    """A scalar with its gradient (3,) and Hessian (3, 3) with respect to a rotation vector (second-order AD)."""

    __slots__ = ('value', 'grad', 'hess')

    def __init__(self, value: float, grad: np.ndarray, hess: np.ndarray) -> None:
        """Hold value, gradient and Hessian."""
        self.value, self.grad, self.hess = float(value), np.asarray(grad, float), np.asarray(hess, float)

    @staticmethod
    def _lift(other: Union[Jet, float]) -> Jet:
        return other if isinstance(other, Jet) else Jet(other, np.zeros(3), np.zeros((3, 3)))

    def __add__(self, other: Union[Jet, float]) -> Jet:
        other = Jet._lift(other)
        return Jet(self.value + other.value, self.grad + other.grad, self.hess + other.hess)

    __radd__ = __add__

    def __neg__(self) -> Jet:
        return Jet(-self.value, -self.grad, -self.hess)

    def __sub__(self, other: Union[Jet, float]) -> Jet:
        return self + (-Jet._lift(other))

    def __rsub__(self, other: Union[Jet, float]) -> Jet:
        return Jet._lift(other) - self

    def __mul__(self, other: Union[Jet, float]) -> Jet:
        other = Jet._lift(other)
        cross = np.outer(self.grad, other.grad)
        return Jet(self.value * other.value, self.value * other.grad + other.value * self.grad,
                   self.value * other.hess + other.value * self.hess + cross + cross.T)

    __rmul__ = __mul__

    def reciprocal(self) -> Jet:
        """Return 1 / self."""
        v = self.value
        return Jet(1.0 / v, -self.grad / v**2, -self.hess / v**2 + 2.0 * np.outer(self.grad, self.grad) / v**3)

    def __truediv__(self, other: Union[Jet, float]) -> Jet:
        if not isinstance(other, Jet):
            return Jet(self.value / other, self.grad / other, self.hess / other)
        q = self.value / other.value
        grad = (self.grad - q * other.grad) / other.value
        cross = np.outer(grad, other.grad)
        return Jet(q, grad, (self.hess - q * other.hess - cross - cross.T) / other.value)

    def __rtruediv__(self, other: Union[Jet, float]) -> Jet:
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


@dataclass
class CostProblem:
    """A snapshot and a current view prepared for one cost: padded terms, correlation channels and the formula.

    Channel k is the linear combination sum w <a_i, D(R) b_j> over its terms; the cost is formula(channels).
    """

    snapshot: np.ndarray  # (q, L+1, 2L+1) padded snapshot-side functions a
    current: np.ndarray  # (r, L+1, 2L+1) padded current-side functions b (turned by R)
    channels: tuple[Channel, ...]
    formula: Callable[[Sequence], object]
    kind: str
    area_channel: int | None = None  # channel holding the overlap area (masked)
    min_area: float = 0.0  # sr; rotations whose overlap is smaller are rejected
    _current_jets: np.ndarray | None = field(default=None, repr=False)
    _matrices: dict = field(default_factory=dict, repr=False)

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
        zonal_s, zonal_c = _is_zonal(self.snapshot), _is_zonal(self.current)
        zonal = [all(zonal_s[i] and zonal_c[j] for i, j, _ in channel) for channel in self.channels]
        general = [channel for channel, z in zip(self.channels, zonal) if not z]
        correlated = iter(so3_correlation(np.stack([
            correlation_products(self.snapshot[[i for i, _, _ in channel]], self.current[[j for _, j, _ in channel]],
                                 np.array([w for _, _, w in channel])) for channel in general]), grid)
            if general else [])
        legendre = grid.half_table()[L * (L + 1)]  # cell (m, n) = (0, 0): (n_beta, L+1)
        values = []
        for channel, z in zip(self.channels, zonal):
            if z:
                per_degree = sum(w * self.snapshot[i, :, L] * self.current[j, :, L] for i, j, w in channel)
                values.append(np.broadcast_to((legendre @ per_degree)[:, None, None], grid.shape))
            else:
                values.append(next(correlated))
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.mask_invalid(values, self.formula(values))

    def _jets_of_current(self) -> np.ndarray:
        """Return b, G_i b and (G_i G_j + G_j G_i) / 2 b for every current term: (r, 13, L+1, 2L+1), cached."""
        if self._current_jets is None:
            shape = self.current.shape
            r, n = shape[0], shape[1] * shape[2]
            flat = self.current.reshape(r, n).T  # (n, r)
            stacked = stacked_generators(self.max_degree)  # (3n, n): G_x, G_y, G_z one above the other
            first = stacked @ flat  # (3n, r): rows i n + k hold (G_i b)_k
            second = (stacked @ first.reshape(3, n, r).transpose(1, 0, 2).reshape(n, 3 * r)).reshape(3, n, 3, r)
            second = 0.5 * (second + second.transpose(2, 1, 0, 3))  # [i, :, j] = (G_i G_j + G_j G_i) b / 2
            columns = np.concatenate([flat[None], first.reshape(3, n, r),
                                      second.transpose(0, 2, 1, 3).reshape(9, n, r)])  # (13, n, r)
            self._current_jets = columns.transpose(2, 0, 1).reshape(r, 13, *shape[1:])
        return self._current_jets

    def _channel_matrix(self, derivatives: bool) -> np.ndarray:
        """Return the (q n, channels k) matrix M with channel values (and derivatives) = vec(D(R)^T a) @ M, cached."""
        cached = self._matrices.get(derivatives)
        if cached is None:
            jets = self._jets_of_current() if derivatives else self.current[:, None]
            q, (r, k) = self.snapshot.shape[0], jets.shape[:2]
            n = jets.shape[-2] * jets.shape[-1]
            combined = np.zeros((len(self.channels), q, k, n))
            for c, channel in enumerate(self.channels):
                for i, j, w in channel:
                    combined[c, i] += w * jets[j].reshape(k, n)
            cached = np.ascontiguousarray(combined.transpose(1, 3, 0, 2).reshape(q * n, len(self.channels) * k))
            self._matrices[derivatives] = cached
        return cached

    def _channel_values(self, rotation: np.ndarray, derivatives: bool) -> np.ndarray:
        """Return every channel's value (and 3 + 9 derivatives) at R (3x3, or K of them): (..., channels, 1 or 13)."""
        # <a, D(R exp w) b> = <D(R)^T a, exp(sum w_i G_i) b>
        rotation = np.asarray(rotation)
        turned = rotate_by_matrix(self.snapshot, np.swapaxes(rotation, -1, -2))  # (..., q, L+1, 2L+1)
        flat = turned.reshape(rotation.shape[:-2] + (-1,))
        return (flat @ self._channel_matrix(derivatives)).reshape(rotation.shape[:-2] + (len(self.channels), -1))

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


def _plain_terms(view: Union[CompassView, np.ndarray]) -> np.ndarray:
    """Return the filled coefficients of a view for the plain cost (a CompassView counts as zero-filled)."""
    return np.asarray(view.weighted if isinstance(view, CompassView) else view, dtype=float)


def build_problem(snapshot: Union[CompassView, np.ndarray], current: Union[CompassView, np.ndarray],
                  max_degree: int, kind: str = 'masked', normalise: bool = False,
                  min_overlap: float = 0.25) -> CostProblem:
    """Return the CostProblem of a cost kind ('masked' or 'plain') for two views cut to degree L.

    min_overlap (masked): reject rotations whose overlap is below this share of the smaller view's area.
    """
    if kind == 'plain':
        from skynav_sh.spectra import illumination_invariant

        f_s, f_c = _plain_terms(snapshot), _plain_terms(current)
        if normalise:
            f_s, f_c = illumination_invariant(f_s[: (max_degree + 1) ** 2]), illumination_invariant(
                f_c[: (max_degree + 1) ** 2])
        a, b = to_padded(f_s, max_degree), to_padded(f_c, max_degree)
        constant = float(np.sum(a * a) + np.sum(b * b))
        return CostProblem(a[None], b[None], (((0, 0, 1.0),),), lambda c: constant - 2.0 * c[0], 'plain')
    if kind != 'masked':
        raise ValueError(f'unknown cost {kind!r}; expected one of {COSTS}')
    if not (isinstance(snapshot, CompassView) and isinstance(current, CompassView)):
        raise TypeError('the masked cost needs CompassView inputs (v f, v f^2 and v)')
    # a = (v_s f_s^2, v_s f_s, v_s), b = (v_c, v_c f_c, v_c f_c^2)
    a = to_padded(np.stack([snapshot.weighted_square, snapshot.weighted, snapshot.visibility]), max_degree)
    b = to_padded(np.stack([current.visibility, current.weighted, current.weighted_square]), max_degree)
    min_area = min_overlap * min(snapshot.area, current.area)
    if not normalise:
        channels = (((0, 0, 1.0), (1, 1, -2.0), (2, 2, 1.0)), ((2, 0, 1.0),))
        return CostProblem(a, b, channels, masked_mean_square, 'masked', 1, min_area)
    channels = (((0, 0, 1.0),), ((1, 1, 1.0),), ((2, 2, 1.0),), ((2, 0, 1.0),), ((1, 0, 1.0),), ((2, 1, 1.0),))
    return CostProblem(a, b, channels, masked_decorrelation, 'masked', 3, min_area)
