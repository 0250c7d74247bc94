# SPDX-License-Identifier: Apache-2.0
"""`skynav skyline train` and `skynav skyline eval` as a user runs them, on the bundled synthetic garden skyline set.

train learns the global separators from 1e5 labelled pixels and writes them as the skyline node's parameters; eval,
given that file, measures the global method over every pixel of the same 20 exposures. Measured: train reports
UV only 99.52 %, UV/green 99.61 %; eval of the written file 99.53 % and 99.61 %.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from skynav_testing import run_skynav

BAG = Path(__file__).resolve().parents[2] / 'bags' / 'synthetic_garden_skyline.mcap'
NUMBER = r'(-?[\d.]+)'


def test_train_writes_what_it_learned_and_eval_measures_the_same_rates(tmp_path):
    params = tmp_path / 'params.yaml'
    trained = run_skynav('skyline', 'train', str(BAG), '--out', str(params), '--max-pixels', '100000')
    assert trained.returncode == 0, trained.stderr
    report = re.search(
        rf'UV only t = {NUMBER} \({NUMBER} %\), UV/green a = {NUMBER} deg, t = {NUMBER} \({NUMBER} %\)', trained.stderr
    )
    assert report, trained.stderr
    threshold_uv, rate_uv, angle, threshold, rate_uv_green = (float(v) for v in report.groups())
    assert yaml.safe_load(params.read_text()) == {
        'skyline': {
            'ros__parameters': {
                'method': 'sector-min-error',
                'channels': 'uv-green',
                'angle_deg': angle,
                'threshold': threshold,
                'threshold_uv': threshold_uv,
            }
        }
    }
    assert min(rate_uv, rate_uv_green) >= 99.0
    plot = tmp_path / 'histogram.png'
    # the separators alone: without the fit check, which would hand a view the separators do not fit to the
    # image's own discriminant
    unchecked = tmp_path / 'unchecked.yaml'
    written = yaml.safe_load(params.read_text())
    written['skyline']['ros__parameters']['max_disagreement'] = float('inf')
    unchecked.write_text(yaml.safe_dump(written))
    evaluated = run_skynav(
        'skyline', 'eval', str(BAG), '--params', str(unchecked), '--methods', 'global', '--plot', str(plot)
    )
    assert evaluated.returncode == 0, evaluated.stderr
    overall = evaluated.stdout.split('all worlds', 1)[1]
    measured = {
        channels: float(mean)
        for channels, mean in re.findall(rf'global\s+(uv|uv-green)\s+on\s+\S+\s+{NUMBER}', overall)
    }
    # the sample's rate and every pixel's agree to 0.1 %: eval ran with the separators train wrote
    assert abs(measured['uv'] - rate_uv) <= 0.1 and abs(measured['uv-green'] - rate_uv_green) <= 0.1, measured
    assert '20 exposures' in evaluated.stdout and plot.stat().st_size > 0
