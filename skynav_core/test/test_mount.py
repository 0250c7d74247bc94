# SPDX-License-Identifier: Apache-2.0
"""The camera's mount: RPY against scipy, camera_link turned into base_link against the rotations' own conventions
(true compass rotation, true home direction), /tf_static's transforms and chains, and the vendored tf2_msgs."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import TransformStamped
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from tf2_msgs.msg import TFMessage

from skynav_core.mount import (
    StaticTransforms,
    direction_to_base,
    mount_from_rpy_deg,
    mount_rpy_deg,
    rotation_to_base,
)
from skynav_core.names import BASE_FRAME, CAMERA_FRAME
from skynav_core.rotations import (
    as_quaternion,
    home_direction,
    relative_rotation,
    rpy_angles,
    rpy_matrix,
    yaw,
    yaw_matrix,
)

seeds = st.integers(0, 2**32 - 1)
# tf2_msgs/msg/TFMessage of ROS 2 Jazzy (ros2/geometry2): what `ros2 topic info --verbose /tf_static` shows
TF_MESSAGE_HASH = 'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_rpy_is_scipys_extrinsic_xyz_and_its_angles_rebuild_the_matrix(seed):
    rng = np.random.default_rng(seed)
    angles = rng.uniform([-np.pi, -np.pi / 2, -np.pi], [np.pi, np.pi / 2, np.pi], (40, 3))
    angles[:2, 1] = [np.pi / 2, -np.pi / 2]  # gimbal lock
    matrices = rpy_matrix(*angles.T)
    np.testing.assert_allclose(matrices, Rotation.from_euler('xyz', angles).as_matrix(), atol=1e-12)
    roll, pitch, yaw_ = rpy_angles(matrices)
    np.testing.assert_allclose(rpy_matrix(roll, pitch, yaw_), matrices, atol=1e-9)
    assert np.all(np.abs(pitch) <= np.pi / 2)
    assert rpy_angles(matrices[5]) == pytest.approx(tuple(a[5] for a in (roll, pitch, yaw_)), abs=1e-15)


def test_a_camera_turned_left_sees_the_robots_left_as_its_forward():
    mount = mount_from_rpy_deg([0.0, 0.0, 90.0])
    np.testing.assert_allclose(direction_to_base(mount, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(direction_to_base(mount, [0.0, 0.0, 1.0]), [0.0, 0.0, 1.0], atol=1e-15)
    # pitched forward (a positive pitch turns +x towards -z): the camera's zenith leans towards the robot's front
    pitched = mount_from_rpy_deg([0, 4, 0])
    zenith = direction_to_base(pitched, [0.0, 0.0, 1.0])
    assert zenith[0] == pytest.approx(math.sin(math.radians(4))) and zenith[1] == 0
    assert mount_rpy_deg(mount_from_rpy_deg([3, -4, 170])) == pytest.approx((3, -4, 170))
    assert np.array_equal(mount_from_rpy_deg([0, 0, 0]), np.eye(3))


@pytest.mark.parametrize(
    'value',
    [[0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, float('nan'), 0.0], [float('inf'), 0.0, 0.0], 'yaw 90', 90.0, None,
     [True, False, True], ['0', '0', '90']],
)  # fmt: skip
def test_an_unusable_mount_is_refused_in_one_line(value):
    with pytest.raises(ValueError, match='camera_mount_rpy_deg') as refused:
        mount_from_rpy_deg(value)
    assert '\n' not in str(refused.value)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_camera_link_quantities_turned_into_base_link_are_the_robots_own(seed):
    # the camera's orientation in map is the base's times the mount (Q = B M): the true compass rotation and home
    # direction of the cameras, turned by the mount, are those of the bases
    rng = np.random.default_rng(seed)
    mount = Rotation.random(random_state=rng).as_matrix()
    bases = Rotation.random(2 * 8, random_state=rng).as_matrix().reshape(2, 8, 3, 3)
    cameras = bases @ mount
    positions = rng.normal(size=(2, 8, 3))
    camera_rotation = relative_rotation(cameras[0], cameras[1])
    np.testing.assert_allclose(rotation_to_base(mount, camera_rotation), relative_rotation(*bases), atol=1e-12)
    camera_home = home_direction(positions[0], positions[1], cameras[1])
    np.testing.assert_allclose(
        direction_to_base(mount, camera_home), home_direction(positions[0], positions[1], bases[1]), atol=1e-12
    )


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_the_robots_turn_on_flat_ground_is_the_yaw_of_the_turned_compass_rotation(seed):
    rng = np.random.default_rng(seed)
    mount = mount_from_rpy_deg(list(rng.uniform([-10, -10, -180], [10, 10, 180])))
    headings = rng.uniform(-np.pi, np.pi, (2, 10))
    cameras = yaw_matrix(headings) @ mount
    turned = rotation_to_base(mount, relative_rotation(cameras[0], cameras[1]))
    np.testing.assert_allclose(np.cos(yaw(turned) - (headings[1] - headings[0])), 1.0, atol=1e-12)


def transform(parent, child, rotation, translation=(0.1, 0.0, 0.3)):
    """Return a geometry_msgs/TransformStamped from `parent` to `child` with a rotation (3, 3)."""
    message = TransformStamped()
    message.header.frame_id, message.child_frame_id = parent, child
    x, y, z, w = as_quaternion(rotation)
    message.transform.rotation.x, message.transform.rotation.y = float(x), float(y)
    message.transform.rotation.z, message.transform.rotation.w = float(z), float(w)
    message.transform.translation.x, message.transform.translation.y, message.transform.translation.z = translation
    return message


def test_one_static_transform_from_base_link_to_camera_link_is_the_mount():
    mount = mount_from_rpy_deg([2.0, -4.0, 90.0])
    transforms = StaticTransforms()
    assert transforms.mount() is None
    assert transforms.add(TFMessage(transforms=[transform(f'/{BASE_FRAME}', CAMERA_FRAME, mount)])) == []
    np.testing.assert_allclose(transforms.mount(), mount, atol=1e-12)
    # the latest transform of a frame replaces the one before (a robot_state_publisher started again)
    transforms.add(TFMessage(transforms=[transform(BASE_FRAME, CAMERA_FRAME, np.eye(3))]))
    np.testing.assert_allclose(transforms.mount(), np.eye(3), atol=1e-12)


def test_a_chain_and_a_tree_of_a_urdf_give_the_mount_once_linked():
    rng = np.random.default_rng(3)
    footprint_base, base_mast, mast_camera, footprint_arm = Rotation.random(4, random_state=rng).as_matrix()
    transforms = StaticTransforms()
    transforms.add(TFMessage(transforms=[transform('mast_link', CAMERA_FRAME, mast_camera)]))
    assert transforms.mount() is None  # the camera's tree does not reach base_link yet
    transforms.add(TFMessage(transforms=[transform(BASE_FRAME, 'mast_link', base_mast)]))
    np.testing.assert_allclose(transforms.mount(), base_mast @ mast_camera, atol=1e-12)
    # camera on a frame of the robot's root, base_link below that root too: the mount goes up and down the tree
    tree = StaticTransforms()
    tree.add(
        TFMessage(
            transforms=[
                transform('base_footprint', BASE_FRAME, footprint_base),
                transform('base_footprint', 'arm_link', footprint_arm),
                transform('arm_link', CAMERA_FRAME, mast_camera),
            ]
        )
    )
    np.testing.assert_allclose(tree.mount(), footprint_base.T @ footprint_arm @ mast_camera, atol=1e-12)


def test_unusable_transforms_are_refused_one_line_each_and_the_rest_kept():
    transforms = StaticTransforms()
    bad = transform(BASE_FRAME, 'laser', np.eye(3))
    bad.transform.rotation.w = 2.0
    nan = transform(BASE_FRAME, 'imu', np.eye(3))
    nan.transform.rotation.x = float('nan')
    itself = transform(CAMERA_FRAME, CAMERA_FRAME, np.eye(3))
    good = transform(BASE_FRAME, CAMERA_FRAME, yaw_matrix(1.0))
    problems = transforms.add(TFMessage(transforms=[bad, nan, itself, good]))
    assert len(problems) == 3 and all('\n' not in p for p in problems)
    assert 'unit length' in problems[0] and 'not finite' in problems[1] and 'no two frames' in problems[2]
    np.testing.assert_allclose(transforms.mount(), yaw_matrix(1.0), atol=1e-12)


def test_transforms_that_loop_are_refused():
    transforms = StaticTransforms()
    links = [('a', 'b'), ('b', 'a'), ('a', CAMERA_FRAME)]
    transforms.add(TFMessage(transforms=[transform(parent, child, np.eye(3)) for parent, child in links]))
    with pytest.raises(ValueError, match='loop'):
        transforms.mount()


def test_the_vendored_tf2_msgs_is_the_real_type():
    # the same type hash as ROS 2 Jazzy's tf2_msgs, so robot_state_publisher's /tf_static matches our subscription
    from ament_index_python.packages import get_package_share_directory
    from rosbags.typesys import Stores, get_typestore

    description = json.loads((Path(get_package_share_directory('tf2_msgs')) / 'msg' / 'TFMessage.json').read_text())
    hashes = {entry['type_name']: entry['hash_string'] for entry in description['type_hashes']}
    assert hashes['tf2_msgs/msg/TFMessage'] == TF_MESSAGE_HASH
    assert get_typestore(Stores.ROS2_JAZZY).hash_rihs01('tf2_msgs/msg/TFMessage') == TF_MESSAGE_HASH
    # and its bytes are those other tools read
    from rclpy.serialization import serialize_message

    message = TFMessage(transforms=[transform(BASE_FRAME, CAMERA_FRAME, yaw_matrix(0.5))])
    read = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(serialize_message(message), 'tf2_msgs/msg/TFMessage')
    (only,) = read.transforms
    assert only.header.frame_id == BASE_FRAME and only.child_frame_id == CAMERA_FRAME
    assert only.transform.rotation.z == pytest.approx(math.sin(0.25)) and only.transform.translation.z == 0.3
