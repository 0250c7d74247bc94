# SPDX-License-Identifier: Apache-2.0
"""`skynav eval localization` run as a user runs it: its table is the library's figures of the same matches.

The bundled detour drive leaves the garden route for a loop up to 4.3 m away (42 of its 76 views are off the route),
so the order in which the precision-recall curve accepts matches decides its figures: by the acceptance score
(best / runner-up ratio), the sequence method reaches recall 0 at 100 % precision and the single-frame method 0.941;
ranked by the descriptor distance instead, both would read 0.971.
"""

from __future__ import annotations

import numpy as np

from skynav_core.maps import MapStore
from skynav_core.views import recording_views
from skynav_localize.eval.evaluation import evaluate
from skynav_localize.localizer import METHODS, Localizer
from skynav_testing import run_skynav

from .conftest import BAGS

DETOUR = BAGS / 'synthetic_garden_detour.mcap'
COMPARED = ('amplitude-seq', 'amplitude')


def table_rows(stdout: str) -> dict[str, list[str]]:
    """Return the rows of the printed table by method label: the cells after the label, as printed."""
    labels = {METHODS[name].label: name for name in COMPARED}
    rows = {}
    for line in stdout.splitlines():
        cells = line.split()
        if cells and cells[0] in labels:
            rows[labels[cells[0]]] = cells[1:]
    return rows


def test_eval_localization_prints_the_figures_of_matches_ranked_by_their_score(garden_map, tmp_path):
    result = run_skynav(
        'eval', 'localization', str(DETOUR), '--map', str(garden_map), '--methods', *COMPARED, '--plots', str(tmp_path)
    )
    assert result.returncode == 0, result.stderr
    assert "76 synthetic queries against map 'garden' (57 snapshots)" in result.stdout
    rows = table_rows(result.stdout)
    assert sorted(rows) == sorted(COMPARED)
    views = recording_views(DETOUR, images=False).views
    positions = np.stack([v.pose[:3] for v in views])
    coefficients = np.stack([v.coefficients for v in views])
    with MapStore.open(garden_map) as store:
        for name in COMPARED:
            matches = Localizer(store, name).match_sequence(
                coefficients=coefficients, field_of_view=views[0].field_of_view, fill=views[0].fill
            )
            expected = evaluate(
                name, matches.index, matches.score, positions, store.positions(), 1.0, accepted=matches.accepted
            )
            figures = (
                expected.recall_at_full_precision,
                expected.auc,
                expected.recall_at_1,
                expected.accepted_precision,
                expected.accepted_recall,
            )
            assert rows[name][:5] == [f'{value:.3f}' for value in figures], name
            assert rows[name][5] == f'{expected.off_route_accepted}/42' == '0/42'
            assert rows[name][6] == f'{expected.threshold_at_full_precision:.4g}'
    # the ranking matters here: ranked by distance the two methods' R@100%P would be alike
    assert rows['amplitude-seq'][0] != rows['amplitude'][0]
    assert (tmp_path / 'synthetic_garden_detour_pr.png').stat().st_size > 0
    assert (tmp_path / 'synthetic_garden_detour_matches.png').stat().st_size > 0
