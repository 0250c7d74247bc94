# SPDX-License-Identifier: Apache-2.0
"""Camera calibration files as ROS camera drivers read them: camera_calibration_parsers' YAML, equidistant model.

The file (written by `skynav calibrate`, read through a node's `camera_info_url`) holds `image_width`,
`image_height`, `camera_name`, `camera_matrix` (3x3), `distortion_model: equidistant`,
`distortion_coefficients` (1x4: k1..k4, OpenCV's fisheye meaning), `rectification_matrix` (3x3) and
`projection_matrix` (3x4), each matrix as {rows, cols, data} with data row by row. A URL is resolved as
camera_info_manager resolves it: `file:///abs/path.yaml`, `package://PKG/path.yaml` (the package's share
directory), or a plain path.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .camera import EquidistantCamera
from .errors import SkynavError

DISTORTION_MODEL = 'equidistant'
# The matrices of a calibration file and their sizes (rows, cols); distortion has one row of k1..k4.
MATRIX_SIZES = {
    'camera_matrix': (3, 3),
    'distortion_coefficients': (1, 4),
    'rectification_matrix': (3, 3),
    'projection_matrix': (3, 4),
}
# A camera matrix entry that must be 0 (skew, the last row's zeros) may differ from it by this much (px).
ZERO_TOLERANCE = 1e-9
FILE_SCHEME = 'file://'
PACKAGE_SCHEME = 'package://'


class CameraYamlError(SkynavError, ValueError):
    """A camera calibration file or URL that cannot be used; the message names the file and the problem."""


def camera_yaml_text(camera: EquidistantCamera, camera_name: str) -> str:
    """Return the camera_calibration_parsers YAML text of an equidistant camera (the layout its writer uses)."""
    fields = camera.camera_info_fields()
    matrices = {
        'camera_matrix': fields['k'],
        'distortion_coefficients': fields['d'],
        'rectification_matrix': fields['r'],
        'projection_matrix': fields['p'],
    }
    lines = [
        f'image_width: {camera.width}',
        f'image_height: {camera.height}',
        f'camera_name: {yaml.safe_dump(camera_name, default_style=None).splitlines()[0]}',
    ]
    for name, data in matrices.items():
        rows, cols = MATRIX_SIZES[name]
        if name == 'distortion_coefficients':  # camera_calibration_parsers writes the model just before D
            lines.append(f'distortion_model: {DISTORTION_MODEL}')
        values = ', '.join(repr(float(x)) for x in data)
        lines += [f'{name}:', f'  rows: {rows}', f'  cols: {cols}', f'  data: [{values}]']
    return '\n'.join(lines) + '\n'


def write_camera_yaml(path: str | os.PathLike, camera: EquidistantCamera, camera_name: str) -> None:
    """Write an equidistant camera to a calibration file at `path`, atomically (a temporary file, then a rename)."""
    path = Path(path)
    text = camera_yaml_text(camera, camera_name)
    if not path.parent.is_dir():
        raise CameraYamlError(f'{path.parent}: no such directory')
    try:
        handle, temporary = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.partial', dir=path.parent)
    except OSError as exc:
        raise CameraYamlError(f'{path}: cannot write here: {exc.strerror or exc}') from None
    try:
        with os.fdopen(handle, 'w') as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except OSError as exc:
        Path(temporary).unlink(missing_ok=True)
        raise CameraYamlError(f'{path}: cannot write: {exc.strerror or exc}') from None


def _matrix(document: dict, name: str, where: str) -> np.ndarray:
    """Return the matrix `name` of a calibration document with its contract's size; CameraYamlError if it has not."""
    rows, cols = MATRIX_SIZES[name]
    entry = document.get(name)
    if not isinstance(entry, dict) or not {'rows', 'cols', 'data'} <= entry.keys():
        raise CameraYamlError(f'{where}: {name} is not a matrix with rows, cols and data')
    if entry['rows'] != rows or entry['cols'] != cols:
        raise CameraYamlError(f'{where}: {name} is {entry["rows"]}x{entry["cols"]}, expected {rows}x{cols}')
    data = entry['data']
    if not isinstance(data, list) or len(data) != rows * cols:
        count = len(data) if isinstance(data, list) else 'no list of'
        raise CameraYamlError(f'{where}: {name} has {count} values, expected {rows * cols}')
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in data):
        raise CameraYamlError(f'{where}: {name} holds a value that is not a number')
    matrix = np.array(data, float).reshape(rows, cols)
    if not np.all(np.isfinite(matrix)):
        raise CameraYamlError(f'{where}: {name} holds a non-finite value')
    return matrix


