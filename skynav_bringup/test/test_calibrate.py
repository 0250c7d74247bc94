# SPDX-License-Identifier: Apache-2.0
"""`skynav calibrate` end to end: synthetic board views as PNG files and as a recording, to a YAML that reads back."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from skynav_bringup.cli import main
from skynav_core.camera import EquidistantCamera
from skynav_core.camera_yaml import camera_from_url
from skynav_core.names import CAMERA_FRAME, COLOUR_COMPRESSED, COLOUR_IMAGE, ODOM, UV_IMAGE
from skynav_sim.checkerboard import BoardRenderer, Checkerboard, calibration_poses, synthetic_fisheye
from skynav_testing import one_line_error, run_skynav

FOV = np.radians(200.0)
BOARD = Checkerboard(9, 6, 0.025)
VIEWS = 14
BOARD_ARGS = ('--board', '9x6', '--square', '0.025')


def assert_meets_the_targets(camera: EquidistantCamera, truth: EquidistantCamera) -> None:
    """Assert issue 28's calibration targets: fx, fy within 1 %, (cx, cy) within 1.5 px, r(theta) within 1.5 px."""
    assert abs(camera.fx / truth.fx - 1) < 0.01 and abs(camera.fy / truth.fy - 1) < 0.01
    assert abs(camera.cx - truth.cx) < 1.5 and abs(camera.cy - truth.cy) < 1.5
    theta = np.linspace(0, np.radians(85.0), 500)
    for f, f_true in ((camera.fx, truth.fx), (camera.fy, truth.fy)):
        assert np.abs(f * camera.distort(theta) - f_true * truth.distort(theta)).max() < 1.5


@pytest.fixture(scope='module')
def views(tmp_path_factory):
    """Synthetic views (8-bit sRGB RGB) of the board all over a 200-degree lens, and the camera they came through."""
    truth = synthetic_fisheye(640, 480, FOV)
    renderer = BoardRenderer(truth, BOARD, FOV, seed=11)
    poses = calibration_poses(truth, BOARD, VIEWS, seed=11, lens_fov=FOV)
    return truth, [renderer.render(pose, index) for index, pose in enumerate(poses)]


def _write_folder(folder: Path, images: list[np.ndarray]) -> Path:
    """Write views as synthetic_board_NN.png into `folder` (made); return it."""
    folder.mkdir()
    for index, image in enumerate(images):
        cv2.imwrite(str(folder / f'synthetic_board_{index:02d}.png'), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    return folder


def _write_recording(path: Path, images: list[np.ndarray]) -> Path:
    """Write views as rgb8 sensor_msgs/Image on /camera/image_raw, 0.5 s apart, into a bare MCAP recording."""
    from skynav_core.recording.bag import BagWriter
    from skynav_core.recording.typestore import typestore

    store = typestore()
    T = store.types
    with BagWriter(path) as writer:
        writer.add_topic(COLOUR_IMAGE, 'sensor_msgs/msg/Image')
        writer.add_topic(ODOM, 'nav_msgs/msg/Odometry')  # another topic, not images: left alone
        for index, image in enumerate(images):
            stamp = 1_700_000_000 * 10**9 + index * 500_000_000
            header = T['std_msgs/msg/Header'](T['builtin_interfaces/msg/Time'](*divmod(stamp, 10**9)), CAMERA_FRAME)
            height, width, _ = image.shape
            message = T['sensor_msgs/msg/Image'](header, height, width, 'rgb8', 0, width * 3, image.ravel())
            writer.write(COLOUR_IMAGE, stamp, store.serialize_cdr(message, 'sensor_msgs/msg/Image'))
    return path


def test_a_folder_of_views_calibrates_to_a_yaml_that_reads_back(views, tmp_path):
    truth, images = views
    folder = _write_folder(tmp_path / 'views', images)
    (folder / 'broken.png').write_bytes(b'\x89PNG\r\n\x1a\n' + bytes(range(200)))  # a damaged image among them
    (folder / 'notes.txt').write_text('not an image: not read')
    out = tmp_path / 'fisheye.yaml'
    result = run_skynav('calibrate', str(folder), *BOARD_ARGS, '--out', str(out))
    assert result.returncode == 0, result.stderr
    assert f'{VIEWS + 1} views of a 9x6 board (25 mm squares): {VIEWS} used, 1 refused' in result.stdout
    assert re.search(r'broken\.png +refused +not an image OpenCV can read', result.stdout)
    assert not result.stderr  # no traceback, no decoder's log: the refusal is the report's line
    assert 'notes.txt' not in result.stdout
    assert 'RMS reprojection error: 0.' in result.stdout and 'coverage: corners in ' in result.stdout
    camera = camera_from_url(f'file://{out}')
    assert_meets_the_targets(camera, truth)
    assert f'fx {camera.fx:.3f}  fy {camera.fy:.3f}  cx {camera.cx:.3f}  cy {camera.cy:.3f}' in result.stdout
    assert f'camera_info_url: file://{out}' in result.stdout
    plot = cv2.imread(str(tmp_path / 'fisheye.png'))  # the plot, beside the YAML by default
    assert plot is not None and plot.shape[1] > 1000


def test_a_recording_calibrates_to_a_yaml_that_reads_back(views, tmp_path, capsys):
    truth, images = views
    bag = _write_recording(tmp_path / 'synthetic_boards.mcap', images)
    out, plot = tmp_path / 'fisheye.yaml', tmp_path / 'plots' / 'corners.png'
    plot.parent.mkdir()
    result = run_skynav('calibrate', str(bag), *BOARD_ARGS, '--out', str(out), '--plot', str(plot), '--fov', '200')
    assert result.returncode == 0, result.stderr
    assert f'{VIEWS} views of a 9x6 board (25 mm squares): {VIEWS} used, 0 refused' in result.stdout
    assert 'synthetic_boards.mcap /camera/image_raw #13' in result.stdout
    assert_meets_the_targets(camera_from_url(str(out)), truth)
    assert plot.exists()

    def in_process(*args: str) -> tuple[int, str]:
        """Return the exit code and error output of `skynav calibrate ARGS` run in this process."""
        code = main(['calibrate', str(bag), *BOARD_ARGS, '--out', str(tmp_path / 'other.yaml'), *args])
        return code, capsys.readouterr().err

    code, stderr = in_process('--topic', ODOM)
    assert code == 1 and one_line_error(stderr) and '/odom carries nav_msgs/msg/Odometry, not images' in stderr
    code, stderr = in_process('--topic', '/camera/left')
    assert code == 1 and one_line_error(stderr) and 'no topic /camera/left' in stderr


def test_too_few_views_of_the_board_exit_1_in_one_line(views, tmp_path):
    _, images = views
    folder = _write_folder(tmp_path / 'views', images[:3])
    cv2.imwrite(str(folder / 'thumbnail.png'), np.full((48, 64, 3), 200, np.uint8))  # another camera's size
    out = tmp_path / 'fisheye.yaml'
    result = run_skynav('calibrate', str(folder), *BOARD_ARGS, '--out', str(out))
    assert result.returncode == 1 and one_line_error(result.stderr)
    assert 'too few views: 3 usable of 4 (3 show the 9x6 board); at least 5' in result.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    ('args', 'code', 'message'),
    [
        (('--board', '9by6', '--square', '0.025'), 2, 'COLSxROWS'),
        (('--board', '9x6', '--square', '-1'), 2, '--square'),
        (('--board', '9x6', '--square', '0.025', '--fov', '400'), 2, '--fov'),
    ],
)
def test_a_malformed_command_line_exits_2_in_one_line(tmp_path, capsys, args, code, message):
    assert main(['calibrate', str(tmp_path), *args, '--out', str(tmp_path / 'c.yaml')]) == code
    stderr = capsys.readouterr().err
    assert one_line_error(stderr) and message in stderr


