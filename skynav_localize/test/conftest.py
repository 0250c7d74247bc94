# SPDX-License-Identifier: Apache-2.0
"""Shared test data: synthetic SH routes, and the bundled synthetic recordings turned into SH coefficients.

The recordings are read through skynav_core.recording.bag; SH coefficients come from the ground-truth sky masks
(FisheyeTransform, fill 'zero'), so these tests measure place recognition, not segmentation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from skynav_core.names import GROUND_TRUTH_MASK, GROUND_TRUTH_POSE, UV_CAMERA_INFO, UV_IMAGE
from skynav_sh.basis import degree_order, n_coefficients

BAGS = Path(__file__).resolve().parents[2] / 'bags'
BAG_DEGREE = 16  # SH degree L of the end-to-end tests


def random_view(degree: int, rng: np.random.Generator) -> np.ndarray:
    """Return random SH coefficients with a skyline-like spectrum (amplitude falling as 1 / (l + 1))."""
    l, _ = degree_order(degree)
    return rng.standard_normal(n_coefficients(degree)) / (l + 1.0)


def synthetic_route(count: int, degree: int, step: float, seed: int) -> np.ndarray:
    """Return (count, n) coefficients of views along a route: a random walk (step per snapshot) from a random view."""
    rng = np.random.default_rng(seed)
    start = random_view(degree, rng)
    l, _ = degree_order(degree)
    steps = rng.standard_normal((count, n_coefficients(degree))) * step / (l + 1.0)
    steps[0] = 0.0
    return start + np.cumsum(steps, axis=0)


@dataclass
class Recording:
    """What the tests need of one bundled recording, in stamp order."""

    stamps: np.ndarray  # (F,) ns
    coefficients: np.ndarray  # (F, (L+1)^2) from the ground-truth masks
    uv: np.ndarray  # (F, H, W) uint8
    poses: np.ndarray  # (F, 7) camera_link in map
    circle: np.ndarray  # (H, W) bool image circle
    camera: object


def read_recording(name: str, degree: int = BAG_DEGREE) -> Recording:
    """Read a bundled recording's masks, UV images and poses; SH coefficients from the ground-truth masks."""
    from skynav_core.camera import EquidistantCamera
    from skynav_core.recording.bag import open_bag
    from skynav_sh.fisheye import FisheyeTransform

    masks, uv, poses, info = {}, {}, {}, None
    with open_bag(BAGS / name) as bag:
        for raw in bag.messages([GROUND_TRUTH_MASK, UV_IMAGE, GROUND_TRUTH_POSE, UV_CAMERA_INFO]):
            msg = bag.deserialize(raw)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            if raw.topic == UV_CAMERA_INFO:
                info = msg
            elif raw.topic == GROUND_TRUTH_POSE:
                p, q = msg.pose.position, msg.pose.orientation
                poses[stamp] = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
            else:
                image = np.asarray(msg.data, dtype=np.uint8).reshape(msg.height, msg.width)
                (masks if raw.topic == GROUND_TRUTH_MASK else uv)[stamp] = image
    camera = EquidistantCamera.from_camera_info(info)
    transform = FisheyeTransform(camera, degree, fill='zero')
    stamps = np.array(sorted(masks), dtype=np.int64)
    return Recording(
        stamps,
        np.array([transform(masks[s]) for s in stamps]),
        np.array([uv[s] for s in stamps]),
        np.array([poses[s] for s in stamps], dtype=float),
        camera.image_circle(),
        camera,
    )


@pytest.fixture(scope='session')
def garden():
    """The bundled garden teach and repeat drives and the garden compass recording (off the route)."""
    return {part: read_recording(f'synthetic_garden_{part}.mcap') for part in ('teach', 'repeat', 'compass')}


@pytest.fixture
def make_route():
    """The synthetic_route function: (count, degree, step, seed) -> (count, n) coefficients along a route."""
    return synthetic_route


@pytest.fixture
def make_view():
    """The random_view function: (degree, rng) -> coefficients of an unrelated view (off any route)."""
    return random_view


@pytest.fixture
def featureless_recording(tmp_path):
    """(kind, frames) -> path of a synthetic featureless recording in tmp_path (skynav_testing)."""
    from skynav_testing import write_featureless_recording

    def write(kind: str, frames: int = 30) -> Path:
        return write_featureless_recording(tmp_path / f'synthetic_featureless_{kind}.mcap', kind, frames)

    return write


@pytest.fixture(scope='session')
def garden_map(tmp_path_factory):
    """The map of the bundled garden teach drive, as `skynav map build` writes it."""
    from skynav_testing import run_skynav

    path = tmp_path_factory.mktemp('maps') / 'garden.db'
    result = run_skynav('map', 'build', str(BAGS / 'synthetic_garden_teach.mcap'), '--out', str(path))
    assert result.returncode == 0, result.stderr
    return path


@pytest.fixture(scope='session')
def render_route():
    """Return render(folder, common, teach, repeat) -> (map store, repeat views): a teach and a repeat drive rendered by
    `skynav sim bag` (common options, then each drive's own), the map as `skynav map build` makes it, and the repeat
    drive's views as the skyline and SH nodes see them; the stores are closed at the end of the session."""
    from skynav_core.maps import MapStore
    from skynav_core.views import recording_views
    from skynav_testing import run_skynav

    stores = []

    def render(folder: Path, common: tuple, teach: tuple, repeat: tuple):
        teach_bag, repeat_bag, path = folder / 'teach.mcap', folder / 'repeat.mcap', folder / 'map.db'
        for scenario, options, out in (('teach', teach, teach_bag), ('repeat', repeat, repeat_bag)):
            result = run_skynav('sim', 'bag', scenario, *common, *options, '--out', str(out))
            assert result.returncode == 0, result.stderr
        result = run_skynav('map', 'build', str(teach_bag), '--out', str(path))
        assert result.returncode == 0, result.stderr
        stores.append(MapStore.open(path))
        return stores[-1], recording_views(repeat_bag, images=False)

    yield render
    for store in stores:
        store.close()


def accepted_figures(store, views, tolerance: float, acceptance=None):
    """Return the evaluation (skynav_localize.eval.evaluation) of the default method's accepted matches of a drive's
    views against a map, a match correct within `tolerance` m."""
    from skynav_localize.eval.evaluation import evaluate
    from skynav_localize.localizer import Localizer

    coefficients = np.stack([v.coefficients for v in views.views])
    positions = np.stack([v.pose[:3] for v in views.views])
    matches = Localizer(store, 'amplitude-seq', acceptance=acceptance).match_sequence(
        coefficients, field_of_view=views.views[0].field_of_view, fill=views.views[0].fill
    )
    return evaluate(
        'amplitude-seq', matches.index, matches.score, positions, store.positions(), tolerance, matches.accepted
    )


@pytest.fixture(scope='session')
def accepted():
    """Return accepted_figures (the default method's accepted matches of a drive, evaluated)."""
    return accepted_figures
