# SPDX-License-Identifier: Apache-2.0
"""Fish-eye mask -> coefficients against the direct transform of the analytic sky region.

Error bound used here (per degree l, coefficient vector c_l):
* image path vs the same sub-samples read from the analytic region: a bilinear sub-sample equals the region's
  indicator unless the indicator differs among the pixels it interpolates (checked on the 4 x 4 pixel block
  around it, which also covers cv2's 1/32-pixel rounding of map coordinates), where the error is at most 1. So
  |sample error| <= band fraction at every node, and by Unsold's theorem (sum_m Y_lm^2 = (2l+1)/(4 pi)) and
  Minkowski's inequality ||dc_l|| <= sqrt((2l+1)/(4 pi)) * A_band, A_band = sum_nodes w * band fraction (sr);
* sampling vs the exact integral: cells the skyline does not cross hold the exact indicator and their smooth
  Y-quadrature error is of higher order, so to first order ||dc_l|| <= sqrt((2l+1)/(4 pi)) * A_cut, A_cut the solid
  angle of the cells the skyline crosses.
Both bounds are worst cases (all errors of one sign); the measured errors sit one to two orders below.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skynav_core.camera import EquidistantCamera, OCamCamera, angles_from_directions
from skynav_sh.basis import n_coefficients, real_sh
from skynav_sh.fisheye import FisheyeTransform

DEGREE = 24
CAMERA = EquidistantCamera.for_field_of_view(640, 480, np.radians(200))


def skyline_theta(phi: np.ndarray) -> np.ndarray:
    """Polar angle (rad) of a made-up skyline: elevation 0.25 rad with two ripples, so theta < 90 degrees."""
    return np.pi / 2 - (0.25 + 0.1 * np.sin(3 * phi) + 0.05 * np.cos(7 * phi + 1.0))


def sky(directions: np.ndarray) -> np.ndarray:
    theta, phi = angles_from_directions(directions)
    return (theta < skyline_theta(phi)).astype(float)


def render_mask(camera) -> np.ndarray:
    """uint8 mask 255 sky / 0 ground, each pixel labelled by its centre's ray."""
    return np.where(sky(camera.pixel_directions()) > 0, 255, 0).astype(np.uint8)


def direct_transform(degree: int, top_theta, n_phi: int = 720, n_theta: int = 40) -> np.ndarray:
    """c_lm of the region theta < top_theta(phi): Gauss-Legendre in theta per azimuth, trapezoid in phi (smooth)."""
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    x, w = np.polynomial.legendre.leggauss(n_theta)
    out = np.zeros(n_coefficients(degree))
    for start in range(0, n_phi, 90):
        p = phi[start : start + 90, None]
        top = top_theta(p)
        theta = (x + 1) / 2 * top
        weight = w * top / 2 * np.sin(theta) * (2 * np.pi / n_phi)
        out += np.einsum('pt,ptn->n', weight, real_sh(degree, theta, np.broadcast_to(p, theta.shape)))
    return out


def per_degree(coefficients: np.ndarray) -> np.ndarray:
    degree = int(np.sqrt(coefficients.size)) - 1
    return np.sqrt(np.add.reduceat(coefficients**2, np.arange(degree + 1) ** 2))


def unsold(degree: int) -> np.ndarray:
    return np.sqrt((2 * np.arange(degree + 1) + 1) / (4 * np.pi))


def band_fraction(transform: FisheyeTransform, camera, region) -> np.ndarray:
    """Per node: share of sub-samples whose 4 x 4 pixel neighbourhood straddles the region's edge."""
    directions, _ = transform.sample_directions()
    pixels = camera.project(directions)
    corner = np.floor(pixels) - 1
    labels = np.array([region(camera.unproject(corner + np.array([du, dv]))) for du in range(4) for dv in range(4)])
    straddles = (labels.max(axis=0) != labels.min(axis=0)) | (labels.max(axis=0) != region(directions))
    return transform.function_samples(lambda _: straddles)


def cut_area(transform: FisheyeTransform, top_theta) -> float:
    """Solid angle (sr) of the grid cells whose theta range meets the edge theta = top_theta(phi)."""
    g = transform.grid
    upper = 1.0 - np.concatenate([[0.0], np.cumsum(g.theta_weights)[:-1]])
    top, bottom = np.arccos(np.clip(upper, -1, 1)), np.arccos(np.clip(upper - g.theta_weights, -1, 1))
    edge = top_theta(g.phi[:, None] + (np.linspace(0, 1, 17) - 0.5) * g.phi_step)
    crosses = (top[:, None] <= edge.max(axis=1)) & (bottom[:, None] >= edge.min(axis=1))
    return float(np.sum(g.weights * crosses))


@pytest.fixture(scope='module')
def mask() -> np.ndarray:
    return render_mask(CAMERA)


@pytest.fixture(scope='module')
def reference() -> np.ndarray:
    return direct_transform(DEGREE, skyline_theta)


def test_image_path_equals_analytic_sampling_outside_the_pixel_band(mask):
    transform = FisheyeTransform(CAMERA, DEGREE, 'zero')
    band = band_fraction(transform, CAMERA, sky)
    error = np.abs(transform.samples(mask) - transform.function_samples(sky))
    assert np.all(error <= band + 1e-6)  # float32 remap; exact wherever no sub-sample is near the skyline
    assert np.count_nonzero(band) < 0.2 * band.size  # the band is a thin strip, so this is a real constraint
    analytic = transform.grid.analysis(transform.function_samples(sky))
    band_area = np.sum(transform.grid.weights * band)
    assert np.all(per_degree(transform.coefficients(mask) - analytic) <= unsold(DEGREE) * band_area + 1e-9)


