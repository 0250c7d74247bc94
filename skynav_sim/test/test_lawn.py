# SPDX-License-Identifier: Apache-2.0
"""Lawns (skynav_sim.lawn): the lane pattern, the operator who teaches it with point turns, and coverage."""

import math

import numpy as np
import pytest

from skynav_sim.lawn import CUT_WIDTH, LaneOperator, Lawn, coverage, place_lawn
from skynav_sim.mower import Mower, Pose2D
from skynav_sim.world import generate

FRAME = 0.2  # s between the operator's commands


def test_the_lanes_run_back_and_forth_a_gap_apart():
    lawn = Lawn((1.0, 2.0), math.pi / 2, lanes=3, length=4.0, gap=0.4, side=-1)  # north, the next lane east
    np.testing.assert_allclose(
        lawn.corners(), [[1.0, 2.0], [1.0, 6.0], [1.4, 6.0], [1.4, 2.0], [1.8, 2.0], [1.8, 6.0]], atol=1e-12
    )
    assert lawn.path_length == pytest.approx(3 * 4.0 + 2 * 0.4)


def drive_lawn(lawn: Lawn, slip: float = 0.0, frames: int = 5000) -> tuple[np.ndarray, np.ndarray, int]:
    """Let the operator drive `lawn` on an empty park; return the positions, headings and frames turned in place."""
    world = generate('park', 5)
    corners = lawn.corners()
    start = Pose2D(
        float(corners[0][0]), float(corners[0][1]), lawn.heading + 0.3
    )  # turned off the first lane: a point turn first
    mower = Mower(world, start, np.random.default_rng(1), slip=slip, odometry_noise=0.0)
    operator = LaneOperator(lawn)
    positions, headings, in_place = [mower.pose.position], [mower.pose.heading], 0
    for _ in range(frames):
        linear, angular = operator.command(mower.pose.x, mower.pose.y, mower.pose.heading)
        if operator.done:
            break
        in_place += linear == 0.0 and angular != 0.0
        mower.drive(linear, angular, FRAME)
        assert not mower.blocked
        positions.append(mower.pose.position)
        headings.append(mower.pose.heading)
    assert operator.done
    return np.array(positions), np.array(headings), in_place


def test_the_operator_drives_every_lane_and_turns_in_place_at_the_ends():
    world = generate('park', 5)
    lawn = place_lawn(world, 4, 3.0)
    assert lawn is not None and lawn.fits(world)
    positions, headings, in_place = drive_lawn(lawn, slip=0.05)
    corners = lawn.corners()
    # every corner is reached (to the operator's tolerance and the last step's length)
    for corner in corners:
        assert np.min(np.linalg.norm(positions - corner, axis=1)) < 0.1
    # the turns are in place: the path never cuts a corner by more than a few centimetres
    lanes = np.array([[corners[k], corners[k + 1]] for k in range(len(corners) - 1)])
    start, chord = lanes[:, 0], lanes[:, 1] - lanes[:, 0]
    share = np.clip(np.einsum('nij,ij->ni', positions[:, None] - start, chord) / np.sum(chord**2, axis=1), 0, 1)
    off = np.min(np.linalg.norm(positions[:, None] - (start + share[..., None] * chord), axis=2), axis=1)
    assert off.max() < 0.05
    assert in_place > 2 * (len(corners) - 2)  # each of the 2 (lanes - 1) corners took frames of turning in place
    assert np.ptp(np.unwrap(headings)) > math.pi  # it turned round at the lanes' ends


def test_a_repeat_on_the_taught_path_cuts_everything():
    taught = Lawn((0.0, 0.0), 0.0, 3, 4.0).corners()
    result = coverage(taught, [taught.copy()])
    assert result.share == pytest.approx(1.0) and result.widest_uncut == 0.0


def test_a_repeat_beside_the_taught_path_leaves_a_strip_as_wide_as_the_shift():
    # one straight lane, repeated 0.1 m to its left: a strip 0.1 m wide along its right edge stays uncut
    taught = np.array([[0.0, 0.0], [6.0, 0.0]])
    repeat = taught + [0.0, 0.1]
    result = coverage(taught, [repeat], width=CUT_WIDTH)
    assert result.widest_uncut == pytest.approx(0.1, abs=0.02)
    # the strip is 0.1 of the 0.5 m swath along the lane; the round ends of the swath a little more
    assert result.share == pytest.approx(1 - 0.1 / 0.5, abs=0.02)


def test_lanes_driven_too_far_apart_leave_strips_between_them():
    # taught 0.4 m apart, 0.5 m cuts overlap by 0.1 m; each lane repeated 0.15 m outwards, they part by 0.2 m
    lawn = Lawn((0.0, 0.0), 0.0, 2, 5.0, gap=0.4)
    taught = lawn.corners()
    # (the repeat runs on past the lanes' ends, so that the ends' round caps are cut)
    repeat = np.array([[-0.3, -0.15], [5.3, -0.15], [5.3, 0.55], [-0.3, 0.55]])
    result = coverage(taught, [repeat])
    # the two swaths, 0.7 m apart, leave the band 0.1..0.3 m between them uncut along the lanes
    assert result.widest_uncut == pytest.approx(0.2, abs=0.02)
    assert result.share == pytest.approx(1 - 0.2 * 5.0 / (result.taught.sum() * result.grid.cell**2), abs=0.02)


def test_a_path_interrupted_and_resumed_counts_as_one():
    taught = np.array([[0.0, 0.0], [6.0, 0.0]])
    halves = [np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[3.0, 0.0], [6.0, 0.0]])]
    assert coverage(taught, halves).share == pytest.approx(1.0)
    assert coverage(taught, halves[:1]).widest_uncut == pytest.approx(CUT_WIDTH, abs=0.02)  # half the lane uncut


@pytest.mark.parametrize(
    'extra, complaint',
    [
        (['--lanes', '0'], '--lanes must be within'),
        (['--gap', '0.01'], '--gap and --cut'),
        (['--interrupt', '1.5'], '--interrupt must be a share'),
    ],
)
def test_eval_mow_refuses_a_malformed_lawn_in_one_line(extra, complaint, tmp_path):
    from skynav_testing import one_line_error, run_skynav

    result = run_skynav('eval', 'mow', '--out', str(tmp_path), *extra)
    assert result.returncode == 2 and one_line_error(result.stderr) and complaint in result.stderr, result.stderr
