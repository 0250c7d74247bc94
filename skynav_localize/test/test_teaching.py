# SPDX-License-Identifier: Apache-2.0
"""Live teaching's logic (RouteTeacher): snapshots by odometry or by view change, max_length, committed maps; dead
reckoning from velocity commands (CommandedMotion)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_core.maps import MapStore
from skynav_localize.teaching import (
    COMMAND_HOLD_NS,
    DEFAULT_ODOMETRY_TOLERANCE_NS,
    ODOM_POSE,
    BadGoal,
    CommandedMotion,
    MapExists,
    MapWriteFailed,
    OdometryTrack,
    RouteTeacher,
)


def path_length(positions):
    """Return the cumulative path length (m) along positions (N, 3)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0), axis=1))])


def teach_drive(teacher, recording, odometry=True):
    """Offer every view of a recording (its ground-truth poses as odometry of the same stamps); return kept."""
    kept = []
    for k, stamp in enumerate(recording.stamps):
        if odometry:
            teacher.add_odometry(int(stamp), recording.poses[k])
        if teacher.offer(int(stamp), recording.coefficients[k]):
            kept.append(k)
    return kept


def test_with_odometry_a_snapshot_every_spacing_metres(garden, tmp_path):
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.3)
    kept = teach_drive(teacher, drive)
    travelled = path_length(drive.poses[:, :3])
    gaps = np.diff(travelled[kept])
    step = np.max(np.diff(travelled))
    assert step < 0.15  # views come more often than half a spacing: the rule is not starved
    # the first view past each multiple of the spacing from the first snapshot, at least half a spacing apart: the
    # mean spacing is the spacing, not the spacing plus the camera's step on average
    marks = np.floor((travelled[kept] - travelled[kept[0]]) / 0.3)
    assert np.all(np.diff(marks) >= 1) and np.all(gaps >= 0.15) and np.all(gaps < 0.3 + step + 1e-9)
    passed = np.floor((travelled[np.array(kept[1:]) - 1] - travelled[kept[0]]) / 0.3)
    assert np.all(passed < marks[1:])  # the view before each snapshot had not reached its mark yet
    assert len(kept) == teacher.snapshots == int((travelled[kept[-1]] - travelled[kept[0]]) // 0.3) + 1
    assert teacher.route_length == pytest.approx(travelled[kept[-1]] - travelled[kept[0]])
    assert teacher.finish() == tmp_path / 'garden.db'
    with MapStore.open(tmp_path / 'garden.db') as store:
        assert store.name == 'garden' and len(store) == len(kept) and store.max_degree == 16
        np.testing.assert_array_equal(store.stamps(), drive.stamps[kept])
        np.testing.assert_allclose(store.coefficients(), drive.coefficients[kept])
        np.testing.assert_allclose(store.descriptor_matrix(ODOM_POSE), drive.poses[kept])
        assert not store.has_poses  # ground truth is never stored by a node
        assert store.meta['taught'] == 'live'


@pytest.mark.parametrize('spacing', [0.2, 0.5])
def test_without_odometry_the_view_change_gives_about_the_spacing(garden, tmp_path, spacing):
    # VIEW_CHANGE_PER_METRE is calibrated on the bundled teach drives so that the spacing holds roughly
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=spacing)
    kept = teach_drive(teacher, drive, odometry=False)
    gaps = np.diff(path_length(drive.poses[:, :3])[kept])
    assert 0.7 * spacing <= np.median(gaps) <= 1.5 * spacing
    assert teacher.route_length == 0.0  # unknown without odometry
    with MapStore.open(teacher.finish()) as store:
        assert len(store) == len(kept)
        assert np.all(np.isnan(store.descriptor_matrix(ODOM_POSE)))


def test_max_length_stores_the_view_that_reaches_it_and_ends(garden, tmp_path):
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.5, max_length=2.0)
    kept = teach_drive(teacher, drive)
    travelled = path_length(drive.poses[:, :3])
    assert teacher.finished
    assert travelled[kept[-1]] - travelled[kept[0]] >= 2.0
    assert travelled[kept[-2]] - travelled[kept[0]] < 2.0
    assert teacher.route_length >= 2.0
    assert not teacher.offer(int(drive.stamps[-1]) + 1, drive.coefficients[-1])


