# SPDX-License-Identifier: Apache-2.0
"""The compass on real skylines: Debian's stellarium-data landscapes under the synthetic sky, rendered at test time.

For each real landscape a compass set (seed 2, held out from the choices made on seed 1: the tilt bound, the sample
grid, the confidence's scale) of rotations at the snapshot's place (any yaw, tilt up to 30 degrees) and views moved
0.1-0.5 m goes through the skyline and SH nodes as `skynav eval compass` runs them; once with every frame in the
morning, once with the snapshot taken at noon. The issue's targets hold at SH degree 32: median error under 1 degree
and 90th percentile under 3 degrees for the rotations of guereins, hurricane and geneva (snapshot and views at the
same time of day), not of garching, whose skyline lies below the horizontal (PRECISE below). At the shipped degree
16 a skyline 0-10 degrees above the rim of the fish-eye (garching, geneva) is blurred into the rim and the compass
misses those targets there, but at every degree and time no estimate tilts the views further apart than 90 degrees,
and the confidence separates estimates under 5 degrees of error from the others (ROC AUC at least 0.9 over all
sets). The images are synthetic renderings of real photographs; the test skips with one line where the package
cannot be fetched.
"""

from __future__ import annotations

import numpy as np
import pytest

from skynav_compass.eval.evaluation import RIGHT_DEG, error_statistics, roc_auc
from skynav_compass.eval.recording import evaluate_recording

pytestmark = pytest.mark.heavy(60)

LANDSCAPES = ('garching', 'guereins', 'hurricane', 'geneva')
SEED = 2
COUNT = 20  # rotations, and as many moved views, per landscape
DEGREE = 32  # of the targets
DEGREES = (16, 32)
TIMES = ('same', 'noon')  # the snapshot's time of day: the views' (morning), or noon


@pytest.fixture(scope='module')
def evaluations(stellarium, tmp_path_factory):
    """Return the compass evaluations {(landscape, snapshot time, SH degree): evaluation}, rendered at 320x240."""
    from skynav_core.camera import EquidistantCamera
    from skynav_core.cli import graph_arguments
    from skynav_sim import recording
    from skynav_sim.cli.options import DEFAULT_DISTORTION
    from skynav_sim.scenarios import ScenarioParameters, build, describe
    from skynav_sim.sky import TIMES_OF_DAY
    from skynav_sim.world import generate

    folder = tmp_path_factory.mktemp('real_compass')
    arguments = {}
    for degree in DEGREES:
        params_file = folder / f'degree_{degree}.yaml'
        params_file.write_text(f'sh:\n  ros__parameters:\n    max_degree: {degree}\n')
        arguments[degree] = graph_arguments(params_file, None)
    distortion = tuple(float(k) for k in DEFAULT_DISTORTION.split(','))
    camera = EquidistantCamera.for_field_of_view(320, 240, np.radians(200.0), distortion)
    out = {}
    for time in TIMES:
        params = ScenarioParameters(
            hours=TIMES_OF_DAY['morning'],
            count=COUNT,
            max_tilt=30.0,
            max_translation=0.5,
            reference_hours=None if time == 'same' else TIMES_OF_DAY[time],
        )
        for name in LANDSCAPES:
            world = generate(name, SEED)
            frames = build('compass', world, params, SEED)
            path = folder / f'synthetic_{name}_{time}_compass.mcap'
            recording.write(
                path, world, camera, frames, 'mono8', SEED, describe('compass', world, params, SEED, frames)
            )
            for degree in DEGREES:
                out[name, time, degree] = evaluate_recording(path, ['fft-masked'], ros_args=arguments[degree])
    return out


# garching's skyline lies 2-8 degrees below the horizontal where Stellarium's landscape file puts it (the rape field
# photographed from above), inside the outer 10 degrees of the 200-degree field of view: a camera tilted 10-30
# degrees loses it on one side, and what is left is a sliver thinner than degree 32 resolves. The compass misses the
# targets there even on the ground-truth masks (seed 2, degree 32: median 1.8, 90th percentile 165 degrees;
# `bench/compass.py --bags`), so garching is held only to the bounds every landscape meets (the tests below).
PRECISE = ('guereins', 'hurricane', 'geneva')


@pytest.mark.parametrize('name', PRECISE)
def test_the_compass_holds_on_real_skylines(evaluations, name):
    evaluation = evaluations[name, 'same', DEGREE]
    assert evaluation.max_degree == DEGREE
    rotations = evaluation.statistics('fft-masked', 'rotation')
    assert rotations.count == COUNT
    assert np.max(evaluation.tilts[evaluation.groups['rotation']]) > 25.0  # the set tilts the camera as asked
    assert rotations.median < 1.0, evaluation.result('fft-masked').errors
    assert rotations.p90 < 3.0, evaluation.result('fft-masked').errors


def test_no_estimate_turns_the_camera_over(evaluations):
    for key, evaluation in evaluations.items():
        assert np.all(evaluation.result('fft-masked').tilts <= 90.0), key  # rotations and moved views
        assert evaluation.max_degree == key[2]


def test_the_confidence_separates_right_estimates_from_wrong_ones(evaluations):
    """Over every set (landscapes, times, degrees; rotations and moved views), and within each degree."""
    for degrees in (DEGREES, *((d,) for d in DEGREES)):
        results = [e.result('fft-masked') for key, e in evaluations.items() if key[2] in degrees]
        errors = np.concatenate([r.errors for r in results])
        confidence = np.concatenate([r.confidence for r in results])
        assert error_statistics(errors).count == len(results) * 2 * COUNT
        assert np.all((confidence >= 0) & (confidence <= 1))
        right = errors < RIGHT_DEG
        assert 0 < np.sum(~right) < np.sum(right), degrees  # some wrong estimates to tell apart, most right
        assert roc_auc(confidence, right) >= 0.9, degrees
