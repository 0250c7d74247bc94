# SPDX-License-Identifier: Apache-2.0
"""A snapshot prepared once (Compass.prepare, ExhaustiveCompass.prepare) gives the same estimates as the raw view.

Also the runner's NAME+prepared methods (the degree-first rotation the prepared path uses is tested against
rotate_by_matrix in skynav_sh/test/test_layouts.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_compass import (
    Compass,
    CompassConfig,
    CompassView,
    ExhaustiveCompass,
    ExhaustiveConfig,
    PreparedSnapshot,
    cap_visibility,
    load_compass_set,
    run_methods,
    standard_methods,
)
from skynav_sh.basis import degree_order
from skynav_sh.rotation import rotate

DEGREE = 10
BAGS = Path(__file__).resolve().parents[2] / 'bags'


def band_limited(seed: int, degree: int = DEGREE) -> np.ndarray:
    l, _ = degree_order(degree)
    return np.random.default_rng(seed).standard_normal(l.size) / (1.0 + l)


def views(kind: str, normalise: bool, count: int = 3):
    """Return a snapshot and `count` current views (turned and changed a little) for a cost kind."""
    world = band_limited(1)
    visibility = cap_visibility(DEGREE, np.radians(100))
    rotations = Rotation.random(count, random_state=5)
    rng = np.random.default_rng(9)
    currents = [rotate(world, r.inv()) + 0.02 * rng.standard_normal(world.size) for r in rotations]
    if kind == 'plain':
        return world, currents
    wrap = lambda f: CompassView.from_coefficients(f, visibility, max_degree=DEGREE)  # noqa: E731
    return wrap(world), [wrap(f) for f in currents]


@pytest.mark.parametrize('kind, normalise', [('masked', False), ('masked', True), ('plain', False), ('plain', True)])
def test_prepared_snapshot_gives_the_same_estimates(kind, normalise):
    compass = Compass(DEGREE, CompassConfig(cost=kind, normalise=normalise))
    snapshot, currents = views(kind, normalise)
    prepared = compass.prepare(snapshot)
    assert isinstance(prepared, PreparedSnapshot) and compass.prepare(prepared) is prepared
    for current in currents:  # one prepared snapshot, many current views
        cold, warm = compass.estimate(snapshot, current), compass.estimate(prepared, current)
        assert np.array_equal(cold.matrix, warm.matrix) and cold.residual == warm.residual
        assert [h.cost for h in cold.hypotheses] == [h.cost for h in warm.hypotheses]
        assert compass.cost(prepared, current, cold.matrix) == pytest.approx(cold.residual, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize('kind', ['masked', 'plain'])
def test_prepared_snapshot_for_the_exhaustive_search(kind):
    compass = ExhaustiveCompass(
        DEGREE, ExhaustiveConfig(cost=kind, max_tilt=np.radians(60), final_step=np.radians(0.5))
    )
    snapshot, currents = views(kind, False, 1)
    prepared = compass.prepare(snapshot)
    cold, warm = compass.estimate(snapshot, currents[0]), compass.estimate(prepared, currents[0])
    assert np.allclose(cold.matrix, warm.matrix, atol=1e-12) and cold.residual == pytest.approx(warm.residual)


def test_a_snapshot_prepared_for_another_setting_is_refused():
    snapshot, currents = views('masked', False, 1)
    prepared = Compass(DEGREE).prepare(snapshot)
    with pytest.raises(ValueError, match='prepared for the masked cost'):
        Compass(DEGREE, CompassConfig(normalise=True)).estimate(prepared, currents[0])
    with pytest.raises(ValueError, match='degree'):
        Compass(DEGREE - 2).estimate(prepared, currents[0])
    with pytest.raises(TypeError):
        Compass(DEGREE).prepare(band_limited(2))  # the masked cost needs a CompassView


def test_runner_prepares_the_snapshot_once_for_prepared_methods():
    path = BAGS / 'synthetic_mineral_compass.mcap'
    data = load_compass_set(path)
    runs = run_methods(data, standard_methods(data.camera, 8, ['fft-masked', 'fft-masked+prepared']), [1, 16])
    cold, warm = runs
    assert warm.result.method == 'fft-masked+prepared' and warm.snapshot_seconds > 0 and cold.snapshot_seconds == 0
    assert np.array_equal(cold.result.errors, warm.result.errors)
    with pytest.raises(ValueError, match='unknown methods'):
        standard_methods(data.camera, 8, ['visual-compass-sh+prepared'])