def test_skyline_coefficients_match_the_direct_transform(mask, reference):
    transform = FisheyeTransform(CAMERA, DEGREE, 'zero')
    coefficients = transform.coefficients(mask)
    band_area = np.sum(transform.grid.weights * band_fraction(transform, CAMERA, sky))
    bound = unsold(DEGREE) * (band_area + cut_area(transform, skyline_theta))
    assert np.all(per_degree(coefficients - reference) <= bound)
    # and in total, well inside the worst case: the measured error is ~0.3 % of the coefficients' norm
    assert np.linalg.norm(coefficients - reference) < 0.01 * np.linalg.norm(reference)


def test_area_averaging_aliases_less_than_point_sampling(mask, reference):
    high = slice(n_coefficients(3 * DEGREE // 4 - 1), None)  # degrees 18..24
    errors = {}
    for sampling in ('point', 'area'):
        transform = FisheyeTransform(CAMERA, DEGREE, 'zero', supersampling=3, sampling=sampling)
        errors[sampling] = np.linalg.norm(transform.coefficients(mask)[high] - reference[high])
    assert errors['area'] < 0.7 * errors['point']


def test_finer_sampling_grids_converge(mask, reference):
    errors = [
        np.linalg.norm(FisheyeTransform(CAMERA, DEGREE, 'zero', oversampling=o).coefficients(mask) - reference)
        for o in (1, 2, 4)
    ]
    assert errors[0] > errors[1] > errors[2]


def test_fills(mask):
    zero = FisheyeTransform(CAMERA, 12, 'zero')
    visibility = zero.visibility
    samples = zero.samples(mask)
    assert np.all(samples[visibility == 0] == 0) and np.any(visibility == 0) and np.any(visibility == 1)
    assert np.any((visibility > 0) & (visibility < 1))
    weights = zero.grid.weights
    seen_mean = np.sum(weights * samples) / np.sum(weights * visibility)
    mean = FisheyeTransform(CAMERA, 12, 'mean').samples(mask)
    np.testing.assert_allclose(mean, samples + (1 - visibility) * seen_mean, atol=1e-6)


def test_mirror_fill_reflects_about_the_image_edge():
    # a smooth grey image g(theta, phi); a node beyond the edge must read g at theta' = 2 theta_max - theta
    def grey(directions):
        theta, phi = angles_from_directions(directions)
        return 0.5 + 0.3 * np.cos(theta) + 0.1 * np.sin(theta) * np.cos(2 * phi)

    image = grey(CAMERA.pixel_directions()).astype(np.float32)
    transform = FisheyeTransform(CAMERA, 12, 'mirror')
    samples = transform.samples(image)
    outside = transform.visibility == 0
    g = transform.grid
    theta = np.broadcast_to(g.theta[:, None], g.shape)[outside]
    phi = np.broadcast_to(g.phi[None, :], g.shape)[outside]
    mirrored = np.clip(2 * transform.theta_max - theta, 0, transform.theta_max)
    expected = grey(np.stack([np.sin(mirrored) * np.cos(phi), np.sin(mirrored) * np.sin(phi), np.cos(mirrored)], -1))
    # the cell mean differs from the node value by the variation of g across a cell (< 0.4 * cell size here)
    cell = np.pi / (2 * (12 + 1))
    np.testing.assert_allclose(samples[outside], expected, atol=0.4 * cell)
    np.testing.assert_allclose(samples, transform.function_samples(grey), atol=2e-3)  # bilinear reading


def test_visibility_is_the_image_circle_cap():
    transform = FisheyeTransform(CAMERA, 16, 'zero')
    theta_max = CAMERA.theta_max
    cap = direct_transform(16, lambda phi: np.full_like(phi, theta_max))
    x0 = np.cos(theta_max)
    assert cap[0] == pytest.approx(2 * np.pi * (1 - x0) / np.sqrt(4 * np.pi), rel=1e-12)  # the reference itself
    ring = cut_area(transform, lambda phi: np.full_like(phi, theta_max))
    assert np.all(per_degree(transform.visibility_coefficients - cap) <= unsold(16) * ring)
    assert np.sum(transform.grid.weights * transform.visibility) == pytest.approx(2 * np.pi * (1 - x0), abs=ring)


def test_ocam_camera_cap_mask():
    camera = OCamCamera.from_calib_file(
        Path(__file__).parents[2] / 'skynav_core' / 'test' / 'data' / 'calib_results.txt'
    )

    def cap(directions):
        return (angles_from_directions(directions)[0] < np.radians(75)).astype(float)

    mask = np.where(cap(camera.pixel_directions()) > 0, 255, 0).astype(np.uint8)
    transform = FisheyeTransform(camera, 16, 'zero')
    edge = lambda phi: np.full_like(phi, np.radians(75))  # noqa: E731
    expected = direct_transform(16, edge)
    band_area = np.sum(transform.grid.weights * band_fraction(transform, camera, cap))
    bound = unsold(16) * (band_area + cut_area(transform, edge))
    assert np.all(per_degree(transform.coefficients(mask) - expected) <= bound)
    assert np.linalg.norm(transform.coefficients(mask) - expected) < 0.01 * np.linalg.norm(expected)


def test_input_types_and_errors(mask):
    transform = FisheyeTransform(CAMERA, 8, 'zero')
    by_uint8 = transform.coefficients(mask)
    np.testing.assert_allclose(transform.coefficients(mask > 0), by_uint8, atol=1e-12)
    np.testing.assert_allclose(transform(mask.astype(np.float64) / 255), by_uint8, atol=1e-12)
    assert by_uint8.dtype == np.float64 and by_uint8.shape == (81,)
    with pytest.raises(ValueError):
        transform.coefficients(mask[:-1])
    with pytest.raises(ValueError):
        FisheyeTransform(CAMERA, 8, 'noise')
