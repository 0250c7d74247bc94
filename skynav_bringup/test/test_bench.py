# SPDX-License-Identifier: Apache-2.0
"""`skynav bench`: the table's structure and that its figures agree with each other (no timing threshold)."""

import re

import pytest

from skynav_bringup.cli import main
from skynav_core.nodes import installed_nodes
from skynav_testing import BAGS

SMALLEST = min(BAGS.glob('*.mcap'), key=lambda path: path.stat().st_size)
ROW = re.compile(r'^(\S+) +(\d+) +([\d.]+) +([\d.]+|inf) +([\d.]+) %$')
ALL = re.compile(r'^all +([\d.]+) +([\d.]+|inf) +([\d.]+) %$')


def _consistent(ms: str, fps: str, share: str, rate: float) -> None:
    """fps = 1000 / ms and share = ms / camera period, within the printed rounding."""
    value = float(ms)
    assert value > 0, ms
    low, high = value - 0.005, value + 0.005  # ms printed to 2 decimals
    assert 1e3 / high - 0.05 <= float(fps) <= 1e3 / max(low, 1e-9) + 0.05, (ms, fps)
    assert abs(float(share) - value * rate / 10) <= 0.05 + 0.005 * rate / 10, (ms, share)


def test_bench_prints_a_consistent_table_per_node(capsys):
    rate = 12.5
    code = main(['bench', '--bag', str(SMALLEST), '--frames', '3', '--warmup', '1', '--rate', str(rate)])
    out = capsys.readouterr().out
    assert code == 0, out
    lines = out.splitlines()
    assert lines[0].startswith(f'skynav bench: {SMALLEST.name} (320x240), 3 frames timed after 1 of warm-up')
    assert lines[2].split() == ['node', 'calls', 'ms/frame', 'fps', 'core', 'at', '12.5', 'Hz']
    rows = {m.group(1): m.groups()[1:] for line in lines if (m := ROW.match(line))}
    assert list(rows) == [spec.name for spec in installed_nodes()] + ['decoding']
    for name, (calls, ms, fps, share) in rows.items():
        assert int(calls) > 0, name
        _consistent(ms, fps, share, rate)
    total = next(m for line in lines if (m := ALL.match(line)))
    _consistent(*total.groups(), rate)
    assert float(total.group(1)) == pytest.approx(sum(float(row[1]) for row in rows.values()), abs=0.01 * len(rows))
    assert re.search(r'keeps up with 12.5 Hz: (yes|no)', out)
    assert 'whole graph: ' in out and 'x the camera period' in out


def test_bench_refuses_bad_options(capsys):
    assert main(['bench', '--bag', str(SMALLEST), '--rate', '0']) == 2
    assert main(['bench', '--bag', str(SMALLEST), '--frames', '0']) == 2
    assert main(['bench', '--bag', 'no-such.mcap']) == 1
    assert main(['bench', '--bag', str(SMALLEST), '--warmup', '1000']) == 1
    errors = capsys.readouterr().err
    assert 'none left to time' in errors and 'no such recording' in errors
