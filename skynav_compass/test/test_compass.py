# SPDX-License-Identifier: Apache-2.0
"""The default compass on band-limited functions: exact recovery, identity, single-axis signs, costs, hypotheses.

Views of a function g fixed in the world, seen from camera orientations Q (camera_link in map), are
f(d) = g(Q d), i.e. rotate(g, Q^-1); with d_snapshot = R d_current, R = Q_s^-1 Q_c (docs/interfaces.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_compass import Compass, CompassConfig, CompassView, build_problem, cap_visibility, estimate_rotation
from skynav_compass.compass import MIN_RIVAL_MARGIN, RIVAL_MARGIN_SCALE, rival_margin
from skynav_compass.eval.evaluation import heading, relative_tilt
from skynav_compass.refine import refine
from skynav_core.rotations import rotation_angle
from skynav_sh.basis import degree_order
from skynav_sh.rotation import rotate

DEGREE = 12


def band_limited(seed: int, degree: int = DEGREE, orders: int | None = None) -> np.ndarray:
    """Random coefficients with a 1/(1+l) spectrum (like a natural view); only m divisible by `orders` if given."""
    l, m = degree_order(degree)
    c = np.random.default_rng(seed).standard_normal(l.size) / (1.0 + l)
    if orders is not None:
        c[np.abs(m) % orders != 0] = 0.0
    return c


def view_of(world: np.ndarray, orientation: Rotation) -> np.ndarray:
    """Return the coefficients seen by a camera with orientation Q in the world: rotate(g, Q^-1)."""
    return rotate(world, orientation.inv())


def angle_between(estimate, rotation: Rotation) -> float:
    return rotation_angle(estimate.matrix, rotation.as_matrix())


@pytest.mark.parametrize('cost', ['plain', 'masked'])
@pytest.mark.parametrize('seed', range(4))
def test_exact_recovery_of_random_rotations_full_sphere(cost, seed):
    f_current = band_limited(seed)
    truth = Rotation.random(random_state=100 + seed)
    f_snapshot = rotate(f_current, truth)  # f_s = f_c turned by R
    compass = Compass(DEGREE, CompassConfig(cost=cost, max_tilt=None))  # any rotation: the whole of SO(3)
    if cost == 'masked':
        estimate = compass.estimate(CompassView.from_coefficients(f_snapshot), CompassView.from_coefficients(f_current))
    else:
        estimate = compass.estimate(f_snapshot, f_current)
    assert angle_between(estimate, truth) < 1e-6  # rad
    assert abs(estimate.residual) < 1e-9
    assert estimate.confident


def test_identity_for_identical_views():
    f = band_limited(11)
    view = CompassView.from_coefficients(f, cap_visibility(DEGREE, np.radians(100)), max_degree=DEGREE)
    estimate = Compass(DEGREE).estimate(view, view)
    assert rotation_angle(estimate.matrix, np.eye(3)) < 1e-6
    assert estimate.quaternion[3] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize('axis', ['x', 'y', 'z'])
@pytest.mark.parametrize('degrees', [25.0, -25.0])
def test_rotation_about_each_axis_alone(axis, degrees):
    f_current = band_limited(21)
    truth = Rotation.from_euler(axis, degrees, degrees=True)
    estimate = estimate_rotation(rotate(f_current, truth), f_current, config=CompassConfig(cost='plain'))
    rotvec = np.degrees(estimate.rotation.as_rotvec())
    expected = np.zeros(3)
    expected['xyz'.index(axis)] = degrees
    assert np.allclose(rotvec, expected, atol=1e-5)


def test_contract_sign_camera_turned_about_its_own_z():
    """Turn the camera by +20 deg about its own z: the estimate is Q_s^-1 Q_c = Rz(+20 deg) (docs/interfaces.md)."""
    world = band_limited(31)
    q_snapshot = Rotation.from_euler('ZYX', [40.0, 8.0, -5.0], degrees=True)  # some heading and tilt in map
    q_current = q_snapshot * Rotation.from_euler('z', 20.0, degrees=True)  # intrinsic: about camera z
    truth = q_snapshot.inv() * q_current
    assert np.allclose(truth.as_rotvec(), [0.0, 0.0, np.radians(20.0)])
    visibility = cap_visibility(DEGREE, np.radians(100))
    views = [
        CompassView.from_coefficients(view_of(world, q), visibility, max_degree=DEGREE) for q in (q_snapshot, q_current)
    ]
    estimate = Compass(DEGREE).estimate(*views)
    assert np.degrees(estimate.rotation.as_rotvec()) == pytest.approx([0.0, 0.0, 20.0], abs=0.5)


def test_masked_cost_through_a_cap_recovers_tilted_rotations():
    """A 200-degree cap hides part of both views; the masked cost still finds R (band-limited products, no fill)."""
    world = band_limited(41)
    visibility = cap_visibility(DEGREE, np.radians(100))
    errors = []
    for seed in range(4):
        q_s = Rotation.from_euler('ZYX', [seed * 70.0, 10.0, -4.0], degrees=True)
        q_c = q_s * Rotation.from_euler('ZYX', [30.0 + 50 * seed, 25.0, 10.0], degrees=True)
        views = [CompassView.from_coefficients(view_of(world, q), visibility, max_degree=DEGREE) for q in (q_s, q_c)]
        estimate = Compass(DEGREE).estimate(*views)
        errors.append(np.degrees(angle_between(estimate, q_s.inv() * q_c)))
    # truncating the products v f, v f^2 to degree L leaves a small bias (measured 0.16-0.40 deg here)
    assert max(errors) < 1.0


def test_jet_derivatives_match_finite_differences():
    f_current = band_limited(51)
    visibility = cap_visibility(DEGREE, np.radians(100))
    truth = Rotation.from_rotvec([0.2, -0.1, 0.9])
    snapshot = CompassView.from_coefficients(rotate(f_current, truth), visibility, max_degree=DEGREE)
    current = CompassView.from_coefficients(f_current, visibility, max_degree=DEGREE)
    for normalise in (False, True):
        problem = build_problem(snapshot, current, DEGREE, 'masked', normalise)
        start = Rotation.from_rotvec([0.3, -0.05, 0.8]).as_matrix()
        jet = problem.jet(start)
        h = 1e-5
        for i in range(3):
            w = np.zeros(3)
            w[i] = h
            plus = problem.jet(start @ Rotation.from_rotvec(w).as_matrix())
            minus = problem.jet(start @ Rotation.from_rotvec(-w).as_matrix())
            assert (plus.value - minus.value) / (2 * h) == pytest.approx(jet.grad[i], rel=1e-5, abs=1e-8)
            # the Hessian in the rotation vector is symmetric; its column is the derivative of the gradient up to
            # the Lie-bracket term, so compare the symmetrised finite difference
            column = (plus.grad - minus.grad) / (2 * h)
            assert column[i] == pytest.approx(jet.hess[i, i], rel=1e-4, abs=1e-7)
        assert jet.value == pytest.approx(problem.cost(start), rel=1e-12)


def test_illumination_invariance_plain_and_masked():
    f_current = band_limited(61)
    truth = Rotation.from_rotvec([0.1, 0.2, -1.1])
    f_snapshot = rotate(f_current, truth)
    gain, offset = 3.0, 0.7
    brighter = gain * f_current
    brighter[0] += offset * np.sqrt(4 * np.pi)  # f -> gain f + offset on the whole sphere
    plain = Compass(DEGREE, CompassConfig(cost='plain', normalise=True)).estimate(f_snapshot, brighter)
    assert angle_between(plain, truth) < 1e-6
    assert plain.residual == pytest.approx(0.0, abs=1e-9)
    snapshot = CompassView.from_coefficients(f_snapshot)
    current = CompassView.from_coefficients(brighter)
    masked = Compass(DEGREE, CompassConfig(normalise=True)).estimate(snapshot, current)
    assert angle_between(masked, truth) < 1e-6
    assert masked.residual == pytest.approx(0.0, abs=1e-9)  # 1 - correlation coefficient


def test_several_peaks_give_several_hypotheses_and_low_confidence():
    """A view with 3-fold symmetry about z has three equally good yaws: report them all, flag low confidence."""
    f_current = band_limited(71, orders=3)
    truth = Rotation.from_euler('ZYZ', [30.0, 0.0, 0.0], degrees=True)
    estimate = estimate_rotation(rotate(f_current, truth), f_current, config=CompassConfig(cost='plain'))
    assert not estimate.confident
    assert len(estimate.hypotheses) >= 2
    assert estimate.hypotheses[1].cost - estimate.hypotheses[0].cost < 1e-6
    yaws = heading(np.stack([h.matrix for h in estimate.hypotheses[:2]]))
    assert np.remainder(yaws - 30.0 + 1.0, 120.0) == pytest.approx([1.0, 1.0], abs=1e-3)  # 30 deg modulo 120
    assert abs(yaws[0] - yaws[1]) > 100.0


def test_small_overlap_rotations_are_rejected():
    f = band_limited(81)
    visibility = cap_visibility(DEGREE, np.radians(60))  # a narrow cap: upside down, the views hardly overlap
    view = CompassView.from_coefficients(f, visibility, max_degree=DEGREE)
    compass = Compass(DEGREE, CompassConfig(min_overlap=0.25))
    assert compass.cost(view, view, Rotation.from_euler('x', 180, degrees=True)) == float('inf')
    assert np.isfinite(compass.cost(view, view, np.eye(3)))


# --- a ground robot's prior: the tilt bound, the overlap, verification on samples and the confidence ---------------


def skyline_view(orientation: Rotation, skyline, field_of_view_deg: float = 200.0, degree: int = 16) -> CompassView:
    """Return the binary mask view (degree L) of a world whose sky lies above the elevation skyline(azimuth) (rad).

    The camera (camera_link in the world: orientation Q) sees the cap up to half the field of view from its +z;
    sampled on a fine Gauss-Legendre grid, so the mask's edges are sharp before the cut to degree L.
    """
    from skynav_sh.transform import GaussLegendreGrid

    grid = GaussLegendreGrid(degree, n_phi=512, n_theta=256)
    directions = grid.directions()
    world = directions @ orientation.as_matrix().T  # Q d
    elevation = np.arcsin(np.clip(world[..., 2], -1.0, 1.0))
    sky = elevation > skyline(np.arctan2(world[..., 1], world[..., 0]))
    seen = directions[..., 2] >= np.cos(np.radians(field_of_view_deg / 2))
    return CompassView.from_samples(grid, (seen & sky).astype(float), seen.astype(float))


def rugged(azimuth):
    """A skyline of trees and roofs: 5-30 degrees above the horizon."""
    return np.radians(15.0 + 7.0 * np.sin(3 * azimuth + 0.4) + 5.0 * np.cos(5 * azimuth) + 3.0 * np.sin(azimuth))


def test_the_masks_of_skyline_views_are_verified_on_samples():
    q_s = Rotation.from_euler('ZYX', [20.0, 4.0, -3.0], degrees=True)
    q_c = q_s * Rotation.from_euler('ZYX', [130.0, 18.0, -9.0], degrees=True)
    estimate = Compass(16).estimate(skyline_view(q_s, rugged), skyline_view(q_c, rugged))
    assert 'verified' in estimate.details  # binary views: ranked on samples
    assert np.degrees(angle_between(estimate, q_s.inv() * q_c)) < 1.0
    assert estimate.details['verified'].disagreement[0] < 0.02  # the recovered masks agree where both see
    assert estimate.confident and estimate.confidence > 0.5


def test_an_upside_down_rotation_is_never_returned_within_the_tilt_bound():
    """The views' truth is a half turn about a horizontal axis; the bounded compass must not claim it."""
    world = band_limited(91)
    turned_over = Rotation.from_euler('x', 180.0, degrees=True)
    views = [CompassView.from_coefficients(view_of(world, q)) for q in (Rotation.identity(), turned_over)]
    unbounded = Compass(DEGREE, CompassConfig(max_tilt=None)).estimate(*views)
    assert np.degrees(angle_between(unbounded, turned_over)) < 1e-3  # on the whole sphere the truth is found
    bounded = Compass(DEGREE).estimate(*views)  # default: 45 degrees
    tilts = relative_tilt(np.stack([h.matrix for h in bounded.hypotheses]))
    assert np.all(tilts <= 45.0 + 1e-6)
    assert relative_tilt(bounded.matrix) <= 45.0 + 1e-6


