# SPDX-License-Identifier: Apache-2.0
"""Homing by warping: the home vector from the current view to a snapshot's place, on bumpy ground.

- 3D-warping in the SH basis (warping3d): movement direction on the sphere, distance ratio and rotation, masked
  comparison of a hemispherical view; estimate_home_vector (homing) combines it with a compass rotation.
- Planar baselines on panoramic bands unwrapped from the fish-eye (panorama, planar): 2D-warping, min-warping.
- Evaluation against ground truth (evaluation; homing_eval runs every method over a recording's views for
  `skynav eval homing`), reading homing grids from recordings (recording), and made-up
  scenes with known geometry for tests (synthetic).

Conventions (docs/interfaces.md): everything in the current camera_link (z up through the fish-eye, x forward = image
right, y left = image down); the home vector points from the current place to the snapshot's place,
Q_c^-1 (p_s - p_c) normalised; the rotation R maps current to snapshot directions, d_snapshot = R d_current.
Public names load on first use (PEP 562), so `import skynav_warping` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from skynav_core.lazy import lazy_exports

_EXPORTS = {
    'views': (
        'DEFAULT_RIM_TAPER',
        'WarpView',
        'cap_fraction',
        'rim_weights',
        'view_from_coefficients',
        'view_from_fisheye',
        'view_from_samples',
    ),
    'warping3d': (
        'WarpResult',
        'WarpingSettings',
        'align_rotation',
        'coarse_costs',
        'hypothesis_costs',
        'tilt_hypotheses',
        'warp_home_vector',
        'warping_tables',
    ),
    'homing': ('HomeEstimate', 'estimate_home_vector'),
    'eval.panorama': ('DEFAULT_ELEVATIONS', 'PanoramaUnwrapper'),
    'eval.planar': (
        'PlanarResult',
        'horizon_profile',
        'min_warping',
        'min_warping_costs',
        'scale_planes',
        'warping_2d',
    ),
    'eval.evaluation': (
        'DISTANCE_BINS',
        'TILT_BINS',
        'BinStatistics',
        'angular_errors',
        'binned_statistics',
        'home_vectors_in_map',
        'quiver_plot',
        'rotation_errors',
        'seconds_per_call',
        'summary_table',
        'tilt_angles',
        'true_home_directions',
        'true_rotations',
    ),
    'eval.methods': ('METHODS', 'PANORAMA_METHODS'),
    'eval.recording': ('HomingGrid', 'load_homing_grid'),
    'eval.homing_eval': (
        'HomingEvalError',
        'HomingEvaluation',
        'HomingSnapshot',
        'HomingResult',
        'evaluate_homing',
        'map_snapshot',
        'recording_snapshot',
    ),
    'eval.synthetic': (
        'BlobScene',
        'PoleWorld',
        'blob_scene',
        'pole_world',
        'render_equal_distance_view',
        'render_pole_panorama',
    ),
}
__getattr__, __dir__, __all__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # static analysers see the real imports
    from skynav_warping.eval.evaluation import *  # noqa: F401,F403
    from skynav_warping.eval.homing_eval import *  # noqa: F401,F403
    from skynav_warping.eval.methods import *  # noqa: F401,F403
    from skynav_warping.eval.panorama import *  # noqa: F401,F403
    from skynav_warping.eval.planar import *  # noqa: F401,F403
    from skynav_warping.eval.recording import *  # noqa: F401,F403
    from skynav_warping.eval.synthetic import *  # noqa: F401,F403
    from skynav_warping.homing import *  # noqa: F401,F403
    from skynav_warping.views import *  # noqa: F401,F403
    from skynav_warping.warping3d import *  # noqa: F401,F403
