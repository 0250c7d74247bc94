# SPDX-License-Identifier: Apache-2.0
"""The fish-eye model and the renderer's geometry: round trips, the zenith, forward and left."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_core.camera import EquidistantCamera, angles_from_directions
from skynav_sim.materials import Surface
from skynav_sim.primitives import ConvexPolytope, Ellipsoid
from skynav_sim.render import CameraPose, Renderer
from skynav_sim.sky import Sky

DISTORTIONS = [(0.0, 0.0, 0.0, 0.0), (0.015, -0.002, 0.0, 0.0), (0.03, -0.006, 0.0008, -0.00005)]


@pytest.mark.parametrize('fov', [180.0, 200.0, 220.0])
@pytest.mark.parametrize('k', DISTORTIONS)
def test_pixel_ray_pixel_round_trip_over_the_image_circle(fov, k):
    camera = EquidistantCamera.for_field_of_view(640, 480, np.radians(fov), k)
    pixels = camera.pixel_grid()[camera.image_circle()]
    theta, _ = angles_from_directions(camera.unproject(pixels))
    assert theta.max() > np.radians(fov / 2) - 0.01  # the rim beyond 90 degrees is covered
    assert np.abs(camera.project(camera.unproject(pixels)) - pixels).max() < 0.01


def test_contract_projection_formula():
    camera = EquidistantCamera(640, 480, 120.0, 118.0, 321.3, 238.7, (0.02, -0.003, 0.0004, -0.00002))
    theta, phi = np.radians(100.0), np.radians(30.0)
    d = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    theta_d = theta * (1 + 0.02 * theta**2 - 0.003 * theta**4 + 0.0004 * theta**6 - 0.00002 * theta**8)
    assert camera.project(d) == pytest.approx(
        [321.3 + 120.0 * theta_d * np.cos(phi), 238.7 + 118.0 * theta_d * np.sin(phi)]
    )


def test_image_circle_follows_the_contract():
    camera = EquidistantCamera(640, 480, 150.0, 150.0, 300.0, 250.0, (0.0, 0.0, 0.0, 0.0))
    # theta_d_max = min(300, 339, 250, 229) / 150 pixels from the principal point.
    assert camera.theta_max == pytest.approx(229 / 150)
    circle = camera.image_circle()
    assert circle[250, 300] and circle[250 + 229, 300] and not circle[250, 300 + 231]


def _object_pixels(make_flat_world, primitive, rotation=None):
    """Return the camera and the (rows, cols) where a primitive hides the sky of an otherwise empty world."""
    camera = EquidistantCamera.for_field_of_view(160, 120, np.radians(200))
    pose = CameraPose(np.array([0.0, 0.0, 0.3]), rotation or Rotation.identity())
    empty = Renderer(make_flat_world([]), camera).render(pose, Sky(12.0))
    view = Renderer(make_flat_world([primitive]), camera).render(pose, Sky(12.0))
    return camera, np.nonzero(empty.sky & ~view.sky)


def test_zenith_renders_at_the_principal_point(make_flat_world):
    # A small ball 10 m straight above the camera.
    camera, (rows, cols) = _object_pixels(
        make_flat_world, Ellipsoid(np.array([0.0, 0.0, 10.3]), np.full(3, 1.0), 0.0, Surface.FOLIAGE)
    )
    assert len(rows) > 10
    assert cols.mean() == pytest.approx(camera.cx, abs=0.5) and rows.mean() == pytest.approx(camera.cy, abs=0.5)


@pytest.mark.parametrize(('where', 'side'), [((6.0, 0.0), 'right'), ((0.0, 6.0), 'down')])
def test_forward_is_image_right_and_left_is_image_down(make_flat_world, where, side):
    # A tall box 6 m ahead (+x, robot forward) or to the left (+y) of a level camera.
    box = ConvexPolytope.box(np.array([*where, 3.0]), np.array([0.5, 0.5, 3.0]), 0.0, Surface.BRICK)
    camera, (rows, cols) = _object_pixels(make_flat_world, box)
    u, v = cols.mean() - camera.cx, rows.mean() - camera.cy
    if side == 'right':
        assert u > 20 and abs(v) < 2
    else:
        assert v > 20 and abs(u) < 2


def test_a_turned_camera_sees_the_world_turned(make_flat_world):
    # Turning the robot 90 degrees left brings the box ahead to its right side: image-up (-v).
    box = ConvexPolytope.box(np.array([6.0, 0.0, 3.0]), np.array([0.5, 0.5, 3.0]), 0.0, Surface.BRICK)
    camera, (rows, cols) = _object_pixels(make_flat_world, box, Rotation.from_euler('z', 90, degrees=True))
    assert rows.mean() - camera.cy < -20 and abs(cols.mean() - camera.cx) < 2
