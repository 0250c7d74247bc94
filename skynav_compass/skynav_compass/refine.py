# SPDX-License-Identifier: Apache-2.0
"""Local refinement of a compass rotation: safeguarded Newton steps on the rotation vector of R = R0 exp(w)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skynav_compass.cost import CostProblem, Jet
from skynav_core.rotations import within_tilt


@dataclass(frozen=True)
class Refined:
    """A refined rotation R (3x3, d_snapshot = R d_current), its cost, gradient norm, Hessian and Newton iterations."""

    matrix: np.ndarray
    cost: float
    gradient_norm: float
    iterations: int
    hessian: np.ndarray  # of the cost in the rotation vector at R (3x3)


def _rotation_vector_exp(w: np.ndarray) -> np.ndarray:
    """Return the 3x3 matrix exp([w]x) of a rotation vector w (rad), by Rodrigues' formula."""
    x, y, z = (float(v) for v in w)
    angle = math.sqrt(x * x + y * y + z * z)
    if angle < 1e-8:
        a, b = 1.0, 0.5
    else:
        a, b = math.sin(angle) / angle, (1.0 - math.cos(angle)) / (angle * angle)
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    return np.array(
        [
            [1.0 - b * (yy + zz), b * xy - a * z, b * xz + a * y],
            [b * xy + a * z, 1.0 - b * (xx + zz), b * yz - a * x],
            [b * xz - a * y, b * yz + a * x, 1.0 - b * (xx + yy)],
        ]
    )


def _cholesky_solve(h: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    """Return H^-1 g for a symmetric 3x3 H by Cholesky, or None if H is not positive definite."""
    (a, b, c), (_, d, e), (_, _, f) = h.tolist()
    if a <= 0:
        return None
    l11 = a**0.5
    l21, l31 = b / l11, c / l11
    t = d - l21 * l21
    if t <= 0:
        return None
    l22 = t**0.5
    l32 = (e - l31 * l21) / l22
    t = f - l31 * l31 - l32 * l32
    if t <= 0:
        return None
    l33 = t**0.5
    g1, g2, g3 = g.tolist()
    y1 = g1 / l11
    y2 = (g2 - l21 * y1) / l22
    y3 = (g3 - l31 * y1 - l32 * y2) / l33
    x3 = y3 / l33
    x2 = (y2 - l32 * x3) / l22
    x1 = (y1 - l21 * x2 - l31 * x3) / l11
    return np.array([x1, x2, x3])


def _newton_step(gradient: np.ndarray, hessian: np.ndarray) -> np.ndarray:
    """Return -H^-1 g, with H's eigenvalues taken by absolute value (floored) where H is not positive definite."""
    solved = _cholesky_solve(hessian, gradient)
    if solved is not None and np.all(np.isfinite(solved)):
        return -solved
    eigenvalues, vectors = np.linalg.eigh(hessian)
    floor = max(np.max(np.abs(eigenvalues)) * 1e-6, 1e-300)
    return -vectors @ ((vectors.T @ gradient) / np.maximum(np.abs(eigenvalues), floor))


def _orthonormalise(matrix: np.ndarray) -> np.ndarray:
    """Return a 3x3 matrix near a rotation moved onto SO(3) (one Newton step of the polar decomposition)."""
    return 1.5 * matrix - 0.5 * matrix @ matrix.T @ matrix


def newton_prediction(
    problem: CostProblem, start: np.ndarray, radius: float = 0.2, jet: Jet | None = None, max_tilt: float | None = None
) -> Refined:
    """Return one Newton step from R0 (3x3) and the cost its quadratic model predicts there (one cost evaluation).

    max_tilt (rad): a step that would tilt z further than this is not taken (R0 and its cost are returned).
    """
    matrix = _orthonormalise(np.asarray(start, dtype=float))
    jet = problem.jet(matrix) if jet is None else jet
    if not np.isfinite(jet.value):
        return Refined(matrix, float('inf'), float('inf'), 0, np.zeros((3, 3)))
    step = _newton_step(jet.grad, jet.hess)
    length = float(np.linalg.norm(step))
    if length > radius:
        step *= radius / length
    predicted = jet.value + float(jet.grad @ step) + 0.5 * float(step @ jet.hess @ step)
    stepped = matrix @ _rotation_vector_exp(step)
    if not within_tilt(stepped, max_tilt):
        return Refined(matrix, jet.value, float(np.linalg.norm(jet.grad)), 0, jet.hess)
    return Refined(stepped, min(predicted, jet.value), float(np.linalg.norm(jet.grad)), 0, jet.hess)


def refine(
    problem: CostProblem,
    start: np.ndarray,
    radius: float = 0.2,
    max_iterations: int = 40,
    tolerance: float = 1e-4,
    jet: Jet | None = None,
    max_tilt: float | None = None,
) -> Refined:
    """Return the local minimum of the cost near R0 (3x3) by Newton steps (|w| <= a trust radius, rad).

    max_tilt (rad): a step that would tilt z further than this is refused like one that does not descend, so the
    result stays within the bound (from a start beyond it, only steps back within it are taken).
    """
    # the Hessian's eigenvalues are taken by absolute value (floored), so a step always descends; a step that
    # does not lower the cost shrinks the trust radius. Convergence: an accepted Newton step shorter than
    # `tolerance` rad; Newton's error after it is of the order of its square (~1e-8 rad for the default)
    matrix = _orthonormalise(np.asarray(start, dtype=float))
    jet = problem.jet(matrix) if jet is None else jet  # a Jet at the start may come from a batched evaluation
    if not np.isfinite(jet.value):
        return Refined(matrix, float('inf'), float('inf'), 0, np.zeros((3, 3)))
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (the count run is read after the loop)
        step = _newton_step(jet.grad, jet.hess)
        length = newton_length = float(np.linalg.norm(step))
        if length > radius:
            step *= radius / length
            length = radius
        if length < 1e-3 * tolerance * tolerance:
            break
        candidate = matrix @ _rotation_vector_exp(step)
        trial = problem.jet(candidate) if within_tilt(candidate, max_tilt) else Jet(np.inf, jet.grad, jet.hess)
        slack = 1e-13 * max(abs(jet.value), 1e-300)
        if np.isfinite(trial.value) and (
            trial.value <= jet.value + slack
            or (length < 1e-6 and np.linalg.norm(trial.grad) < np.linalg.norm(jet.grad))
        ):
            matrix, jet = candidate, trial
            radius = max(radius, 2.0 * length)
            if newton_length < tolerance:
                break
        else:
            radius = length / 4.0
            if radius < 1e-3 * tolerance * tolerance:
                break
    return Refined(_orthonormalise(matrix), jet.value, float(np.linalg.norm(jet.grad)), iterations, jet.hess)
