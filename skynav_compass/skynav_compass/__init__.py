# SPDX-License-Identifier: Apache-2.0
"""The visual 3D compass: full 3D rotation between a current view and a snapshot, from the skyline, in the SH basis.

Convention (docs/interfaces.md, camera_link): every estimate is R with d_snapshot = R d_current for any direction d,
so f_snapshot(d) = f_current(R^T d); from ground-truth orientations of camera_link in map, R = Q_s^-1 Q_c.
R comes as a 3x3 matrix, a scipy Rotation or a quaternion (x, y, z, w). ZYZ Euler angles mean
R = Rz(alpha) Ry(beta) Rz(gamma); beta is the tilt between the two views' z axes.

Public names are loaded on first use (PEP 562), so `import skynav_compass` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from skynav_core.lazy import lazy_exports

_EXPORTS = {
    'compass': ('Compass', 'CompassConfig', 'MAX_TILT', 'any_tilt_config', 'estimate_rotation'),
    'estimate': ('CompassEstimate', 'Hypothesis'),
    'views': ('CompassView', 'cap_visibility'),
    'cost': ('COSTS', 'CostProblem', 'PreparedSnapshot', 'build_problem', 'cost_channels', 'prepare_snapshot'),
    'so3': (
        'EulerGrid',
        'so3_correlation',
        'correlation_products',
        'wigner_small_d_table',
        'generators',
        'so3_correlation_cells',
    ),
    'refine': ('refine', 'newton_prediction'),
    'verify': ('Verification', 'verify', 'recovered_masks'),
    'eval.exhaustive': ('ExhaustiveCompass', 'ExhaustiveConfig'),
    'eval.yaw': ('PanoramicCompass', 'YawCompass'),
    'eval.features': ('FeatureCompass', 'FeatureConfig', 'kabsch', 'eight_point', 'decompose_essential'),
    'eval.evaluation': (
        'CompassResult',
        'ConfidentStatistics',
        'ErrorStatistics',
        'angular_error',
        'confident_statistics',
        'error_statistics',
        'format_table',
        'heading_error',
        'plot_errors',
        'relative_tilt',
        'roc_auc',
        'summary_rows',
    ),
    'eval.methods': ('METHODS', 'NODE_METHODS', 'DEFAULT_METHODS', 'CompassMethod'),
    'eval.dataset': ('CompassSet', 'load_compass_set', 'true_rotation'),
    'eval.runner': (
        'ImageViews',
        'Images',
        'Method',
        'NodeViews',
        'RunResult',
        'build_method',
        'compass_result',
        'run_methods',
        'standard_methods',
        'timed_estimates',
    ),
    'eval.recording': (
        'ExternalSnapshot',
        'EvaluationError',
        'RecordingEvaluation',
        'evaluate_recording',
        'evaluate_views',
        'format_report',
        'recording_methods',
    ),
}
__getattr__, __dir__, __all__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # static analysers see the real imports
    from skynav_compass.compass import *  # noqa: F401,F403
    from skynav_compass.cost import *  # noqa: F401,F403
    from skynav_compass.estimate import *  # noqa: F401,F403
    from skynav_compass.eval.dataset import *  # noqa: F401,F403
    from skynav_compass.eval.evaluation import *  # noqa: F401,F403
    from skynav_compass.eval.exhaustive import *  # noqa: F401,F403
    from skynav_compass.eval.features import *  # noqa: F401,F403
    from skynav_compass.eval.methods import *  # noqa: F401,F403
    from skynav_compass.eval.recording import *  # noqa: F401,F403
    from skynav_compass.eval.runner import *  # noqa: F401,F403
    from skynav_compass.eval.yaw import *  # noqa: F401,F403
    from skynav_compass.refine import *  # noqa: F401,F403
    from skynav_compass.so3 import *  # noqa: F401,F403
    from skynav_compass.verify import *  # noqa: F401,F403
    from skynav_compass.views import *  # noqa: F401,F403