def test_odometry_far_from_the_views_stamp_is_not_used(garden, tmp_path):
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.3)
    late = 10**10 + DEFAULT_ODOMETRY_TOLERANCE_NS  # odometry 10 s ahead of every view
    for k, stamp in enumerate(drive.stamps[:10]):
        teacher.add_odometry(int(stamp) + late, drive.poses[k])
        teacher.offer(int(stamp), drive.coefficients[k])
    assert teacher.route_length == 0.0
    assert teacher.snapshots >= 1
    with MapStore.open(teacher.finish()) as store:
        assert np.all(np.isnan(store.descriptor_matrix(ODOM_POSE)))


def test_odometry_track_ignores_old_or_broken_samples():
    track = OdometryTrack(capacity=3)
    pose = np.array([0, 0, 0, 0, 0, 0, 1.0])
    assert track.add(10, pose)
    assert not track.add(10, pose + [1, 0, 0, 0, 0, 0, 0])  # not newer
    assert not track.add(20, np.full(7, np.nan))
    for k, stamp in enumerate((20, 30, 40), start=1):
        assert track.add(stamp, pose + [k, 0, 0, 0, 0, 0, 0])
    assert track.at(10, 5) is None  # dropped beyond the capacity
    found = track.at(41, 5)  # past the newest sample: extrapolated at the last velocity (0.1 m/ns here)
    assert found is not None and found[1] == pytest.approx(3.1) and found[0][0] == pytest.approx(3.1)
    found = track.at(25, 5)  # between samples: interpolated
    assert found[1] == pytest.approx(1.5) and found[0][0] == pytest.approx(1.5)
    assert track.at(30, 0)[1] == 2.0
    assert track.at(100, 5) is None


def test_a_view_ahead_of_its_odometry_uses_the_extrapolated_path_length(garden, tmp_path):
    # live, a view is often taken before the odometry sample of its instant arrives
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.3)
    kept = []
    for k, stamp in enumerate(drive.stamps):
        if k:
            teacher.add_odometry(int(drive.stamps[k - 1]) + 10_000_000, drive.poses[k - 1])
        if teacher.offer(int(stamp), drive.coefficients[k]):
            kept.append(k)
    travelled = path_length(drive.poses[:, :3])
    kept = kept[1:]  # the first snapshot has no odometry yet: the marks count from the second
    # each snapshot is the first view past its mark by its true path length (to 1 cm): a view that took the last
    # sample's length instead of extrapolating would come one view late, when the view before had passed the mark
    marks = np.floor((travelled[kept] - travelled[kept[0]]) / 0.3 + 0.01 / 0.3)
    passed = np.floor((travelled[np.array(kept[1:]) - 1] - travelled[kept[0]]) / 0.3 - 0.01 / 0.3)
    assert np.all(np.diff(marks) >= 1) and np.all(passed < marks[1:])
    assert np.all(np.diff(travelled[kept]) >= 0.15 - 0.01)


def test_after_a_first_view_without_odometry_the_spacing_counts_from_the_first_sample(garden, tmp_path):
    # the first view may come before the first /odom sample; from then on odometry, not view change, spaces
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.5)
    assert teacher.offer(int(drive.stamps[0]), drive.coefficients[0])
    kept = [0] + [k for k in range(1, len(drive.stamps)) if teacher_takes(teacher, drive, k)]
    travelled = path_length(drive.poses[:, :3]) - path_length(drive.poses[:, :3])[1]  # from the first sample
    expected = [0]
    for k in range(1, len(drive.stamps)):
        if len(expected) == 1:  # the first with odometry: half a metre from the first sample
            taken = travelled[k] >= 0.5
        else:  # then the first view past each mark half a metre apart from there (and a quarter from the last)
            start, last = travelled[expected[1]], travelled[expected[-1]]
            due = start + (np.floor((last - start) / 0.5) + 1) * 0.5
            taken = travelled[k] >= due and travelled[k] - last >= 0.25
        if taken:
            expected.append(k)
    assert kept == expected and len(kept) > 10


