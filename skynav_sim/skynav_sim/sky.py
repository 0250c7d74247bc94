# SPDX-License-Identifier: Apache-2.0
"""Daylight in four bands, ultraviolet (~360 nm), blue (~460 nm), green (~530 nm) and red (~610 nm): sun, sky
dome and clouds. A UV/green camera needs the first and third, a colour camera the last three.

Units: spectral irradiance W m^-2 nm^-1, spectral radiance W m^-2 sr^-1 nm^-1,
for every band alike (the contract's one fixed unit for 32FC1 images).

The model, kept simple and physical where it matters for sky/ground separation:
- Direct sunlight is attenuated by Beer-Lambert extinction along the air mass
  (Kasten-Young), with the optical depth of each band (Rayleigh plus aerosol):
  ultraviolet is attenuated far more, so low sun light is green-rich; Rayleigh scattering goes as
  wavelength^-4, so among the visible bands blue is scattered most and a low sun is red.
- The sky's diffuse irradiance is the scattered part of the beam, which makes
  the sky ultraviolet-rich (and blue) compared with the direct light; after sunset it
  fades exponentially with the sun's depression (civil twilight).
- The sky's radiance over the dome follows the Perez all-weather form (darkening
  or brightening toward the horizon, a bright circumsolar region), scaled so its
  cosine-weighted integral equals the diffuse irradiance. Ultraviolet skylight
  is more uniform (weaker circumsolar peak) than green.
- Clouds are a seeded fractal layer at CLOUD_ALTITUDE; they are bright in green
  and barely brighter than the clear sky in ultraviolet, as observed for UV
  imagery (Carey & Stuerzl 2011; Differt & Moeller 2016), at every time of day. In the visible
  bands a cloud scatters sun and sky light of every wavelength alike (Mie scattering on droplets),
  so it is white (bright, near neutral), tinted only by the light that falls on it.
Times from dawn to noon span well over two orders of magnitude of brightness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_sim.errors import SimError

from .noise import FractalNoise

BANDS = ('uv', 'blue', 'green', 'red')  # every band the daylight model knows
UV_GREEN = ('uv', 'green')  # what the UV/green camera sees
RGB = ('red', 'green', 'blue')  # what a colour camera sees, in its channel order
# Solar spectral irradiance at the top of the atmosphere, W m^-2 nm^-1, at 360, 460, 530 and 610 nm (Wehrli 1985;
# ASTM E-490), each a mean over about 10 nm.
EXTRATERRESTRIAL = {'uv': 1.05, 'blue': 2.05, 'green': 1.86, 'red': 1.73}
# Rayleigh + aerosol optical depth. Rayleigh at sea level (Bucholtz 1995: 0.56, 0.20, 0.11, 0.064 at 360, 460, 530,
# 610 nm, about wavelength^-4); aerosol an Angstroem law through the ultraviolet and green values' remainders
# (0.14 and 0.13: exponent 0.28, a clear continental atmosphere), 0.13 at 460 nm and 0.12 at 610 nm.
OPTICAL_DEPTH = {'uv': 0.70, 'blue': 0.33, 'green': 0.24, 'red': 0.19}
DOWNWARD_SCATTER = 0.55  # share of the scattered beam that reaches the ground as skylight
TWILIGHT_ELEVATION = np.radians(3.0)  # below this sun elevation the skylight fades exponentially ...
TWILIGHT_FADE = np.radians(1.6)  # ... by e per this depression
# Perez coefficients (a, b, c, d, e): horizon gradient, circumsolar peak and back-scatter per band (clear sky).
# Blue lies between ultraviolet and green by wavelength; red continues the trend: the longer the wavelength, the
# more of the skylight is the aerosol's forward scatter (a brighter circumsolar region and horizon).
PEREZ = {
    'uv': (-0.6, -0.35, 3.0, -2.0, 0.25),
    'blue': (-0.85, -0.33, 7.0, -2.6, 0.37),
    'green': (-1.0, -0.32, 10.0, -3.0, 0.45),
    'red': (-1.1, -0.30, 12.0, -3.0, 0.5),
}
SUN_ANGULAR_RADIUS = np.radians(0.8)  # drawn a little larger than the real 0.27 degrees so it covers pixels
CLOUD_ALTITUDE = 1500.0  # m
# Ultraviolet light is mostly diffuse already, so a cloud looks about as bright as the clear sky behind
# it; in the visible bands a cloud scatters the direct sunlight too and shines far brighter than blue sky.
CLOUD_UV_CONTRAST = 1.08  # cloud / clear-sky radiance in the same direction, ultraviolet
CLOUD_BRIGHTNESS = 0.85  # visible cloud radiance as a share of (direct normal + diffuse) / pi, the same share in
# every visible band (white); a cloud high in the air faces even a low sun


def air_mass(elevation: float) -> float:
    """Return the relative optical air mass for a sun elevation (rad), Kasten & Young (1989)."""
    degrees = max(np.degrees(elevation), -0.5)
    return 1.0 / (np.sin(np.radians(degrees)) + 0.50572 * (degrees + 6.07995) ** -1.6364)


def sun_position(hours: float, day_of_year: int = 172, latitude: float = np.radians(52.0)) -> tuple[float, float]:
    """Return (elevation, azimuth) of the sun in radians at local solar time `hours` (azimuth from north, eastward)."""
    declination = np.radians(23.44) * np.sin(2 * np.pi * (284 + day_of_year) / 365)
    hour_angle = np.radians(15.0 * (hours - 12.0))
    sin_el = np.sin(latitude) * np.sin(declination) + np.cos(latitude) * np.cos(declination) * np.cos(hour_angle)
    elevation = np.arcsin(sin_el)
    azimuth = np.arctan2(
        -np.cos(declination) * np.sin(hour_angle),
        np.cos(latitude) * np.sin(declination) - np.sin(latitude) * np.cos(declination) * np.cos(hour_angle),
    )
    return float(elevation), float(azimuth % (2 * np.pi))


# Named times of day (local solar time in June at 52 N): sun at -2, 5, 20, 40 and 61 degrees.
TIMES_OF_DAY = {'dawn': 3.35, 'sunrise': 4.45, 'morning': 6.2, 'forenoon': 8.5, 'noon': 12.0}


def parse_time(value: str | float) -> float:
    """Return local solar time in hours from a name in TIMES_OF_DAY or a number of hours."""
    if isinstance(value, str) and value in TIMES_OF_DAY:
        return TIMES_OF_DAY[value]
    try:
        hours = float(value)
    except ValueError:
        raise SimError(
            f'unknown time of day {value!r} (a number of hours or one of {", ".join(TIMES_OF_DAY)})'
        ) from None
    if not 0 <= hours <= 24:
        raise SimError(f'time of day {hours} h is not within 0-24 h')
    return hours


@dataclass
class Sky:
    """The light of one moment: sun direction, irradiances and the sky's radiance per band."""

    hours: float
    cloud_cover: float = 0.0  # 0 clear .. 1 overcast
    cloud_seed: int = 0

    def __post_init__(self) -> None:
        self.elevation, self.azimuth = sun_position(self.hours)
        # map frame: x east, y north; azimuth from north towards east.
        self.sun = np.array(
            [
                np.cos(self.elevation) * np.sin(self.azimuth),
                np.cos(self.elevation) * np.cos(self.azimuth),
                np.sin(self.elevation),
            ]
        )
        m = air_mass(self.elevation)
        fade = (
            1.0
            if self.elevation >= TWILIGHT_ELEVATION
            else np.exp((self.elevation - TWILIGHT_ELEVATION) / TWILIGHT_FADE)
        )
        effective_sine = max(np.sin(max(self.elevation, TWILIGHT_ELEVATION)), 1e-6) * fade
        self.direct = {}  # irradiance on a plane facing the sun
        self.diffuse = {}  # skylight on a horizontal plane
        for band in BANDS:
            transmitted = np.exp(-OPTICAL_DEPTH[band] * m)
            self.direct[band] = EXTRATERRESTRIAL[band] * transmitted if self.elevation > 0 else 0.0
            scattered = 1.0 - np.exp(-OPTICAL_DEPTH[band] * air_mass(max(self.elevation, TWILIGHT_ELEVATION)))
            self.diffuse[band] = EXTRATERRESTRIAL[band] * effective_sine * scattered * DOWNWARD_SCATTER
        self._zenith = {band: 1.0 for band in BANDS}
        self._normalise()
        self.clouds = FractalNoise(self.cloud_seed, scale=900.0, octaves=4, persistence=0.55)

    def global_irradiance(self, band: str) -> float:
        """Return direct plus diffuse irradiance (W m^-2 nm^-1) on a horizontal plane in `band`."""
        return self.direct[band] * max(self.sun[2], 0.0) + self.diffuse[band]

    def _perez(self, band: str, directions: np.ndarray) -> np.ndarray:
        a, b, c, d, e = PEREZ[band]
        cos_theta = np.clip(directions[..., 2], 0.02, 1.0)
        gamma = np.arccos(np.clip(directions @ self.sun, -1.0, 1.0))
        return (1 + a * np.exp(b / cos_theta)) * (1 + c * np.exp(d * gamma) + e * np.cos(gamma) ** 2)

    def _normalise(self) -> None:
        """Scale each band's zenith radiance so the dome's cosine-weighted integral is the diffuse irradiance."""
        mu, w = np.polynomial.legendre.leggauss(48)
        cos_theta = 0.5 * (mu + 1)  # upper hemisphere
        weights_theta = 0.5 * w
        phi = np.linspace(0, 2 * np.pi, 96, endpoint=False)
        ct, ph = np.meshgrid(cos_theta, phi, indexing='ij')
        st = np.sqrt(1 - ct**2)
        directions = np.stack([st * np.cos(ph), st * np.sin(ph), ct], axis=-1)
        for band in BANDS:
            shape = self._perez(band, directions)
            integral = np.sum(shape * ct * weights_theta[:, None]) * (2 * np.pi / len(phi))
            self._zenith[band] = self.diffuse[band] / integral

    def cloud_density(self, directions: np.ndarray, origin: np.ndarray) -> np.ndarray:
        """Return cloud cover in [0, 1] seen along upward directions (N, 3) from `origin` (map frame)."""
        if self.cloud_cover <= 0:
            return np.zeros(directions.shape[:-1])
        up = np.maximum(directions[..., 2], 0.03)
        reach = (CLOUD_ALTITUDE - origin[2]) / up
        x = origin[0] + reach * directions[..., 0]
        y = origin[1] + reach * directions[..., 1]
        field = 0.5 + 0.5 * self.clouds(x, y) / 0.6
        threshold = 1.0 - self.cloud_cover
        density = np.clip((field - threshold) / 0.15, 0.0, 1.0)
        return density * np.clip(directions[..., 2] / 0.05, 0.0, 1.0)

    def radiance(
        self, band: str, directions: np.ndarray, origin: np.ndarray, clouds: np.ndarray | None = None
    ) -> np.ndarray:
        """Return the radiance of the sky (sun and clouds included) seen along directions (N, 3) in `band`.

        `clouds` may pass the cloud_density of these directions when it is already known.
        """
        clear = self._zenith[band] * self._perez(band, directions)
        if clouds is None:
            clouds = self.cloud_density(directions, origin)
        if band == 'uv':
            cloud_radiance = CLOUD_UV_CONTRAST * clear
        else:
            lit = self.direct[band] + self.diffuse[band]
            cloud_radiance = np.maximum(clear, CLOUD_BRIGHTNESS * lit / np.pi)
        sky = clear * (1 - clouds) + cloud_radiance * clouds
        if self.elevation > -SUN_ANGULAR_RADIUS:
            on_sun = directions @ self.sun > np.cos(SUN_ANGULAR_RADIUS)
            disc_radiance = self.direct[band] / (np.pi * SUN_ANGULAR_RADIUS**2)
            sky = np.where(on_sun, np.maximum(sky, disc_radiance * (1 - 0.9 * clouds)), sky)
        return sky

    def sun_visibility(self, origin: np.ndarray) -> float:
        """Return the share of direct sunlight that the clouds let through toward `origin`."""
        return float(1.0 - 0.9 * self.cloud_density(self.sun[None, :], origin)[0]) if self.elevation > 0 else 0.0