def test_newton_steps_stay_within_the_tilt_bound():
    """The optimum lies at 80 degrees of tilt; from 30 degrees the bounded refinement stops at the bound."""
    world = band_limited(93)
    truth = Rotation.from_euler('y', 80.0, degrees=True)
    views = [CompassView.from_coefficients(view_of(world, q)) for q in (Rotation.identity(), truth)]
    problem = Compass(DEGREE).problem(*views)
    start = Rotation.from_euler('y', 30.0, degrees=True).as_matrix()
    assert np.degrees(rotation_angle(refine(problem, start).matrix, truth.as_matrix())) < 1e-3
    bounded = refine(problem, start, max_tilt=np.radians(45.0))
    assert relative_tilt(bounded.matrix) <= 45.0 + 1e-6
    assert relative_tilt(bounded.matrix) > 40.0  # it went as far towards the optimum as the bound lets it


def test_hypotheses_whose_fields_of_view_hardly_overlap_are_refused():
    """200-degree fish-eyes turned over still share a 20-degree band (30 % of a view): the default refuses it."""
    view = CompassView.from_coefficients(band_limited(95), cap_visibility(DEGREE, np.radians(100)), max_degree=DEGREE)
    turned_over = Rotation.from_euler('x', 180, degrees=True)
    assert Compass(DEGREE).cost(view, view, turned_over) == float('inf')  # default: at least half
    assert np.isfinite(Compass(DEGREE, CompassConfig(min_overlap=0.25)).cost(view, view, turned_over))
    assert np.isfinite(Compass(DEGREE).cost(view, view, Rotation.from_euler('x', 45, degrees=True)))