def teacher_takes(teacher, recording, k):
    """Give the teacher frame k's odometry, then its view; return whether the view became a snapshot."""
    teacher.add_odometry(int(recording.stamps[k]), recording.poses[k])
    return teacher.offer(int(recording.stamps[k]), recording.coefficients[k])


def test_views_of_a_higher_degree_are_cut_and_of_a_lower_one_refused(garden, tmp_path):
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.1)
    low = drive.coefficients[0][: 9**2]  # degree 8
    assert teacher.offer(1, low)
    assert teacher.offer(2, drive.coefficients[40])  # degree 16: cut to 8
    with pytest.raises(ValueError, match='degree 4'):
        teacher.offer(3, drive.coefficients[1][:25])
    with MapStore.open(teacher.finish()) as store:
        assert store.max_degree == 8
        np.testing.assert_allclose(store.coefficients()[1], drive.coefficients[40][:81])


def test_goals_that_cannot_be_taught(tmp_path):
    existing = tmp_path / 'taken.db'
    existing.write_bytes(b'x')
    with pytest.raises(MapExists):
        RouteTeacher(existing)
    RouteTeacher(existing, overwrite=True)  # allowed: replaced with the first snapshot
    with pytest.raises(MapWriteFailed, match='no such directory'):
        RouteTeacher(tmp_path / 'missing' / 'map.db')
    with pytest.raises(MapWriteFailed, match='directory'):
        RouteTeacher(tmp_path)
    with pytest.raises(BadGoal):
        RouteTeacher('')
    with pytest.raises(BadGoal):
        RouteTeacher(tmp_path / 'a.db', max_length=float('nan'))
    with pytest.raises(BadGoal):
        RouteTeacher(tmp_path / 'a.db', spacing=float('inf'))


def test_a_map_that_cannot_be_written_fails_with_map_write_failed(garden, tmp_path):
    drive = garden['teach']
    folder = tmp_path / 'gone'
    folder.mkdir()
    teacher = RouteTeacher(folder / 'map.db')
    folder.rmdir()  # the directory disappears between the goal and the first view
    with pytest.raises(MapWriteFailed):
        teacher.offer(int(drive.stamps[0]), drive.coefficients[0])


SECOND = 1_000_000_000  # ns


def test_commands_held_on_a_circle_come_back_to_the_start():
    motion = CommandedMotion()
    speed, rate, period = 0.3, 0.5, SECOND // 10  # m/s, rad/s, 10 Hz
    turn_time = 2 * np.pi / rate  # s for one full circle
    for k in range(int(turn_time * 10) + 1):
        assert motion.add(k * period, speed, rate)
    pose, travelled = motion.at(int(turn_time * SECOND))
    np.testing.assert_allclose(pose[:2], [0.0, 0.0], atol=1e-9)
    assert travelled == pytest.approx(speed * turn_time)
    pose, _ = motion.at(int(turn_time * SECOND / 2))  # half way: diametrically opposite, facing back
    np.testing.assert_allclose(pose[:2], [0.0, 2 * speed / rate], atol=1e-9)
    assert abs(Rotation.from_quat(pose[3:]).as_euler('zyx')[0]) == pytest.approx(np.pi, abs=1e-9)


