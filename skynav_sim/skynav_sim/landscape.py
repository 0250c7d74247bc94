# SPDX-License-Identifier: Apache-2.0
"""Real skylines: photographed Stellarium landscapes as the backdrop of a synthetic world.

Debian's `stellarium-data` package (GPL) ships landscape panoramas of real places
with a transparent sky. skynav uses four of them, fetched on demand with
`apt-get download` into a cache folder and never shipped:

- `garching`: a rape field with far trees and buildings (photographed from a roof, so the skyline dips below 0);
- `guereins`: a meadow with trees, farm buildings and a pale barn;
- `hurricane`: snow-covered ground and tall conifers on a mountain ridge;
- `geneva`: a measured horizon line only (0-3.5 degrees, one low hill: an open field), ground in one colour.

The panorama is painted on a vertical cylinder of radius BACKDROP_DISTANCE around the
map origin, as Stellarium paints it around the observer: a camera at the centre, at the
camera's height on level ground, sees exactly the photograph; elsewhere it sees it with the parallax of that
one distance. Below the panorama lies the landscape's ground texture, a disc around the
nadir. Where the panorama is transparent the view sees the synthetic sky. Its colours
(sRGB, linearised) are the visible bands' albedos, red, green and blue, and blue stands
in for ultraviolet; a surface's radiance is that colour, as an albedo, under the synthetic
daylight's irradiance on a horizontal plane in the same band (the photograph keeps its own shading).

Azimuth here is the compass's: from north (+y of `map`) towards east (+x); panoramas
run left to right with it, as a camera turned to the right takes them.
"""

from __future__ import annotations

import configparser
import fcntl
import os
import shutil
import subprocess
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from skynav_core.colour import srgb_to_linear
from skynav_sim.errors import SimError

from .names import LANDSCAPES
from .robot import CAMERA_HEIGHT
from .sky import UV_GREEN

PACKAGE = 'stellarium-data'
PACKAGE_PREFIX = './usr/share/stellarium/landscapes/'
CACHE_ENVIRONMENT = 'SKYNAV_DATA'  # folder for fetched data (default ~/.cache/skynav)
BACKDROP_DISTANCE = 40.0  # m: radius of the cylinder the panorama is painted on
SKY_COVERAGE = 0.5  # a panorama pixel with less opacity than this is sky
POLYGON_ROWS_PER_DEGREE = 20  # raster of a polygonal horizon
POLYGON_COLUMNS = 7200
REMAP_WIDTH = 1024  # points per row of the maps handed to cv2.remap
FETCH_TIMEOUT = 600.0  # s for apt-get and unpacking
_COMPLETE = '.complete'
#: The photograph's channel (linear R, G, B) that is each band's albedo: blue stands in for ultraviolet.
BAND_CHANNEL = {'uv': 2, 'blue': 2, 'green': 1, 'red': 0}


class LandscapeUnavailable(SimError, RuntimeError):
    """The landscapes could not be fetched or read; the message is one line saying why."""


def cache_folder() -> Path:
    """Return the folder fetched data is kept in ($SKYNAV_DATA, else ~/.cache/skynav)."""
    configured = os.environ.get(CACHE_ENVIRONMENT)
    return Path(configured) if configured else Path.home() / '.cache' / 'skynav'


