# SPDX-License-Identifier: Apache-2.0
"""ElapsedTime: the time a running clock passes, its jumps (a late start, a restart) left out."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from skynav_core.elapsed import ElapsedTime

SECOND = 1_000_000_000
STEP = SECOND // 10  # a reading every 0.1 s, as the nodes take them


def test_a_clock_that_starts_late_passes_no_time_until_it_runs():
    elapsed = ElapsedTime(max_step_ns=SECOND)
    assert [elapsed.read(0) for _ in range(50)] == [0] * 50  # sim time before the first /clock
    start = 1_700_000_000 * SECOND
    assert elapsed.read(start) == 0  # the first /clock: a jump
    assert elapsed.read(start + 3 * STEP) == 3 * STEP
    assert elapsed.jumps == 1


def test_a_clock_that_jumps_back_keeps_counting_from_where_it_lands():
    elapsed = ElapsedTime(max_step_ns=SECOND)
    for k in range(11):
        elapsed.read(100 * SECOND + k * STEP)
    assert elapsed.read(5 * SECOND) == 10 * STEP  # a recording played again
    assert elapsed.read(5 * SECOND + STEP) == 11 * STEP
    assert elapsed.jumps == 1


@given(st.lists(st.integers(min_value=0, max_value=SECOND), min_size=1, max_size=50), st.integers(1, 10**18))
def test_a_running_clock_passes_exactly_its_steps(steps, start):
    elapsed = ElapsedTime(max_step_ns=SECOND)
    clock = start
    elapsed.read(clock)
    for step in steps:
        clock += step
        total = elapsed.read(clock)
    assert total == sum(steps) and elapsed.jumps == 0


@given(st.lists(st.integers(min_value=-(10**15), max_value=10**15), min_size=2, max_size=50))
def test_time_passed_never_goes_back_nor_outruns_the_steps_taken(readings):
    elapsed = ElapsedTime(max_step_ns=SECOND)
    totals = [elapsed.read(r) for r in readings]
    assert all(b >= a for a, b in zip(totals, totals[1:]))
    assert all(b - a <= SECOND for a, b in zip(totals, totals[1:]))


def test_without_a_step_limit_every_forward_step_passes_but_the_start_from_zero():
    # the in-process graph's time: a gap in a recording is time that passed; time zero is no time yet
    elapsed = ElapsedTime(max_step_ns=2**63 - 1)
    assert elapsed.read(0) == 0 and elapsed.read(1_750_000_000 * SECOND) == 0
    assert elapsed.read(1_750_000_010 * SECOND) == 10 * SECOND
    assert elapsed.read(1_750_000_000 * SECOND) == 10 * SECOND  # back: a jump
    assert elapsed.jumps == 2


def test_a_step_limit_must_be_positive():
    with pytest.raises(ValueError):
        ElapsedTime(0)
