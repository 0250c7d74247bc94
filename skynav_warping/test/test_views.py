# SPDX-License-Identifier: Apache-2.0
"""Masked terms of partly seen views: visibility, taper and the masked cost they give."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from skynav_core.camera import EquidistantCamera
from skynav_sh.fisheye import FisheyeTransform
from skynav_sh.transform import grid
from skynav_warping import WarpingSettings, hypothesis_costs, view_from_coefficients, view_from_fisheye, warping_tables
from skynav_warping.eval.synthetic import blob_scene, render_equal_distance_view
from skynav_warping.views import cap_fraction, rim_weights


def test_cap_fraction_integrates_to_the_cap_area():
    quadrature = grid(20)
    theta_max = np.radians(100.0)
    area = np.sum(quadrature.weights * cap_fraction(quadrature, theta_max))
    assert abs(area - 2 * np.pi * (1 - np.cos(theta_max))) < 1e-12


def test_rim_taper_falls_from_one_to_zero():
    theta_max, taper = np.radians(100.0), np.radians(10.0)
    weights = rim_weights(np.radians([0.0, 89.9, 95.0, 100.0, 120.0]), theta_max, taper)
    np.testing.assert_allclose(weights, [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-9)
    assert np.all(rim_weights(np.radians([0.0, 99.0]), theta_max, 0.0) == 1.0)


def masked_cost_by_quadrature(first, second, rotation, degree):
    """Mean of (f - g)^2 where both see, f turned by R (f(R^T d)), on a fine grid from the truncated terms."""
    quadrature = grid(2 * degree + 4)
    d = quadrature.directions()
    turned = d @ np.asarray(rotation)  # R^T d as row vectors
    f_v, f_vf, _ = (quadrature.synthesis_at(term, turned) for term in first.terms)
    g_v, g_vf, _ = (quadrature.synthesis_at(term, d) for term in second.terms)
    seen = (f_v > 0.05) & (g_v > 0.05)
    f = np.divide(f_vf, f_v, out=np.zeros_like(f_v), where=seen)
    g = np.divide(g_vf, g_v, out=np.zeros_like(g_v), where=seen)
    weight = quadrature.weights * np.where(seen, f_v * g_v, 0.0)  # integral of v_f v_g (f - g)^2 over v_f v_g
    return np.sum(weight * (f - g) ** 2) / np.sum(weight)


def test_identical_views_cost_nothing_and_turned_ones_cost_their_difference():
    settings = WarpingSettings()
    tables = warping_tables(settings).fine
    scene = blob_scene(2)
    view = render_equal_distance_view(scene, np.zeros(3), np.eye(3), degree=settings.degree)
    up = np.array([[0.0, 0.0, 1.0]])
    same = hypothesis_costs(tables, view.terms, view.terms, up, np.array([0]), np.eye(3)[None])
    turn = Rotation.from_euler('zx', [40.0, 8.0], degrees=True).as_matrix()
    turned = hypothesis_costs(tables, view.terms, view.terms, up, np.array([0]), turn[None])
    # identical views: the truncated products leave a small floor (exact products would give 0), here ~2 % of
    # what a 40-degree turn costs
    assert abs(same[0]) < 0.03 * turned[0]
    # the cost of the turned pair is the masked mean squared difference where both see (the truncated terms
    # differ from exact products, so this agrees to ~10 %, not to rounding)
    reference = masked_cost_by_quadrature(view, view, turn, settings.degree)
    assert abs(turned[0] - reference) < 0.15 * reference


def test_fisheye_and_coefficient_paths_agree():
    camera = EquidistantCamera.for_field_of_view(320, 240, np.radians(200))
    transform = FisheyeTransform(camera, 16, fill='zero')
    v, u = np.mgrid[0:240, 0:320]
    mask = ((u - 160.0) ** 2 + (v - 100.0) ** 2 < 60.0**2).astype(np.uint8) * 255  # a round patch of sky
    from_image = view_from_fisheye(transform, mask)
    from_coefficients = view_from_coefficients(transform.coefficients(mask), camera.field_of_view, 16)
    # v agrees (same cap, same taper); v f and v f^2 of the coefficient path carry the ringing of the band-limited
    # mask (f^2 most: measured 0.08 %, 2.2 % and 10.5 % relative differences)
    for a, b, tolerance in zip(from_image.terms, from_coefficients.terms, (0.01, 0.05, 0.15)):
        assert np.linalg.norm(a - b) < tolerance * np.linalg.norm(a)
    # seen solid angle: between the caps up to the taper's start and up to the image circle
    inner, outer = (2 * np.pi * (1 - np.cos(t)) for t in (camera.theta_max - np.radians(10.0), camera.theta_max))
    assert inner < from_image.seen_area < outer
