# SPDX-License-Identifier: Apache-2.0
"""Benchmark: skynav_sh transforms, fish-eye path, rotation and descriptors against ducc0, on one thread.

    .venv/bin/python bench/sh_transform.py [--quick]

Prints, for L = 16, 32, 64 (and 128 for the transforms), the time per forward transform (analysis), inverse
(synthesis), fish-eye mask -> coefficients (640x480, 200-degree equidistant camera), general rotation, amplitude
spectrum and bispectrum; next to it the same work done by ducc0 (Gauss-Legendre analysis_2d / synthesis_2d,
rotate_alm; the fish-eye peer is our sampling followed by ducc0's analysis) and the ratio ours / ducc0. Before
timing, it checks the conversion between ducc0's complex a_lm and the contract's real coefficients both ways.
"""

from __future__ import annotations

import os

for _variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMEXPR_NUM_THREADS'):
    os.environ[_variable] = '1'  # before numpy loads its BLAS

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402

MIN_SECONDS = 0.2  # s of repetitions per measurement
REPEATS = 5  # measurements; the best counts


def seconds_per_call(function: Callable[[], object], min_seconds: float = MIN_SECONDS) -> float:
    """Return the best over REPEATS of the mean time (s) of one call, each run lasting about min_seconds."""
    function()
    start = time.perf_counter()
    function()
    once = max(time.perf_counter() - start, 1e-7)
    loops = max(1, int(min_seconds / REPEATS / once))
    best = float('inf')
    for _ in range(REPEATS):
        start = time.perf_counter()
        for _ in range(loops):
            function()
        best = min(best, (time.perf_counter() - start) / loops)
    return best


