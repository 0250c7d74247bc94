# SPDX-License-Identifier: Apache-2.0
"""Planar motion: arcs compose, a full circle comes back, and a ground pose's quaternion is its heading."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_core.motion import arc, ground_pose


@pytest.mark.parametrize('curvature', [0.0, 0.7, -2.0])
def test_two_arcs_of_one_curvature_are_one_arc(curvature):
    rng = np.random.default_rng(3)
    for _ in range(20):
        x, y, heading = rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi)
        first, second = rng.uniform(0, 2, 2)
        halfway = arc(x, y, heading, first, curvature * first)
        np.testing.assert_allclose(
            arc(*halfway, second, curvature * second),
            arc(x, y, heading, first + second, curvature * (first + second)),
            atol=1e-9,
        )


def test_a_full_circle_comes_back_and_a_straight_step_goes_along_the_heading():
    np.testing.assert_allclose(arc(1.0, 2.0, 0.3, 2 * math.pi * 0.5, 2 * math.pi), (1.0, 2.0, 0.3), atol=1e-9)
    np.testing.assert_allclose(arc(0.0, 0.0, math.pi / 2, 2.0, 0.0), (0.0, 2.0, math.pi / 2), atol=1e-12)
    assert arc(0.0, 0.0, 3.0, 0.0, 1.0)[2] == pytest.approx(4.0 - 2 * math.pi)  # the heading is wrapped


def test_a_ground_pose_is_turned_about_z_by_its_heading():
    pose = ground_pose(1.0, -2.0, 2.5)
    assert pose.shape == (7,) and tuple(pose[:3]) == (1.0, -2.0, 0.0)
    assert Rotation.from_quat(pose[3:]).as_euler('zyx')[0] == pytest.approx(2.5)
