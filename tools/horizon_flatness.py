# SPDX-License-Identifier: Apache-2.0
"""Print how flat and open each real landscape's skyline is, as seen from the yard's centre.

    .venv/bin/python tools/horizon_flatness.py

The skyline's altitude is read from the panorama's opacity (skynav_sim.landscape.Landscape.horizon) at every
degree of azimuth. Per landscape: its median altitude (how open: near 0 the sky reaches down to the horizontal),
its spread over azimuth (standard deviation, 5th-95th percentile, range) and how much it changes when the view
turns (the mean absolute difference between the skyline and itself turned 10, 20, ... 180 degrees): the less,
the less a skyline compass has to tell one yaw from another. Fetches stellarium-data on first use (GPL data).
"""

from __future__ import annotations

import numpy as np

from skynav_sim.landscape import LANDSCAPES, load


def main() -> None:
    """Print one line per landscape."""
    azimuth = np.radians(np.arange(360.0))
    print('skyline altitude (deg): landscape, median, std, 5th..95th percentile, range, mean change with yaw')
    for name in LANDSCAPES:
        altitude = np.degrees(load(name).horizon(azimuth))
        change = np.mean([np.mean(np.abs(altitude - np.roll(altitude, shift))) for shift in range(10, 181, 10)])
        p5, p95 = np.percentile(altitude, [5, 95])
        print(
            f'{name:10s} {np.median(altitude):6.1f} {altitude.std():4.1f} {p5:6.1f}..{p95:5.1f}     '
            f'{np.ptp(altitude):5.1f}  {change:5.1f}'
        )


if __name__ == '__main__':
    main()