def test_a_command_moves_the_robot_for_at_most_the_hold_and_nothing_before_the_first():
    motion = CommandedMotion()
    np.testing.assert_array_equal(motion.at(5 * SECOND)[0], [0, 0, 0, 0, 0, 0, 1])  # standing where teaching began
    assert motion.add(SECOND, 0.4, 0.0)
    pose, travelled = motion.at(SECOND + COMMAND_HOLD_NS // 2)
    assert pose[0] == pytest.approx(0.4 * COMMAND_HOLD_NS / 2 / SECOND) and travelled == pytest.approx(pose[0])
    pose, travelled = motion.at(10 * SECOND)  # the teleoperation went quiet: the base stopped after the hold
    assert pose[0] == pytest.approx(0.4 * COMMAND_HOLD_NS / SECOND) and pose[1] == 0.0
    assert motion.add(11 * SECOND, -0.2, 0.0)  # reversing shortens the way from the start, lengthens the path
    pose, travelled = motion.at(11 * SECOND + COMMAND_HOLD_NS)
    assert pose[0] == pytest.approx((0.4 - 0.2) * COMMAND_HOLD_NS / SECOND)
    assert travelled == pytest.approx(0.6 * COMMAND_HOLD_NS / SECOND)


def test_broken_stale_or_forgotten_commands():
    motion = CommandedMotion(capacity=3)
    assert motion.add(10, 0.1, 0.0)
    assert not motion.add(10, 0.2, 0.0)  # not newer
    assert not motion.add(20, np.nan, 0.0) and not motion.add(20, 0.1, np.inf)
    for stamp in (20, 30, 40):
        assert motion.add(stamp, 0.1, 0.0)
    assert motion.at(15) is None  # older than every command kept: unknown
    assert motion.at(25) is not None


def test_without_odometry_the_commands_give_the_route_shape_and_the_view_change_the_spacing(garden, tmp_path):
    drive = garden['teach']
    stamps = drive.stamps.astype(np.int64)
    headings = Rotation.from_quat(drive.poses[:, 3:]).as_euler('zyx')[:, 0]
    steps = np.linalg.norm(np.diff(drive.poses[:, :2], axis=0), axis=1)
    seconds = np.diff(stamps) / SECOND
    # the commands that drive the ground truth from each frame to the next (an arc of the same chord and turn)
    turns = np.arctan2(np.sin(np.diff(headings)), np.cos(np.diff(headings)))
    chords = np.where(np.abs(turns) > 1e-9, np.abs(turns / 2) / np.maximum(np.abs(np.sin(turns / 2)), 1e-12), 1.0)
    linear, angular = steps * chords / seconds, turns / seconds
    plain = RouteTeacher(tmp_path / 'plain.db', spacing=0.3)
    kept_plain = teach_drive(plain, drive, odometry=False)
    teacher = RouteTeacher(tmp_path / 'garden.db', spacing=0.3)
    kept = []
    for k, stamp in enumerate(stamps):
        if teacher.offer(int(stamp), drive.coefficients[k]):
            kept.append(k)
        if k < len(linear):
            teacher.add_command(int(stamp), linear[k], angular[k])
    assert kept == kept_plain  # the spacing is by the view's change, commands or not
    true_length = float(np.sum(steps[kept[0] : kept[-1]]))
    assert teacher.route_length == pytest.approx(true_length, rel=0.02)
    with MapStore.open(teacher.finish()) as store:
        assert np.all(np.isnan(store.descriptor_matrix(ODOM_POSE)))
        commanded = store.commanded_poses()
    # the shape: every distance between two snapshots as the ground truth has it (the frame is where teaching began)
    truth = drive.poses[kept, :2]
    shape = commanded[:, :2]
    true_distances = np.linalg.norm(truth[:, None] - truth[None], axis=2)
    distances = np.linalg.norm(shape[:, None] - shape[None], axis=2)
    assert np.max(np.abs(distances - true_distances)) < 0.05


def test_a_point_turn_is_stored_where_the_robot_turns(garden, tmp_path):
    # a mower at a lane's end turns a quarter turn where it stands: no travel, yet the route's corner is there
    drive = garden['teach']
    teacher = RouteTeacher(tmp_path / 'lawn.db', spacing=0.1)
    headings = np.radians(np.r_[np.zeros(3), np.arange(1, 8) * 12.0, np.full(3, 84.0)])  # 12 degrees a frame
    quaternions = Rotation.from_euler('z', headings[:, None]).as_quat()
    kept = []
    for k, quaternion in enumerate(quaternions):
        stamp = 1_000_000_000 + k * 200_000_000
        teacher.add_odometry(stamp, np.r_[2.0, 1.0, 0.0, quaternion])
        if teacher.offer(stamp, drive.coefficients[k]):
            kept.append(k)
    assert kept == [0, 5, 8]  # the start, then at 30 degrees of turn or more since the last snapshot: 36 and 72
    with MapStore.open(teacher.finish()) as store:
        poses = store.descriptor_matrix(ODOM_POSE)
    assert np.degrees(Rotation.from_quat(poses[:, 3:]).as_euler('xyz')[:, 2]) == pytest.approx([0, 36, 72])
    np.testing.assert_allclose(poses[:, :2], [[2.0, 1.0]] * 3)