def test_the_confidence_ranks_estimates():
    """A flat horizon says nothing about yaw: its estimates rank below those of a rugged skyline, and below 1/2."""
    rng = np.random.default_rng(97)
    flat = lambda azimuth: np.zeros_like(azimuth)  # noqa: E731
    confidences = {}
    for name, skyline in (('rugged', rugged), ('flat', flat)):
        values = []
        for _ in range(3):
            q_s = Rotation.from_euler(
                'ZYX', [rng.uniform(0, 360), rng.uniform(-5, 5), rng.uniform(-5, 5)], degrees=True
            )
            q_c = q_s * Rotation.from_euler(
                'ZYX', [rng.uniform(0, 360), rng.uniform(-20, 20), rng.uniform(-20, 20)], degrees=True
            )
            estimate = Compass(16).estimate(skyline_view(q_s, skyline), skyline_view(q_c, skyline))
            values.append(estimate.confidence)
            if name == 'rugged':
                assert np.degrees(angle_between(estimate, q_s.inv() * q_c)) < 1.0
        confidences[name] = values
    assert min(confidences['rugged']) > 0.5 > max(confidences['flat'])


def symmetric(azimuth):
    """A skyline alike at every azimuth and the one half a turn round it: two yaws fit it equally well."""
    return np.radians(15.0 + 8.0 * np.cos(2 * azimuth) + 4.0 * np.sin(6 * azimuth + 0.3))


