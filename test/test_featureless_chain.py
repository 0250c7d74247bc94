# SPDX-License-Identifier: Apache-2.0
"""A featureless view (all sky, all ground, an open field) is a normal input everywhere in the chain.

Cores: the skyline segmentation gives a mask or one clear ValueError; the SH transform and the place descriptors
stay finite (a mask with no edge has the zero descriptor); the compass gives a finite rotation; 3D-warping gives
a finite result and no confidence where a view or the snapshot shows no skyline. The node graph (`skynav run`
over synthetic featureless recordings with their own maps): every output finite, nothing accepted, estimated or
homed on where there is nothing to see, every refusal counted.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from skynav_core.camera import EquidistantCamera
from skynav_core.names import COMPASS_ORIENTATION, HOME_VECTOR, LOCALIZATION_MATCH
from skynav_core.recording.bag import open_bag
from skynav_testing import run_skynav, write_featureless_recording

FOV = np.radians(200.0)  # rad: the bundled recordings' fish-eye
DEGREE = 16


@pytest.fixture(scope='module')
def camera():
    return EquidistantCamera.for_field_of_view(320, 240, FOV)


@pytest.fixture(scope='module')
def masks(camera):
    """Fish-eye masks (uint8, 255 sky): no skyline (sky, ground), a level horizon (open field), and a real skyline."""
    directions = camera.pixel_directions()
    up, azimuth = directions[..., 2], np.arctan2(directions[..., 1], directions[..., 0])
    circle = camera.image_circle()
    return {
        name: (sky & circle).astype(np.uint8) * 255
        for name, sky in {
            'sky': np.ones_like(circle),
            'ground': np.zeros_like(circle),
            'open field': up > np.sin(np.radians(1.5)),
            'skyline': up > np.sin(np.radians(20 + 15 * np.sin(3 * azimuth))),
        }.items()
    }


@pytest.fixture(scope='module')
def coefficients(camera, masks):
    from skynav_sh.fisheye import FisheyeTransform

    transform = FisheyeTransform(camera, DEGREE, fill='zero')
    return {name: transform(mask) for name, mask in masks.items()}


@pytest.mark.parametrize('levels', [(80, 43), (5, 20), (0, 0), (255, 255)])
def test_skyline_of_a_uniform_image_is_a_mask_or_one_clear_error(camera, levels):
    from skynav_skyline.exposure import ExposureError
    from skynav_skyline.segment import SkylineParams, SkylineSegmenter

    circle = camera.image_circle()
    uv, green = ((np.full(circle.shape, level) * circle).astype(np.uint8) for level in levels)
    for params in (SkylineParams(), SkylineParams(channels='uv-green')):
        try:
            mask = SkylineSegmenter(camera, params).segment(uv, green, 'mono8', 'mono8')
        except ExposureError as exc:  # all dark or all saturated: refused for its exposure, in one line
            assert '\n' not in str(exc) and exc.reason in ('overexposed', 'underexposed') and levels[0] in (0, 255)
        except ValueError as exc:
            assert '\n' not in str(exc) and 'trusted pixels' in str(exc)
        else:
            assert mask.shape == circle.shape and set(np.unique(mask)) <= {0, 255}


def test_sh_and_descriptors_of_views_without_a_skyline_are_finite(coefficients):
    from skynav_localize.descriptors import describe
    from skynav_sh.product import message_sky_share, shows_skyline

    with warnings.catch_warnings():
        warnings.simplefilter('error')  # no division by zero, no invalid value anywhere
        for name, c in coefficients.items():
            assert np.all(np.isfinite(c)), name
            for descriptor in ('amplitude', 'bispectrum'):
                d = describe(descriptor, c, DEGREE)
                assert np.all(np.isfinite(d)), (name, descriptor)
                assert np.linalg.norm(d) == pytest.approx(0.0 if name == 'ground' else 1.0, abs=1e-9)
            assert shows_skyline(message_sky_share(c, FOV)) == (name in ('open field', 'skyline')), name
    np.testing.assert_array_equal(coefficients['ground'], 0.0)


def test_compass_and_warping_cores_give_finite_answers_and_no_confidence_without_a_skyline(coefficients):
    from skynav_compass.compass import Compass
    from skynav_compass.views import CompassView
    from skynav_warping.homing import estimate_home_vector
    from skynav_warping.views import view_from_coefficients

    compass = Compass(DEGREE)
    blank = ('sky', 'ground')
    for snapshot_name, snapshot in coefficients.items():
        for current_name, current in coefficients.items():
            pair = (snapshot_name, current_name)
            estimate = compass.estimate(
                CompassView.from_sh_message(snapshot, FOV, 'zero', DEGREE),
                CompassView.from_sh_message(current, FOV, 'zero', DEGREE),
            )
            np.testing.assert_allclose(estimate.matrix @ estimate.matrix.T, np.eye(3), atol=1e-9)
            assert np.isfinite(estimate.residual), pair
            home = estimate_home_vector(
                view_from_coefficients(current, FOV, DEGREE), view_from_coefficients(snapshot, FOV, DEGREE)
            )
            assert np.all(np.isfinite(home.best_direction)) and np.all(np.isfinite(home.rotation)), pair
            assert np.isfinite(home.residual) and 0.0 <= home.confidence <= 1.0, pair
            if snapshot_name in blank or current_name in blank:
                assert home.confidence == 0.0 and not home.confident, pair
                np.testing.assert_array_equal(home.direction, 0.0)


def outputs(path: Path) -> dict[str, list]:
    """Return the messages of every output topic of a `skynav run` recording."""
    found: dict[str, list] = {}
    with open_bag(path) as bag:
        wanted = [t for t in (LOCALIZATION_MATCH, COMPASS_ORIENTATION, HOME_VECTOR) if t in bag.topics]
        for raw in bag.messages(wanted):
            found.setdefault(raw.topic, []).append(bag.deserialize(raw))
    return found


def finite_fields(message) -> bool:
    """Return whether every float of a (rosbags) message is finite; a PlaceMatch's distance may be +inf."""
    import dataclasses

    values = []
    for field in dataclasses.fields(message):
        value = getattr(message, field.name)
        if dataclasses.is_dataclass(value):
            if not finite_fields(value):
                return False
        elif isinstance(value, float | np.ndarray):
            values.append(np.asarray(value, dtype=float).ravel())
    return all(np.all(~np.isnan(v)) for v in values)


