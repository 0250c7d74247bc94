# SPDX-License-Identifier: Apache-2.0
"""Gaunt coefficients, SH products and the masked distance against the quadrature grid."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_sh.basis import degree_order, n_coefficients, real_sh_directions
from skynav_sh.coupling import real_gaunt
from skynav_sh.product import (
    MIN_CLASS_SHARE,
    MaskedView,
    cap_area,
    masked_distance,
    masked_distance_views,
    message_sky_share,
    overlap_area,
    product,
    seen_mean,
    shows_skyline,
)
from skynav_sh.rotation import rotate
from skynav_sh.spectra import coefficient_distance
from skynav_sh.transform import grid


def cap_visibility(degree: int, axis: np.ndarray, half_angle: float) -> np.ndarray:
    """Band-limited coefficients of a soft cap about `axis` (a seen region), by the exact grid transform."""
    g = grid(degree)
    cosine = g.directions() @ (axis / np.linalg.norm(axis))
    return g.analysis(0.5 * (1 + np.tanh(6 * (cosine - np.cos(half_angle)))))


def test_gaunt_coefficients_equal_brute_force_quadrature():
    degrees = (4, 3, 5)
    gaunt = real_gaunt(*degrees)
    g = grid(6)  # exact for degree 4 + 3 + 5 = 12 <= 2 * 6 + 1
    y = real_sh_directions(5, g.directions())
    n1, n2, n3 = (n_coefficients(d) for d in degrees)
    expected = np.einsum('tpa,tpb,tpc,tp->abc', y[..., :n1], y[..., :n2], y[..., :n3], g.weights)
    dense = np.zeros_like(expected)
    np.add.at(dense, (gaunt.first, gaunt.second, gaunt.third), gaunt.values)
    np.testing.assert_allclose(dense, expected, atol=1e-14)
    assert gaunt.nnz == np.count_nonzero(np.abs(expected) > 1e-12)  # stores exactly the non-zero ones
    l, _ = degree_order(5)
    l1, l2, l3 = l[gaunt.first], l[gaunt.second], l[gaunt.third]
    assert np.all((l1 + l2 + l3) % 2 == 0) and np.all(l3 <= l1 + l2) and np.all(l3 >= np.abs(l1 - l2))


@pytest.mark.parametrize('method', ['grid', 'gaunt'])
def test_product_equals_the_pointwise_product(method):
    rng = np.random.default_rng(17)
    f, g_ = rng.standard_normal(n_coefficients(5)), rng.standard_normal(n_coefficients(4))
    h = product(f, g_, method=method)
    assert h.shape == (n_coefficients(9),)
    quadrature = grid(9)
    np.testing.assert_allclose(quadrature.synthesis(h), quadrature.synthesis(f) * quadrature.synthesis(g_), atol=1e-12)
    truncated = product(f, g_, max_degree=3, method=method)
    np.testing.assert_allclose(truncated, h[: n_coefficients(3)], atol=1e-13)


def test_product_methods_agree_on_batches():
    rng = np.random.default_rng(18)
    f, g = rng.standard_normal((3, n_coefficients(4))), rng.standard_normal(n_coefficients(4))
    np.testing.assert_allclose(product(f, g, 6, 'grid'), product(f, g, 6, 'gaunt'), atol=1e-13)


def masked_distance_on_grid(f, g, vf, vg, degree):
    quadrature = grid(degree)
    s = quadrature.synthesis
    weight = s(vf) * s(vg)
    return quadrature.integrate(weight * (s(f) - s(g)) ** 2) / quadrature.integrate(weight)


@pytest.mark.parametrize('method', ['grid', 'gaunt'])
def test_masked_distance_equals_the_grid_integral(method):
    rng = np.random.default_rng(19)
    degree, degree_v = 10, 6
    f, g = rng.standard_normal((2, n_coefficients(degree)))
    vf = cap_visibility(degree_v, np.array([0.0, 0.0, 1.0]), 1.7)
    vg = cap_visibility(degree_v, np.array([0.3, -0.2, 1.0]), 1.7)
    expected = masked_distance_on_grid(f, g, vf, vg, degree + degree_v)
    assert masked_distance(f, g, vf, vg, method=method) == pytest.approx(expected, rel=1e-11)
    assert overlap_area(vf, vg) == pytest.approx(
        grid(degree_v).integrate(grid(degree_v).synthesis(vf) * grid(degree_v).synthesis(vg)), rel=1e-12
    )


def test_masked_distance_with_full_visibility_is_the_mean_squared_error():
    rng = np.random.default_rng(20)
    f, g = rng.standard_normal((2, n_coefficients(6)))
    everywhere = np.zeros(n_coefficients(2))
    everywhere[0] = np.sqrt(4 * np.pi)  # v = 1
    assert masked_distance(f, g, everywhere, everywhere) == pytest.approx(
        coefficient_distance(f, g) / (4 * np.pi), rel=1e-12
    )


def test_masked_view_rotates_with_its_view():
    rng = np.random.default_rng(21)
    f, g = rng.standard_normal((2, n_coefficients(8)))
    vf = cap_visibility(4, np.array([0.0, 0.0, 1.0]), 1.6)
    vg = cap_visibility(4, np.array([0.0, 0.2, 1.0]), 1.6)
    matrix = Rotation.from_rotvec([0.1, -0.3, 0.8]).as_matrix()
    by_terms = masked_distance_views(
        MaskedView.from_coefficients(f, vf).rotated(matrix), MaskedView.from_coefficients(g, vg)
    )
    direct = masked_distance(rotate(f, matrix), g, rotate(vf, matrix), vg)
    assert by_terms == pytest.approx(direct, rel=1e-11)


def test_masked_distance_ignores_what_only_one_view_sees():
    # the views agree on the upper cap and differ only where visibility g is (nearly) zero
    degree = 12
    quadrature = grid(24)
    z = quadrature.directions()[..., 2]
    common = quadrature.analysis(np.cos(3 * z))[: n_coefficients(degree)]
    extra = quadrature.analysis(np.where(z < -0.2, (z + 0.2) ** 4, 0.0))[: n_coefficients(degree)]
    v = quadrature.analysis(np.where(z > 0.3, (z - 0.3) ** 4, 0.0))[: n_coefficients(8)]
    masked = masked_distance(common, common + extra, v, v)
    full = coefficient_distance(common, common + extra) / (4 * np.pi)
    assert masked < 1e-4 * full


FEATURELESS_FOV = np.radians(200.0)  # rad: the bundled recordings' fish-eye


def featureless_masks(camera) -> dict[str, np.ndarray]:
    """Return fish-eye masks (uint8, 255 sky) of views with little or nothing to see, and one with a skyline."""
    up = camera.pixel_directions()[..., 2]
    circle = camera.image_circle()
    azimuth = np.arctan2(*camera.pixel_directions()[..., 1::-1].transpose(2, 0, 1))
    return {
        name: (sky & circle).astype(np.uint8) * 255
        for name, sky in {
            'sky': np.ones_like(circle),
            'ground': np.zeros_like(circle),
            'open field': up > np.sin(np.radians(1.5)),  # a level horizon, nothing on it
            'skyline': up > np.sin(np.radians(20 + 15 * np.sin(3 * azimuth))),
        }.items()
    }


@pytest.mark.parametrize('fill', ['zero', 'mean', 'mirror'])
def test_sky_share_tells_views_without_a_skyline_from_views_with_one(fill):
    from skynav_core.camera import EquidistantCamera
    from skynav_sh.fisheye import FisheyeTransform

    camera = EquidistantCamera.for_field_of_view(160, 120, FEATURELESS_FOV)
    transform = FisheyeTransform(camera, 16, fill=fill)
    masks = featureless_masks(camera)
    # sky shares of solid angle (not of pixels: a fish-eye's pixels are not of equal area)
    expected = {'sky': 1.0, 'ground': 0.0, 'open field': cap_area(np.radians(88.5)) / cap_area(np.radians(100))}
    for name, mask in masks.items():
        share = message_sky_share(transform(mask), camera.field_of_view, fill)
        if name in expected:
            assert share == pytest.approx(expected[name], abs=0.03 if fill == 'mirror' else 0.005), name
        assert shows_skyline(share) == (name in ('open field', 'skyline')), (name, share)
    assert message_sky_share(transform(masks['ground']), camera.field_of_view, fill) == pytest.approx(0, abs=1e-9)


def test_seen_mean_of_masked_terms_and_the_edges_of_the_test():
    g = grid(16)
    seen = g.analysis((g.directions()[..., 2] > -0.2).astype(float))  # a cap, as band-limited coefficients
    for value in (0.0, 1.0, 0.4):
        assert seen_mean(value * seen, seen) == pytest.approx(value, abs=1e-12)
    np.testing.assert_allclose(seen_mean(np.stack([seen, 0.5 * seen]), np.stack([seen, seen])), [1.0, 0.5])
    assert seen_mean(seen, np.zeros_like(seen)) == 0.0  # sees nothing: no division by zero
    assert not shows_skyline(MIN_CLASS_SHARE / 2) and not shows_skyline(1 - MIN_CLASS_SHARE / 2)
    assert shows_skyline(MIN_CLASS_SHARE) and shows_skyline(0.5)
    np.testing.assert_array_equal(shows_skyline(np.array([0.0, 0.5, 1.0])), [False, True, False])
    assert cap_area(np.pi) == pytest.approx(4 * np.pi) and cap_area(np.pi / 2) == pytest.approx(2 * np.pi)
    # an unknown field of view (0 in a message) counts as the whole sphere: c_00 = share sqrt(4 pi)
    assert message_sky_share(np.array([0.5 * np.sqrt(4 * np.pi)]), 0.0) == pytest.approx(0.5)
