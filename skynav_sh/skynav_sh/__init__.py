# SPDX-License-Identifier: Apache-2.0
"""Real spherical harmonics of fish-eye views: transform, rotation, spectra, translation.

The public names below are loaded on first use (PEP 562), so `import skynav_sh` stays light; every table
(Legendre values, quarter turns, Gaunt coefficients, translation blocks) is built lazily and cached.
Frames, angles and the coefficient order are those of docs/interfaces.md (camera_link, theta from +z, phi from +x to +y,
index l*l + l + m). Rotation convention: rotate(c, R) gives f(R^T d), so f_snapshot = rotate(f_current, R) for the
compass's d_snapshot = R d_current. Translation: translate(c, t / rho) gives g with g(normalise(d - t/rho)) = f(d).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from skynav_core.lazy import lazy_exports

_EXPORTS = {
    'basis': (
        'DEFAULT_DEGREE',
        'SPHERE_AREA',
        'degree_from_size',
        'degree_order',
        'degree_slices',
        'lm_index',
        'n_coefficients',
        'normalised_legendre',
        'real_sh',
        'real_sh_directions',
    ),
    'transform': ('GaussLegendreGrid', 'analysis', 'grid', 'synthesis', 'synthesis_at'),
    'fisheye': ('FILLS', 'FisheyeTransform', 'camera_image_values', 'image_values'),
    'layouts': ('from_padded', 'to_padded'),
    'rotation': (
        'apply_sparse',
        'quarter_turn',
        'quarter_turn_padded',
        'quarter_turn_sparse',
        'rotate',
        'rotate_by_matrix',
        'rotate_degree_major',
        'rotate_y',
        'rotate_z',
        'rotate_z_padded',
        'rotate_zyz',
        'wigner_d',
        'wigner_d_matrix',
        'wigner_d_recurrence',
        'wigner_small_d',
        'y_rotation_block',
        'z_phases',
        'z_rotation_blocks',
        'z_rotation_factors',
        'z_rotation_factors_padded',
        'z_rotation_index',
    ),
    'coupling': ('RealGaunt', 'real_gaunt'),
    'spectra': (
        'amplitude_distance',
        'amplitude_spectrum',
        'bispectrum',
        'bispectrum_distance',
        'bispectrum_size',
        'bispectrum_triples',
        'coefficient_distance',
        'illumination_invariant',
        'squared_distance',
    ),
    'product': (
        'MIN_CLASS_SHARE',
        'MaskedView',
        'cap_area',
        'inner',
        'masked_distance',
        'masked_distance_views',
        'message_sky_share',
        'overlap_area',
        'product',
        'seen_mean',
        'shows_skyline',
    ),
    'translation': ('source_directions', 'translate', 'translate_z', 'translated_directions', 'z_translation_blocks'),
}
__getattr__, __dir__, __all__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # static analysers see the real imports
    from skynav_sh.basis import *  # noqa: F401,F403
    from skynav_sh.coupling import *  # noqa: F401,F403
    from skynav_sh.fisheye import *  # noqa: F401,F403
    from skynav_sh.layouts import *  # noqa: F401,F403
    from skynav_sh.product import *  # noqa: F401,F403
    from skynav_sh.rotation import *  # noqa: F401,F403
    from skynav_sh.spectra import *  # noqa: F401,F403
    from skynav_sh.transform import *  # noqa: F401,F403
    from skynav_sh.translation import *  # noqa: F401,F403
