# SPDX-License-Identifier: Apache-2.0
"""The /skyline/sh messages (skynav_msgs/ShCoefficients) as the localize, compass and warping nodes take them.

One check with one set of reasons for a message a node cannot use, counted in /diagnostics as rejected_<reason>
(checked in this order, the first that applies counts):

- 'malformed': the number of coefficients is not (max_degree + 1)^2;
- 'non_finite': a coefficient is NaN or infinite;
- 'degree': the message's degree is lower than the node needs;
- 'fill': the fill is not one the node can use.

Coefficient order, basis and fill: docs/interfaces.md, 'Real spherical harmonics'. Logic only (no rclpy).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import Any

import numpy as np

from .images import stamp_ns

SH_REJECTIONS = ('malformed', 'non_finite', 'degree', 'fill')  # the reasons, in the order they are checked


def usable_coefficients(
    message: Any, reject: Callable[[str, str], None], degree: int = 0, fills: Collection[str] | None = None
) -> np.ndarray | None:
    """Return the coefficients (float64) of an ShCoefficients message, or None after rejecting it with its reason.

    degree: the least degree the node needs; fills: the fills it takes (None: any).
    """
    coefficients = np.asarray(message.coefficients, np.float64)
    max_degree = int(message.max_degree)
    view = f'view stamped {stamp_ns(message.header)}'
    if coefficients.size != (max_degree + 1) ** 2:
        reject('malformed', f'{view}: {coefficients.size} coefficients for degree {max_degree}')
    elif not np.all(np.isfinite(coefficients)):
        reject('non_finite', f'{view} has NaN or infinite coefficients')
    elif max_degree < degree:
        reject('degree', f'{view}: coefficients of degree {max_degree}; this node needs degree {degree}')
    elif fills is not None and message.fill not in fills:
        reject('fill', f'{view}: coefficients filled with {message.fill!r}; this node takes {", ".join(fills)}')
    else:
        return coefficients
    return None