def healpy_index(degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (l, m, index) of ducc0's complex a_lm (m >= 0, m-major healpy order)."""
    l, m = np.array([(l, m) for m in range(degree + 1) for l in range(m, degree + 1)]).T
    return l, m, m * (2 * degree + 1 - m) // 2 + l


def real_to_complex(coefficients: np.ndarray, degree: int) -> np.ndarray:
    """Contract real c_lm -> ducc0/healpy complex a_lm (with Condon-Shortley phase), m >= 0."""
    l, m, index = healpy_index(degree)
    alm = np.zeros((degree + 1) * (degree + 2) // 2, dtype=complex)
    sign = (-1.0) ** m
    cos_part = coefficients[l * l + l + m]
    sin_part = np.where(m > 0, coefficients[l * l + l - m], 0.0)
    alm[index] = np.where(m == 0, cos_part, sign * (cos_part - 1j * sin_part) / np.sqrt(2))
    return alm


def complex_to_real(alm: np.ndarray, degree: int) -> np.ndarray:
    """ducc0/healpy complex a_lm -> contract real c_lm: c_l0 = a_l0, c_l(+-m) = sqrt2 (-1)^m (Re a, -Im a)."""
    l, m, index = healpy_index(degree)
    out = np.zeros((degree + 1) ** 2)
    a = alm[index]
    sign = (-1.0) ** m
    out[l * l + l + m] = np.where(m == 0, a.real, np.sqrt(2) * sign * a.real)
    positive = m > 0
    out[(l * l + l - m)[positive]] = -np.sqrt(2) * (sign * a.imag)[positive]
    return out


def check_conversion(degree: int) -> float:
    """Return the worst disagreement between ours and ducc0 on transforms and a rotation (after conversion)."""
    import ducc0
    from scipy.spatial.transform import Rotation

    from skynav_core.rotations import zyz_angles
    from skynav_sh import grid, rotate

    rng = np.random.default_rng(degree)
    coefficients = rng.standard_normal((degree + 1) ** 2)
    g = grid(degree)
    samples = g.synthesis(coefficients)
    by_ducc = ducc0.sht.experimental.analysis_2d(map=samples[None], spin=0, lmax=degree, geometry='GL', nthreads=1)
    worst = np.abs(complex_to_real(by_ducc[0], degree) - coefficients).max()
    ducc_samples = ducc0.sht.experimental.synthesis_2d(
        alm=real_to_complex(coefficients, degree)[None],
        spin=0,
        lmax=degree,
        geometry='GL',
        ntheta=g.n_theta,
        nphi=g.n_phi,
        nthreads=1,
    )[0]
    worst = max(worst, np.abs(ducc_samples - samples).max() / np.abs(samples).max())
    rotation = Rotation.from_rotvec([0.3, -1.1, 0.7])
    alpha, beta, gamma = zyz_angles(rotation)  # ducc0: psi about z, theta about y, phi about z, extrinsic
    turned = ducc0.sht.rotate_alm(real_to_complex(coefficients, degree), degree, gamma, beta, alpha, nthreads=1)
    return max(worst, np.abs(complex_to_real(turned, degree) - rotate(coefficients, rotation)).max())


def skyline_mask(camera) -> np.ndarray:
    """A 640x480 uint8 mask (255 sky) of a rippled skyline, labelled at pixel centres."""
    from skynav_core.camera import angles_from_directions

    theta, phi = angles_from_directions(camera.pixel_directions())
    skyline = np.pi / 2 - (0.25 + 0.1 * np.sin(3 * phi) + 0.05 * np.cos(7 * phi + 1.0))
    return np.where(theta < skyline, 255, 0).astype(np.uint8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='shorter measurements (noisier)')
    arguments = parser.parse_args()
    min_seconds = 0.05 if arguments.quick else MIN_SECONDS

    import ducc0
    from scipy.spatial.transform import Rotation

    from skynav_core.camera import EquidistantCamera
    from skynav_core.rotations import zyz_angles
    from skynav_sh import (
        FisheyeTransform,
        MaskedView,
        amplitude_spectrum,
        bispectrum,
        bispectrum_size,
        grid,
        masked_distance_views,
        quarter_turn,
        rotate,
    )

    def measure(function: Callable[[], object]) -> float:
        return seconds_per_call(function, min_seconds)

    print('conversion check (ours vs ducc0 after real<->complex, max |difference|):')
    for degree in (16, 64):
        error = check_conversion(degree)
        print(f'  L={degree:3d}: {error:.1e}')
        if error > 1e-9:
            raise SystemExit('ducc0 and skynav_sh disagree: the conversion or a transform is wrong')

    rows: list[tuple[str, int, float, float | None]] = []
    rng = np.random.default_rng(0)
    for degree in (16, 32, 64, 128):
        coefficients = rng.standard_normal((degree + 1) ** 2)
        g = grid(degree)
        samples = g.synthesis(coefficients)
        ducc_map = samples[None].copy()
        alm = real_to_complex(coefficients, degree)[None]
        rows.append(
            (
                'forward transform (analysis)',
                degree,
                measure(lambda: g.analysis(samples)),
                measure(
                    lambda: ducc0.sht.experimental.analysis_2d(
                        map=ducc_map, spin=0, lmax=degree, geometry='GL', nthreads=1
                    )
                ),
            )
        )
        rows.append(
            (
                'inverse transform (synthesis)',
                degree,
                measure(lambda: g.synthesis(coefficients)),
                measure(
                    lambda: ducc0.sht.experimental.synthesis_2d(
                        alm=alm, spin=0, lmax=degree, geometry='GL', ntheta=g.n_theta, nphi=g.n_phi, nthreads=1
                    )
                ),
            )
        )

    camera = EquidistantCamera.for_field_of_view(640, 480, np.radians(200))
    mask = skyline_mask(camera)
    rotation = Rotation.from_rotvec([0.3, -1.1, 0.7])
    alpha, beta, gamma = zyz_angles(rotation)
    for degree in (16, 32, 64):
        transform = FisheyeTransform(camera, degree)  # defaults: zero fill, 4x finer grid, 2x2 sub-samples
        fine = transform.grid
        rows.append(
            (
                f'fish-eye mask -> coeffs ({fine.n_theta}x{fine.n_phi} grid)',
                degree,
                measure(lambda: transform.coefficients(mask)),
                measure(
                    lambda: ducc0.sht.experimental.analysis_2d(
                        map=transform.samples(mask)[None], spin=0, lmax=degree, geometry='GL', nthreads=1
                    )
                ),
            )
        )
        coefficients = rng.standard_normal((degree + 1) ** 2)
        alm = real_to_complex(coefficients, degree)
        quarter_turn(degree)  # the cached table is built once per degree
        rows.append(
            (
                'general rotation',
                degree,
                measure(lambda: rotate(coefficients, rotation)),
                measure(lambda: ducc0.sht.rotate_alm(alm, degree, gamma, beta, alpha, nthreads=1)),
            )
        )
        rows.append(('amplitude spectrum', degree, measure(lambda: amplitude_spectrum(coefficients)), None))
        rows.append(
            (
                f'bispectrum ({bispectrum_size(degree)} triples, grid)',
                degree,
                measure(lambda: bispectrum(coefficients)),
                None,
            )
        )
        visibility = transform.visibility_coefficients
        view = MaskedView.from_coefficients(transform.coefficients(mask), visibility)
        rows.append(
            (
                'masked view terms (v, v f, v f^2)',
                degree,
                measure(lambda: MaskedView.from_coefficients(coefficients, visibility)),
                None,
            )
        )
        rows.append(
            (
                'rotate masked view + masked distance',
                degree,
                measure(lambda: masked_distance_views(view.rotated(rotation), view)),
                None,
            )
        )
        if degree <= 16:
            bispectrum(coefficients, method='gaunt')  # builds the cached Gaunt table
            rows.append(
                (
                    'bispectrum (Gaunt contraction)',
                    degree,
                    measure(lambda: bispectrum(coefficients, method='gaunt')),
                    None,
                )
            )

    print()
    print('one thread; best of 5 runs; ducc0', ducc0.__version__, '| numpy', np.__version__)
    header = f'{"operation":<44} {"L":>4} {"ours ms":>10} {"ducc0 ms":>10} {"ours/ducc0":>11}'
    print(header)
    print('-' * len(header))
    for name, degree, ours, peer in rows:
        peer_text = f'{peer * 1e3:10.3f}' if peer is not None else f'{"-":>10}'
        ratio_text = f'{ours / peer:11.2f}' if peer is not None else f'{"-":>11}'
        print(f'{name:<44} {degree:>4} {ours * 1e3:10.3f} {peer_text} {ratio_text}')
    print()
    print('fish-eye peer = our remap sampling + ducc0 analysis on the same grid (ducc0 has no fish-eye reader);')
    print('rotation peer = ducc0.sht.rotate_alm on the complex a_lm (same rotation, checked above).')


if __name__ == '__main__':
    main()