def _size(document: dict, name: str, where: str) -> int:
    """Return the image size entry `name` (px); CameraYamlError unless it is a positive whole number."""
    value = document.get(name)
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise CameraYamlError(f'{where}: {name} is {value!r}, not a positive whole number of pixels')
    return value


def camera_from_document(document: Any, where: str) -> EquidistantCamera:
    """Return the camera a parsed calibration document describes; CameraYamlError naming `where` and the problem."""
    if not isinstance(document, dict):
        raise CameraYamlError(f'{where}: not a camera calibration file (no mapping of image_width, camera_matrix, ...)')
    model = document.get('distortion_model')
    if model != DISTORTION_MODEL:
        raise CameraYamlError(f'{where}: distortion_model is {model!r}; skynav reads {DISTORTION_MODEL!r} (fish-eye)')
    width, height = _size(document, 'image_width', where), _size(document, 'image_height', where)
    k = _matrix(document, 'camera_matrix', where)
    d = _matrix(document, 'distortion_coefficients', where)
    for name in ('rectification_matrix', 'projection_matrix'):
        if name in document:  # camera_calibration_parsers reads a file without them too
            _matrix(document, name, where)
    off_pattern = np.abs(k - np.array([[k[0, 0], 0, k[0, 2]], [0, k[1, 1], k[1, 2]], [0, 0, 1]]))
    if off_pattern.max() > ZERO_TOLERANCE:
        raise CameraYamlError(f'{where}: camera_matrix is not [fx 0 cx; 0 fy cy; 0 0 1] (skew or a bad last row)')
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise CameraYamlError(f'{where}: camera_matrix has focal lengths {k[0, 0]:g}, {k[1, 1]:g}; both must be > 0')
    k1, k2, k3, k4 = (float(x) for x in d.ravel())
    return EquidistantCamera(
        width, height, float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]), (k1, k2, k3, k4)
    )


def read_camera_yaml(path: str | os.PathLike) -> EquidistantCamera:
    """Return the equidistant camera of a calibration file; CameraYamlError (one line) if it cannot be used."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise CameraYamlError(f'{path}: no such camera calibration file') from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CameraYamlError(f'{path}: cannot read: {getattr(exc, "strerror", None) or exc}') from None
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        at = f' at line {mark.line + 1}' if mark is not None else ''
        raise CameraYamlError(f'{path}: not valid YAML{at}') from None
    return camera_from_document(document, str(path))


def resolve_camera_url(url: str) -> Path:
    """Return the file a camera_info_url names: file:// (as camera_info_manager strips it), package://, or a path."""
    if url.lower().startswith(FILE_SCHEME):
        return Path(url[len(FILE_SCHEME) :])
    if url.lower().startswith(PACKAGE_SCHEME):
        package, _, relative = url[len(PACKAGE_SCHEME) :].partition('/')
        from ament_index_python.packages import (  # noqa: PLC0415 (only package:// URLs need the ament index)
            PackageNotFoundError,
            get_package_share_directory,
        )

        try:
            return Path(get_package_share_directory(package)) / relative
        except PackageNotFoundError:
            raise CameraYamlError(f'{url}: package {package!r} is not installed (not in the ament index)') from None
        except (LookupError, ValueError, OSError) as exc:  # no AMENT_PREFIX_PATH, a malformed name
            raise CameraYamlError(f'{url}: cannot find package {package!r}: {exc}') from None
    scheme, separator, _ = url.partition('://')
    if separator and scheme.isidentifier():
        raise CameraYamlError(f'{url}: unsupported URL scheme {scheme!r}; use file:///path/camera.yaml')
    if not url:
        raise CameraYamlError('camera_info_url is empty: no calibration file named')
    return Path(url)


def camera_from_url(url: str) -> EquidistantCamera:
    """Return the camera of the calibration file a camera_info_url names; CameraYamlError (one line) if unusable."""
    return read_camera_yaml(resolve_camera_url(url))
