# SPDX-License-Identifier: Apache-2.0
"""Camera models: pixel -> ray -> pixel round trips, axis conventions, OCamCalib files."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from skynav_core.camera import EquidistantCamera, OCamCamera, angles_from_directions, load_camera

CALIB = Path(__file__).parent / 'data' / 'calib_results.txt'  # made-up numbers, see the file's first line


@pytest.fixture(params=['equidistant', 'equidistant-distorted', 'ocam'])
def camera(request):
    if request.param == 'equidistant':
        return EquidistantCamera.for_field_of_view(640, 480, np.radians(200))
    if request.param == 'equidistant-distorted':
        return EquidistantCamera.for_field_of_view(320, 240, np.radians(190), k=(0.02, -0.01, 0.002, 0.0))
    return load_camera(CALIB)


def test_pixel_ray_pixel_round_trip(camera):
    inside = camera.image_circle()
    pixels = camera.pixel_grid()[inside]
    # OCamCalib projects with its fitted inverse polynomial: the fixture's fit is good to ~4e-4 px
    tolerance = 1e-3 if isinstance(camera, OCamCamera) else 1e-9
    np.testing.assert_allclose(camera.project(camera.unproject(pixels)), pixels, atol=tolerance)
    rays = camera.unproject(pixels)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0, atol=1e-12)


def test_ray_pixel_ray_round_trip(camera):
    rng = np.random.default_rng(30)
    theta = rng.uniform(0, camera.theta_max, 500)
    phi = rng.uniform(-np.pi, np.pi, 500)
    rays = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    back = camera.unproject(camera.project(rays))
    angle = np.linalg.norm(back - rays, axis=-1)  # chord = angle for small angles (arccos would lose 1e-8)
    assert angle.max() < (1e-5 if isinstance(camera, OCamCamera) else 1e-12)


def test_axes_follow_the_contract(camera):
    # principal point = zenith; +x (robot forward) = growing u (image right); +y (robot left) = growing v (down)
    centre = camera.project(np.array([0.0, 0.0, 1.0]))
    step = 0.3 * camera.height  # px, well inside the image circle
    right = camera.unproject(centre + np.array([step, 0.0]))
    down = camera.unproject(centre + np.array([0.0, step]))
    assert right[0] > 0.5 and abs(right[1]) < 0.01 and right[2] > 0
    assert down[1] > 0.5 and abs(down[0]) < 0.01 and down[2] > 0
    behind = camera.project(np.array([np.sin(1.7), 0.0, np.cos(1.7)]))  # below the horizon, still in the image
    assert behind[0] > centre[0] and abs(behind[1] - centre[1]) < 1.0


def test_image_circle_is_the_theta_max_disc(camera):
    theta, _ = angles_from_directions(camera.pixel_directions())
    inside = camera.image_circle()
    assert np.all(theta[inside] <= camera.theta_max)
    border = np.concatenate([theta[0], theta[-1], theta[:, 0], theta[:, -1]])
    assert border.min() >= camera.theta_max - 1e-12  # every border pixel is at or beyond the edge
    assert camera.field_of_view == pytest.approx(2 * camera.theta_max)
    narrower = camera.with_fov_limit(np.radians(120))
    assert narrower.theta_max == pytest.approx(np.radians(60))
    assert camera.with_fov_limit(np.radians(300)).theta_max == pytest.approx(camera.theta_max)


def test_ocam_file_is_read_with_its_conventions():
    camera = OCamCamera.from_calib_file(CALIB)
    assert (camera.width, camera.height) == (640, 480)
    assert len(camera.pol) == 5 and len(camera.invpol) == 13
    # the file's centre (row 242.3, column 319.6) is 1-based (Matlab): pixel (u, v) = (318.6, 241.3) is the zenith
    np.testing.assert_allclose(camera.project(np.array([0.0, 0.0, 1.0])), [318.6, 241.3], atol=1e-9)
    np.testing.assert_allclose(camera.unproject(np.array([318.6, 241.3])), [0.0, 0.0, 1.0], atol=1e-12)
    assert np.degrees(camera.field_of_view) == pytest.approx(212.7, abs=0.5)  # the made-up lens: ~212 degrees


def test_ocam_matches_ocamcalib_formulas_written_out():
    # cam2world of OCamCalib's C code on (row, column), then its frame mapped to camera_link (y, x, -z)
    camera = OCamCamera.from_calib_file(CALIB)
    row, column = 100.25, 500.5
    xp = (row - camera.xc - camera.d * (column - camera.yc)) / (camera.c - camera.d * camera.e)
    yp = (-camera.e * (row - camera.xc) + camera.c * (column - camera.yc)) / (camera.c - camera.d * camera.e)
    zp = np.polynomial.polynomial.polyval(np.hypot(xp, yp), camera.pol)
    ocam_ray = np.array([xp, yp, zp]) / np.linalg.norm([xp, yp, zp])
    np.testing.assert_allclose(camera.unproject(np.array([column, row])), ocam_ray[[1, 0, 2]] * [1, 1, -1], atol=1e-14)


def test_load_camera_dispatch():
    equidistant = EquidistantCamera.for_field_of_view(64, 48, np.radians(190))
    info = SimpleNamespace(**equidistant.camera_info_fields())
    assert load_camera(info) == equidistant
    assert load_camera(equidistant) is equidistant
    assert isinstance(load_camera(str(CALIB)), OCamCamera)
    with pytest.raises(TypeError):
        load_camera(3.0)


def test_bad_calib_files_are_refused(tmp_path):
    path = tmp_path / 'calib_results.txt'
    path.write_text('#pol\n5 1 2\n')
    with pytest.raises(ValueError):
        OCamCamera.from_calib_file(path)


def test_a_distorted_camera_reads_back_from_its_camera_info():
    # every distortion coefficient differs (a swap of any two changes the lens): the camera the skyline node builds
    # from the driver's CameraInfo sees the same image circle and puts every ray on the same pixel
    from sensor_msgs.msg import CameraInfo

    camera = EquidistantCamera.for_field_of_view(320, 240, np.radians(190), k=(0.05, -0.02, 0.004, -0.0005))
    info = CameraInfo()
    for key, value in camera.camera_info_fields().items():
        setattr(info, key, value)
    back = EquidistantCamera.from_camera_info(info)
    assert back.theta_max == pytest.approx(camera.theta_max, abs=1e-12)
    assert np.array_equal(back.image_circle(), camera.image_circle())
    rng = np.random.default_rng(4)
    theta = rng.uniform(0, camera.theta_max, 200)
    phi = rng.uniform(-np.pi, np.pi, 200)
    rays = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    np.testing.assert_allclose(back.project(rays), camera.project(rays), atol=1e-9)