def test_missing_inputs_exit_1_in_one_line(tmp_path, capsys):
    assert main(['calibrate', str(tmp_path / 'nothing'), *BOARD_ARGS, '--out', str(tmp_path / 'c.yaml')]) == 1
    stderr = capsys.readouterr().err
    assert one_line_error(stderr) and 'no such file or folder' in stderr
    assert main(['calibrate', str(tmp_path), *BOARD_ARGS, '--out', str(tmp_path / 'c.yaml')]) == 1
    stderr = capsys.readouterr().err
    assert one_line_error(stderr) and 'a folder without images' in stderr
    assert main(['calibrate', str(tmp_path), *BOARD_ARGS, '--out', str(tmp_path / 'no' / 'c.yaml')]) == 1
    stderr = capsys.readouterr().err
    assert one_line_error(stderr) and 'no such directory' in stderr


def test_a_compressed_frame_is_decoded_for_the_detector(views):
    from types import SimpleNamespace

    from skynav_bringup.cli.calibrate import _message_frame
    from skynav_core.calibration import Board, find_corners
    from skynav_core.colour import compress
    from skynav_core.recording.bag import RawMessage

    _, images = views
    format_text, data = compress(images[0], 'jpeg', 95)
    message = SimpleNamespace(format=format_text, data=np.frombuffer(data, np.uint8))
    bag = SimpleNamespace(deserialize=lambda raw: message)
    raw = RawMessage(COLOUR_COMPRESSED, 'sensor_msgs/msg/CompressedImage', 0, b'')
    frame = _message_frame(bag, raw, 'jpeg')
    assert frame.grey is not None and frame.grey.shape == (480, 640)
    assert find_corners(frame.grey, Board(9, 6, 0.025)) is not None
    message.data = message.data[: len(data) // 2]  # a truncated JPEG: refused with the decoder's reason
    broken = _message_frame(bag, raw, 'jpeg')
    assert broken.grey is None and 'cannot decode' in broken.reason and 'truncated' in broken.reason


def test_a_mono_frame_is_taken_as_linear(views):
    from types import SimpleNamespace

    from skynav_bringup.cli.calibrate import _message_frame
    from skynav_core.calibration import Board, find_corners
    from skynav_core.colour import SRGB8_TO_LINEAR16
    from skynav_core.recording.bag import RawMessage

    _, images = views
    grey = cv2.cvtColor(images[0], cv2.COLOR_RGB2GRAY)
    linear = SRGB8_TO_LINEAR16[grey]  # mono16, linear as the contract has it
    fields = {'encoding': 'mono16', 'height': 480, 'width': 640, 'step': 1280, 'is_bigendian': 0}
    message = SimpleNamespace(**fields, data=linear.tobytes())
    raw = RawMessage(UV_IMAGE, 'sensor_msgs/msg/Image', 0, b'')
    frame = _message_frame(SimpleNamespace(deserialize=lambda raw: message), raw, 'mono16')
    assert frame.grey is not None and frame.grey.dtype == np.uint8
    assert np.corrcoef(frame.grey.ravel(), grey.ravel())[0, 1] > 0.99  # back on an sRGB-like curve, not linear
    board = Board(9, 6, 0.025)
    found, from_8_bit = find_corners(frame.grey, board), find_corners(grey, board)
    assert found is not None and np.abs(found - from_8_bit).max() < 0.3