def test_a_rival_that_fits_as_well_takes_the_confidence_however_sharp_the_best():
    """Two rotations half a turn apart explain a two-fold skyline alike: whichever wins, it is not confident."""
    for current in ([70.0, 8.0, 5.0], [100.0, -10.0, 4.0]):
        q_s = Rotation.from_euler('ZYX', [10.0, 3.0, -2.0], degrees=True)
        q_c = q_s * Rotation.from_euler('ZYX', current, degrees=True)
        truth = (q_s.inv() * q_c).as_matrix()
        estimate = Compass(16).estimate(skyline_view(q_s, symmetric), skyline_view(q_c, symmetric))
        errors = [np.degrees(rotation_angle(h.matrix, truth)) for h in estimate.hypotheses[:2]]
        assert min(errors) < 1.0 and max(errors) > 170.0  # the truth and its half turn, the best two
        assert estimate.details['sharpness'] * estimate.details['verified'].contrast[0] > 0.5  # sharp on its own
        assert estimate.details['rival_margin'] < MIN_RIVAL_MARGIN
        assert not estimate.confident, current
        # the rugged skyline under the same rotations: no rival comes close, the estimate is confident
        rugged_estimate = Compass(16).estimate(skyline_view(q_s, rugged), skyline_view(q_c, rugged))
        assert rugged_estimate.details['rival_margin'] > RIVAL_MARGIN_SCALE and rugged_estimate.confident


def test_the_rival_margin_compares_the_best_with_the_closest_distinct_rival():
    assert rival_margin(np.array([0.01, 0.04, 0.02])) == pytest.approx(0.75)
    assert rival_margin(np.array([0.02, 0.02])) == 0.0
    assert rival_margin(np.array([0.0, 0.0])) == 0.0  # both fit perfectly: a tie
    assert rival_margin(np.array([0.0, 0.01])) == 1.0
    assert rival_margin(np.array([0.02])) == 1.0  # no rival


def test_a_hypothesis_found_twice_is_not_its_own_rival(monkeypatch):
    """Two starts that refine to the same optimum (common on real masks) must not read as a rival that fits as well."""
    q_s = Rotation.from_euler('ZYX', [20.0, 4.0, -3.0], degrees=True)
    q_c = q_s * Rotation.from_euler('ZYX', [130.0, 18.0, -9.0], degrees=True)
    views = skyline_view(q_s, rugged), skyline_view(q_c, rugged)
    once = Compass(16).estimate(*views)
    found = Compass._verified_optima

    def twice(self, problem, starts, start_jets, details):
        results = found(self, problem, starts, start_jets, details)
        details['verified'] = details['verified'].subset(np.r_[0, np.arange(len(results))])
        return [results[0], *results]

    monkeypatch.setattr(Compass, '_verified_optima', twice)
    doubled = Compass(16).estimate(*views)
    assert once.confident and doubled.confident
    assert doubled.details['rival_margin'] == once.details['rival_margin'] > RIVAL_MARGIN_SCALE
    assert doubled.confidence == once.confidence