def fetch(cache: Path | None = None) -> Path:
    """Return the folder holding the four landscapes, downloading and unpacking stellarium-data once."""
    root = (cache or cache_folder()) / PACKAGE
    if (root / _COMPLETE).exists():
        return root
    root.mkdir(parents=True, exist_ok=True)
    with open(root.parent / f'.{PACKAGE}.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # concurrent test runs fetch once
        if not (root / _COMPLETE).exists():
            _download_and_unpack(root)
    return root


def _download_and_unpack(root: Path) -> None:
    """Download the package with apt-get (updating the package lists if needed) and unpack the four landscapes."""
    if shutil.which('apt-get') is None or shutil.which('dpkg-deb') is None:
        raise LandscapeUnavailable(f'{PACKAGE} needs apt-get and dpkg-deb (a Debian system) to be fetched')
    with tempfile.TemporaryDirectory(dir=root.parent) as scratch:
        if _run(['apt-get', 'download', PACKAGE], scratch) != 0:
            _run(['apt-get', 'update', '-qq'], scratch)
            if _run(['apt-get', 'download', PACKAGE], scratch) != 0:
                raise LandscapeUnavailable(f'apt-get download {PACKAGE} failed (no network or no Debian archive)')
        package = next(Path(scratch).glob('*.deb'))
        unpacked = Path(scratch) / 'landscapes'
        with subprocess.Popen(['dpkg-deb', '--fsys-tarfile', str(package)], stdout=subprocess.PIPE) as dpkg:
            with tarfile.open(fileobj=dpkg.stdout, mode='r|') as archive:
                for member in archive:
                    relative = _wanted(member)
                    if relative is not None:
                        member.name = relative
                        archive.extract(member, unpacked, filter='data')
        if dpkg.returncode != 0:
            raise LandscapeUnavailable(f'dpkg-deb could not unpack {package.name}')
        for name in LANDSCAPES:
            if not (unpacked / name / 'landscape.ini').exists():
                raise LandscapeUnavailable(f'{package.name} has no landscape {name!r}')
            shutil.rmtree(root / name, ignore_errors=True)
            shutil.move(unpacked / name, root / name)
    (root / _COMPLETE).write_text(package.name + '\n')


def _wanted(member: tarfile.TarInfo) -> str | None:
    """Return the path below landscapes/ of an archive member of the four landscapes (texts in English only)."""
    if not member.isfile() or not member.name.startswith(PACKAGE_PREFIX):
        return None
    relative = member.name[len(PACKAGE_PREFIX) :]
    landscape, _, file = relative.partition('/')
    if (
        landscape not in LANDSCAPES
        or '/' in file
        or (file.startswith('description.') and file != 'description.en.utf8')
    ):
        return None
    return relative


def _run(command: list[str], folder: str) -> int:
    """Run a command quietly in a folder; return its exit code (127 when it could not start)."""
    try:
        return subprocess.run(
            command, cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=FETCH_TIMEOUT
        ).returncode
    except (OSError, subprocess.TimeoutExpired):
        return 127


def bilinear(image: np.ndarray, columns: np.ndarray, rows: np.ndarray, border: int) -> np.ndarray:
    """Return an image (H, W, C) interpolated bilinearly at N points (pixel coordinates), shape (N, C)."""
    count = len(columns)
    width = REMAP_WIDTH
    padded = -(-count // width) * width  # cv2.remap takes maps of fewer than 32767 rows and columns
    maps = [np.pad(np.asarray(c, np.float32), (0, padded - count)).reshape(-1, width) for c in (columns, rows)]
    out = cv2.remap(image, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=border)
    return out.reshape(padded, image.shape[2])[:count]


@dataclass
class Landscape:
    """A landscape's panorama and ground as functions of direction (compass azimuth, altitude in rad)."""

    name: str
    panorama: np.ndarray  # (H, W + 1, 4) float32: linear R, G, B and opacity; columns over azimuth 0..2 pi
    top: float  # altitude (rad) of the panorama's upper edge
    bottom: float  # altitude (rad) of its lower edge
    tan_mode: bool  # rows linear in tan(altitude) instead of altitude
    ground: np.ndarray  # (G, G, 3) float32 linear RGB of the ground disc around the nadir
    ground_edge: float  # altitude (rad) of the ground disc's rim
    ground_rotation: float  # azimuth (rad) of the ground texture's upward direction

    def sample(self, azimuth: np.ndarray, altitude: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (ground (N,) bool, linear RGB (N, 3)) seen in directions of compass azimuth and altitude (rad)."""
        azimuth = np.mod(azimuth, 2 * np.pi)
        height, width = self.panorama.shape[:2]
        columns = azimuth / (2 * np.pi) * (width - 1) - 0.5
        if self.tan_mode:
            span = np.tan(self.top) - np.tan(self.bottom)
            fraction = (np.tan(self.top) - np.tan(np.clip(altitude, -1.5, 1.5))) / span
        else:
            fraction = (self.top - altitude) / (self.top - self.bottom)
        rows = fraction * height - 0.5
        decor = bilinear(self.panorama, columns, rows, cv2.BORDER_REPLICATE)
        on_panorama = (fraction >= 0) & (fraction <= 1)
        ground = on_panorama & (decor[:, 3] >= SKY_COVERAGE)
        colour = decor[:, :3].copy()
        below = (altitude < self.bottom) | ((altitude < self.ground_edge) & ~ground)
        if below.any():
            size = self.ground.shape[0]
            radius = 0.5 * (np.pi / 2 + altitude[below]) / (np.pi / 2 + self.ground_edge)  # texture radius 0..0.5
            angle = azimuth[below] - self.ground_rotation
            u = (0.5 + radius * np.sin(angle)) * size - 0.5
            v = (0.5 - radius * np.cos(angle)) * size - 0.5
            colour[below] = bilinear(self.ground, u, v, cv2.BORDER_REFLECT)
            ground = ground | below
        return ground, colour

    def horizon(self, azimuth: np.ndarray) -> np.ndarray:
        """Return the altitude (rad) of the skyline seen from the centre at compass azimuths (rad)."""
        altitudes = np.linspace(self.top, self.bottom, 2048)
        grid_azimuth = np.repeat(np.asarray(azimuth, float)[:, None], altitudes.size, axis=1)
        ground, _ = self.sample(grid_azimuth.ravel(), np.tile(altitudes, len(grid_azimuth)))
        first = np.argmax(ground.reshape(grid_azimuth.shape), axis=1)
        return altitudes[first]


def load(name: str, cache: Path | None = None) -> Landscape:
    """Return landscape `name` (one of LANDSCAPES), fetching stellarium-data first if needed."""
    if name not in LANDSCAPES:
        raise SimError(f'unknown landscape {name!r} (known: {", ".join(LANDSCAPES)})')
    folder = fetch(cache) / name
    ini = configparser.ConfigParser(interpolation=None, inline_comment_prefixes=(';',))
    ini.read(folder / 'landscape.ini', encoding='utf-8')
    section = ini['landscape']
    kind = section.get('type')
    if kind == 'old_style':
        return _old_style(name, folder, section)
    if kind == 'polygonal':
        return _polygonal(name, folder, section)
    raise LandscapeUnavailable(f'landscape {name!r} has type {kind!r}, which skynav does not read')


def _image(path: Path) -> np.ndarray:
    """Return an image file as float32 linear RGBA (opaque where it has no alpha)."""
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise LandscapeUnavailable(f'cannot read {path}')
    if raw.ndim == 2:
        raw = cv2.cvtColor(raw, cv2.COLOR_GRAY2BGR)
    rgb = srgb_to_linear(raw[..., 2::-1] / 255.0)
    alpha = raw[..., 3:4] / np.float32(255.0) if raw.shape[2] == 4 else np.ones(rgb.shape[:2] + (1,), np.float32)
    return np.concatenate([rgb, alpha.astype(np.float32)], axis=2)


def _old_style(name: str, folder: Path, section: configparser.SectionProxy) -> Landscape:
    """Return an 'old_style' landscape: side textures around the horizon, a ground texture below."""
    textures = {f'tex{k}': _image(folder / section[f'tex{k}']) for k in range(int(section['nbsidetex']))}
    sides = []
    for k in range(int(section['nbside'])):
        texture, x0, y0, x1, y1 = section[f'side{k}'].split(':')
        image = textures[texture]
        rows, columns = image.shape[:2]
        # texture coordinates run upwards from the image's bottom row
        crop = image[
            int(round((1 - float(y1)) * rows)) : int(round((1 - float(y0)) * rows)),
            int(round(float(x0) * columns)) : int(round(float(x1) * columns)),
        ]
        sides.append(crop)
    height = max(side.shape[0] for side in sides)
    sides = [cv2.resize(side, (side.shape[1], height), interpolation=cv2.INTER_AREA) for side in sides]
    panorama = _rotate_columns(np.concatenate(sides, axis=1), np.radians(float(section['decor_angle_rotatez'])))
    bottom = np.radians(float(section['decor_angle_shift']))
    top = bottom + np.radians(float(section['decor_alt_angle']))
    ground = _image(folder / section['groundtex'])[..., :3]
    return Landscape(
        name,
        _wrap(panorama),
        float(top),
        float(bottom),
        section.get('tan_mode', 'false').strip().lower() == 'true',
        np.ascontiguousarray(ground),
        float(np.radians(float(section['ground_angle_shift']))),
        float(np.radians(float(section['ground_angle_rotatez']))),
    )


def _polygonal(name: str, folder: Path, section: configparser.SectionProxy) -> Landscape:
    """Return a 'polygonal' landscape: a measured horizon line over ground of one colour."""
    points = np.loadtxt(folder / section['polygonal_horizon_list'], comments='#', ndmin=2)
    azimuth = np.radians(points[:, 0]) + np.radians(section.getfloat('polygonal_angle_rotatez', 0.0))
    order = np.argsort(np.mod(azimuth, 2 * np.pi))
    azimuth, altitude = np.mod(azimuth[order], 2 * np.pi), np.radians(points[order, 1])
    columns = (np.arange(POLYGON_COLUMNS) + 0.5) / POLYGON_COLUMNS * 2 * np.pi
    skyline = np.interp(columns, azimuth, altitude, period=2 * np.pi)
    top = float(np.ceil(np.degrees(skyline.max())) + 1.0)
    bottom = -10.0
    rows = int((top - bottom) * POLYGON_ROWS_PER_DEGREE)
    row_altitude = np.radians(top - (np.arange(rows) + 0.5) / POLYGON_ROWS_PER_DEGREE)
    colour = srgb_to_linear(np.array([float(v) for v in section['ground_color'].split(',')]))
    panorama = np.zeros((rows, POLYGON_COLUMNS, 4), np.float32)
    panorama[..., :3] = colour
    panorama[..., 3] = row_altitude[:, None] <= skyline[None, :]
    ground = np.broadcast_to(colour, (8, 8, 3)).astype(np.float32)
    return Landscape(
        name,
        _wrap(panorama),
        float(np.radians(top)),
        float(np.radians(bottom)),
        False,
        ground,
        float(np.radians(bottom)),
        0.0,
    )


def _rotate_columns(panorama: np.ndarray, azimuth: float) -> np.ndarray:
    """Return a panorama whose first column starts at compass azimuth `azimuth` rotated to start at azimuth 0."""
    shift = int(round(azimuth / (2 * np.pi) * panorama.shape[1]))
    return np.roll(panorama, shift, axis=1)


def _wrap(panorama: np.ndarray) -> np.ndarray:
    """Return a panorama with its first column repeated at the end, so interpolation wraps around azimuth."""
    return np.ascontiguousarray(np.concatenate([panorama, panorama[:, :1]], axis=1))


class Backdrop:
    """A landscape on a cylinder around the map origin, lit by the synthetic daylight: what rays from a camera see."""

    def __init__(
        self, landscape: Landscape, distance: float = BACKDROP_DISTANCE, eye_height: float = CAMERA_HEIGHT
    ) -> None:
        """Put a landscape on a cylinder of radius `distance` (m), seen undistorted from `eye_height` (m) above."""
        self.landscape = landscape
        self.distance = float(distance)
        self.eye_height = float(eye_height)

    @property
    def source(self) -> str:
        """Return one line saying what is real in views of this backdrop and where it comes from."""
        return (
            f'skyline and ground colours of the Stellarium landscape {self.landscape.name!r} ({PACKAGE}, GPL), '
            f'on a {self.distance:g} m backdrop under the synthetic sky'
        )

    def intersect(self, origin: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (distance m, compass azimuth rad, altitude rad from the centre's eye) where rays meet the cylinder."""
        origin = np.asarray(origin, float)
        horizontal = np.einsum('ij,ij->i', directions[:, :2], directions[:, :2])
        along = directions[:, :2] @ origin[:2]
        outside = self.distance**2 - origin[:2] @ origin[:2]
        if outside <= 0:
            raise SimError(f'the camera at {origin[:2]} stands outside the {self.distance:g} m backdrop')
        with np.errstate(divide='ignore', invalid='ignore'):
            t = (-along + np.sqrt(along**2 + horizontal * outside)) / horizontal
        vertical = horizontal < 1e-12
        t = np.where(vertical, np.inf, t)
        hits = origin + np.where(vertical, 0.0, t)[:, None] * directions
        azimuth = np.arctan2(hits[:, 0], hits[:, 1])
        altitude = np.where(
            vertical, np.sign(directions[:, 2]) * np.pi / 2, np.arctan2(hits[:, 2] - self.eye_height, self.distance)
        )
        return t, azimuth, altitude

    def shade(
        self, origin: np.ndarray, directions: np.ndarray, sky, bands: tuple[str, ...] = UV_GREEN
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """Return radiance per band of `bands`, whether each ray sees sky, and the distance to what it sees (m, inf
        for sky); rays from `origin` along `directions` (N, 3), both in map."""
        distance, azimuth, altitude = self.intersect(origin, directions)
        ground, colour = self.landscape.sample(azimuth, altitude)
        sky_hit = ~ground
        radiance = {}
        clouds = sky.cloud_density(directions[sky_hit], origin) if sky_hit.any() else None
        for band in bands:
            channel = BAND_CHANNEL[band]
            values = np.zeros(len(directions))
            if sky_hit.any():
                values[sky_hit] = sky.radiance(band, directions[sky_hit], origin, clouds)
            irradiance = sky.direct[band] * max(sky.sun[2], 0.0) * sky.sun_visibility(origin) + sky.diffuse[band]
            values[ground] = colour[ground, channel] * irradiance / np.pi
            radiance[band] = values
        return radiance, sky_hit, np.where(ground, np.minimum(distance, self.distance * 4), np.inf)