@pytest.mark.parametrize('kind', ['sky', 'open-field'])
def test_the_node_graph_over_a_featureless_drive_with_its_own_map(kind, tmp_path):
    bag = write_featureless_recording(tmp_path / f'synthetic_featureless_{kind}.mcap', kind, frames=30)
    built = run_skynav('map', 'build', str(bag), '--out', str(tmp_path / 'map.db'))
    assert built.returncode == 0, built.stderr
    ran = run_skynav('run', str(bag), '--map', str(tmp_path / 'map.db'), '--out', str(tmp_path / 'run.mcap'))
    assert ran.returncode == 0 and 'Traceback' not in ran.stderr, ran.stderr
    found = outputs(tmp_path / 'run.mcap')
    matches = found[LOCALIZATION_MATCH]
    assert len(matches) == 30 and all(finite_fields(m) for m in matches)
    for topic in (COMPASS_ORIENTATION, HOME_VECTOR):
        assert all(finite_fields(m) for m in found.get(topic, []))
    if kind == 'sky':  # the skyline node reads a uniform image as one class: no skyline anywhere
        assert not any(m.accepted for m in matches)
        assert found.get(COMPASS_ORIENTATION, []) == [] and found.get(HOME_VECTOR, []) == []
    else:  # a level horizon: a skyline, but one alike everywhere on the drive
        assert all(0.0 <= h.residual <= 1.0 for h in found.get(HOME_VECTOR, []))
        # and alike at every yaw: whatever the compass estimates, it is not sure of it
        estimates = found.get(COMPASS_ORIENTATION, [])
        assert estimates and not any(e.confident for e in estimates), [(e.confidence, e.confident) for e in estimates]
