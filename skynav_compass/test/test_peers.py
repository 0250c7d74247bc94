# SPDX-License-Identifier: Apache-2.0
"""The exhaustive baseline, the yaw-only visual compass and the feature compass; view construction."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_compass import (
    CompassView,
    ExhaustiveCompass,
    ExhaustiveConfig,
    FeatureCompass,
    PanoramicCompass,
    YawCompass,
    cap_visibility,
    decompose_essential,
    eight_point,
    estimate_rotation,
    kabsch,
    load_compass_set,
)
from skynav_core.camera import EquidistantCamera
from skynav_core.rotations import rotation_angle
from skynav_sh.basis import degree_order
from skynav_sh.fisheye import FisheyeTransform
from skynav_sh.rotation import rotate

BAGS = Path(__file__).resolve().parents[2] / 'bags'
DEGREE = 10


def band_limited(seed: int, degree: int = DEGREE) -> np.ndarray:
    l, _ = degree_order(degree)
    return np.random.default_rng(seed).standard_normal(l.size) / (1.0 + l)


@pytest.fixture(scope='module')
def garden():
    path = BAGS / 'synthetic_garden_compass.mcap'
    return load_compass_set(path)


@pytest.mark.parametrize('cost', ['plain', 'masked'])
def test_exhaustive_search_finds_the_rotation_to_its_final_step(cost):
    f = band_limited(1)
    truth = Rotation.from_euler('ZYZ', [50.0, 20.0, -75.0], degrees=True)
    config = ExhaustiveConfig(cost=cost, max_tilt=np.radians(40), final_step=np.radians(0.05))
    snapshot, current = rotate(f, truth), f
    if cost == 'masked':
        snapshot, current = CompassView.from_coefficients(snapshot), CompassView.from_coefficients(current)
    estimate = ExhaustiveCompass(DEGREE, config).estimate(snapshot, current)
    assert np.degrees(rotation_angle(estimate.matrix, truth.as_matrix())) < 0.1
    assert estimate.details['evaluated_rotations'] > 1000


def test_exhaustive_search_respects_the_tilt_limit():
    f = band_limited(2)
    truth = Rotation.from_euler('ZYZ', [10.0, 60.0, 30.0], degrees=True)  # tilt 60 deg, outside a 30 deg limit
    estimate = ExhaustiveCompass(
        DEGREE, ExhaustiveConfig(cost='plain', max_tilt=np.radians(30), final_step=np.radians(1.0))
    ).estimate(rotate(f, truth), f)
    assert np.degrees(estimate.euler_zyz[1]) < 45.0


def test_yaw_compass_on_sh_recovers_a_yaw_and_ignores_tilt():
    f = band_limited(3)
    truth = Rotation.from_euler('z', -70.0, degrees=True)
    estimate = YawCompass(DEGREE, cost='plain').estimate(rotate(f, truth), f)
    assert np.degrees(estimate.rotation.as_rotvec()) == pytest.approx([0.0, 0.0, -70.0], abs=1e-6)
    tilted = YawCompass(DEGREE, cost='plain').estimate(rotate(f, Rotation.from_euler('x', 15, degrees=True)), f)
    assert np.allclose(tilted.matrix[2], [0.0, 0.0, 1.0])  # a yaw-only result


def test_panoramic_compass_recovers_a_yaw_of_a_turned_mask(garden):
    import cv2

    camera = garden.camera
    truth = Rotation.from_euler('z', 33.0, degrees=True)  # the camera turned by +33 deg about its own z
    source = camera.project(truth.apply(camera.pixel_directions().reshape(-1, 3))).reshape(
        camera.height, camera.width, 2
    )
    mask = garden.masks[0]
    turned = cv2.remap(mask, source[..., 0].astype(np.float32), source[..., 1].astype(np.float32), cv2.INTER_LINEAR)
    estimate = PanoramicCompass(camera).estimate(mask, turned)
    assert np.degrees(estimate.rotation.as_rotvec()[2]) == pytest.approx(33.0, abs=0.5)


def test_kabsch_and_essential_on_synthetic_bearings():
    rng = np.random.default_rng(4)
    truth = Rotation.from_euler('ZYX', [40.0, 10.0, -20.0], degrees=True).as_matrix()
    points = rng.normal(size=(60, 3)) * 3.0 + np.array([0.0, 0.0, 2.0])  # scene around the cameras, in all directions
    d_c = points / np.linalg.norm(points, axis=1, keepdims=True)
    assert np.allclose(kabsch(d_c, d_c @ truth.T), truth, atol=1e-12)
    t = np.array([0.3, -0.2, 0.05])  # current camera's position in the snapshot frame
    in_snapshot = points @ truth.T + t  # X_s = R X_c + t
    d_s = in_snapshot / np.linalg.norm(in_snapshot, axis=1, keepdims=True)
    essential = eight_point(d_s, d_c)
    assert np.abs(np.einsum('ni,ij,nj->n', d_s, essential, d_c)).max() < 1e-10
    rotation, direction = decompose_essential(essential, d_s, d_c)
    assert np.allclose(rotation, truth, atol=1e-9)
    assert np.allclose(direction, t / np.linalg.norm(t), atol=1e-9)


def test_feature_compass_on_a_rendered_rotation(garden):
    compass = FeatureCompass(garden.camera)
    frame = [i for i in garden.queries if garden.labels[i] == 'rotation'][0]
    estimate = compass.estimate(garden.uv[garden.reference], garden.uv[frame])
    truth = garden.true_rotations()[frame]
    assert np.degrees(rotation_angle(estimate.matrix, Rotation.from_quat(truth).as_matrix())) < 2.0
    assert estimate.details['inliers'] >= 10 and estimate.confident


def test_views_from_sh_messages_undo_the_mean_fill_exactly(garden):
    """A skyline message filled with the mean carries v f (v f = f - mu (1 - v)): the same view as the zero fill.

    Exact but for the visibility: the message's cap is analytic, the transform's is its grid's (measured largest
    coefficient differences 3e-3 and 8e-3 against values up to 2).
    """
    camera = garden.camera
    mask = garden.masks[0]
    zero = FisheyeTransform(camera, DEGREE, 'zero')
    mean = FisheyeTransform(camera, DEGREE, 'mean')
    fov = 2 * camera.theta_max
    from_zero = CompassView.from_sh_message(zero.coefficients(mask), fov, 'zero')
    from_mean = CompassView.from_sh_message(mean.coefficients(mask), fov, 'mean')
    assert np.allclose(from_zero.weighted, from_mean.weighted, atol=1e-2)
    # the analytic cap equals the transform's cell-exact visibility up to the grid's quadrature
    assert np.allclose(cap_visibility(DEGREE, camera.theta_max), zero.visibility_coefficients, atol=2e-2)
    image_view = CompassView.from_image(zero, mask)
    assert np.allclose(image_view.weighted, from_zero.weighted)
    estimate = estimate_rotation(from_zero, from_mean)
    assert np.degrees(rotation_angle(estimate.matrix, np.eye(3))) < 0.1


def test_grey_images_get_their_own_square_term():
    camera = EquidistantCamera.for_field_of_view(64, 48, np.radians(200))
    transform = FisheyeTransform(camera, 6, 'zero')
    image = (np.arange(64 * 48).reshape(48, 64) % 251).astype(np.uint8)
    grey = CompassView.from_image(transform, image)
    assert not np.allclose(grey.weighted, grey.weighted_square)
    binary = CompassView.from_image(transform, np.where(image > 120, 255, 0).astype(np.uint8))
    assert np.array_equal(binary.weighted, binary.weighted_square)
