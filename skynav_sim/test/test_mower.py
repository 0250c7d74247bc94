# SPDX-License-Identifier: Apache-2.0
"""The simulated mower obeys velocity commands: exact arcs, slip that shortens the true motion, odometry that
counts the wheels' motion with noise, and a bumper that stops it at obstacles."""

import math

import numpy as np
import pytest

from skynav_sim.closed_loop import clear_line
from skynav_sim.mower import Mower, Pose2D
from skynav_sim.world import BODY_RADIUS, BOUNDARY_WIRE, CLEARANCE, generate


@pytest.fixture(scope='module')
def world():
    return generate('park', 3)


def free_place(world):
    for x in np.linspace(-3, 3, 13):
        if all(world.is_free(x + dx, dy) for dx in np.linspace(-2, 2, 21) for dy in np.linspace(-2, 2, 21)):
            return float(x)
    raise AssertionError('no free 4 m square near the middle of this world')


def test_pose_moves_along_exact_arcs():
    straight = Pose2D(1.0, 2.0, math.pi / 2).moved(0.5, 0.0)
    assert (straight.x, straight.y, straight.heading) == pytest.approx((1.0, 2.5, math.pi / 2))
    # a quarter circle of radius 1 to the left, from the origin facing +x, ends at (1, 1) facing +y
    quarter = Pose2D().moved(math.pi / 2, math.pi / 2)
    assert (quarter.x, quarter.y, quarter.heading) == pytest.approx((1.0, 1.0, math.pi / 2))
    # in small steps the same
    pose = Pose2D()
    for _ in range(100):
        pose = pose.moved(math.pi / 200, math.pi / 200)
    assert (pose.x, pose.y) == pytest.approx((1.0, 1.0))


def test_without_slip_and_noise_truth_and_odometry_agree(world):
    x = free_place(world)
    mower = Mower(world, Pose2D(x, 0.0, 0.0), np.random.default_rng(0), slip=0.0, odometry_noise=0.0)
    for _ in range(10):
        mower.drive(0.4, 0.5, 0.2)
    assert not mower.blocked
    travelled = mower.pose.position - np.array([x, 0.0])
    assert np.linalg.norm(travelled) == pytest.approx(np.hypot(mower.odometry.x, mower.odometry.y))
    assert mower.pose.heading == pytest.approx(1.0) and mower.odometry.heading == pytest.approx(1.0)


def test_slip_shortens_the_true_motion_and_odometry_drifts(world):
    x = free_place(world)
    mower = Mower(world, Pose2D(x, 0.0, 0.0), np.random.default_rng(1), slip=0.2, odometry_noise=0.05)
    for _ in range(10):
        mower.drive(0.5, 0.0, 0.2)
    true = mower.pose.x - x
    assert 0.8 * 1.0 <= true < 1.0  # up to 20 % of each step lost to slip
    assert mower.odometry.x != pytest.approx(true, abs=1e-3)  # the wheels' count is not the truth
    assert abs(mower.odometry.x - 1.0) < 0.1  # but close to what the wheels did


def test_obstacles_block_the_mower(world):
    rng = np.random.default_rng(3)
    for _ in range(10000):  # a free place next to an obstacle, facing it
        x, y, heading = rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-math.pi, math.pi)
        ahead = Pose2D(x, y, heading).moved(0.1, 0.0)
        if not world.collides(x, y) and world.collides(ahead.x, ahead.y):
            break
    mower = Mower(world, Pose2D(x, y, heading), np.random.default_rng(0), slip=0.0, odometry_noise=0.0)
    mower.drive(0.5, 0.0, 0.2)
    assert mower.blocked and (mower.pose.x, mower.pose.y) == (x, y) and mower.odometry == Pose2D()


def test_the_bumper_hits_at_the_body_not_at_the_planning_clearance(world):
    trunk = next(f for f in world.footprints if f.disc and np.hypot(*f.center) < 7)
    outward = trunk.center / np.hypot(*trunk.center)  # towards the yard's edge, away from the middle
    near = trunk.center + (trunk.half_sizes[0] + (BODY_RADIUS + CLEARANCE) / 2) * outward
    touching = trunk.center + (trunk.half_sizes[0] + BODY_RADIUS / 2) * outward
    assert not world.is_free(*near) and not world.collides(*near)  # no route is planned there; it is no crash
    assert world.collides(*touching)
    assert world.collides(0.0, BOUNDARY_WIRE + 0.1)  # the boundary wire


def test_bad_shares_are_refused(world):
    with pytest.raises(ValueError, match='shares'):
        Mower(world, Pose2D(), np.random.default_rng(0), slip=1.5)


def test_a_clear_line_is_one_the_body_drives_without_touching_an_object(world):
    # across an object's footprint the line is blocked; beside it, in the free square, it is clear
    inside = [f for f in world.footprints if math.hypot(*f.center) < BOUNDARY_WIRE - 3]
    center = np.asarray(inside[0].center, dtype=float)
    assert not clear_line(world, center + [2.5, 0.0], center - [2.5, 0.0])
    x = free_place(world)
    assert clear_line(world, np.array([x - 1.5, -1.5]), np.array([x + 1.5, 1.5]))
