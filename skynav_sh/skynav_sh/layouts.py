# SPDX-License-Identifier: Apache-2.0
"""The padded layout of real SH coefficients: every degree one row, so per-degree matrices act by batched matmul.

Coefficients (..., (L+1)^2) in the contract's flat order (index l*l + l + m, docs/interfaces.md) become
(..., L+1, 2L+1) arrays with entry [l, m + L] (zero where |m| > l). skynav_sh.rotation turns both layouts.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from skynav_sh.basis import degree_from_size, degree_order


@lru_cache(maxsize=16)
def _flat_to_padded(max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (row l, column m + L) of every flat coefficient index of degree L."""
    l, m = degree_order(max_degree)
    return np.asarray(l), np.asarray(m + max_degree)


def to_padded(coefficients: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return coefficients (..., (L'+1)^2) in the padded layout (..., L+1, 2L+1), truncated or zero-extended to L."""
    coefficients = np.asarray(coefficients, dtype=float)
    source = degree_from_size(coefficients.shape[-1])
    degree = source if max_degree is None else int(max_degree)
    keep = min(source, degree)
    rows, cols = _flat_to_padded(keep)
    out = np.zeros(coefficients.shape[:-1] + (degree + 1, 2 * degree + 1))
    out[..., rows, cols - keep + degree] = coefficients[..., : (keep + 1) ** 2]
    return out


def from_padded(padded: np.ndarray) -> np.ndarray:
    """Return the flat coefficients (..., (L+1)^2) of a padded array (..., L+1, 2L+1)."""
    rows, cols = _flat_to_padded(padded.shape[-2] - 1)
    return padded[..., rows, cols]
