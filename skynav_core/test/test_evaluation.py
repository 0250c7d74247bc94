# SPDX-License-Identifier: Apache-2.0
"""The helpers every evaluation command shares: methods, argument checks, text tables."""

from __future__ import annotations

import argparse
import math

import pytest

from skynav_core.cli import CliError
from skynav_core.evaluation import (
    Column,
    add_methods_argument,
    add_plots_argument,
    check_at_least,
    check_methods,
    check_not_negative,
    check_positive,
    check_recordings,
    plots_folder,
    text_table,
    unknown_methods,
)

KNOWN = ('fast', 'slow', 'peer')


def test_unknown_methods_are_named_with_the_registry():
    assert unknown_methods(['slow', 'fast'], KNOWN) is None
    assert unknown_methods(['fast', 'bogus', 'odd'], KNOWN) == 'unknown method bogus, odd (one of fast, slow, peer)'
    with pytest.raises(CliError, match='unknown method bogus') as refused:
        check_methods(['bogus'], KNOWN)
    assert refused.value.exit_code == 2


@pytest.mark.parametrize('default', [None, ('slow',)])
def test_the_methods_argument_defaults_to_the_registry_or_a_choice(default):
    parser = argparse.ArgumentParser()
    add_methods_argument(parser, KNOWN, default)
    add_plots_argument(parser, 'out_eval', 'the plot')
    args = parser.parse_args([])
    assert args.methods == list(KNOWN if default is None else default)
    assert str(args.plots) == 'out_eval'
    assert parser.parse_args(['--methods', 'peer', 'fast']).methods == ['peer', 'fast']
    helps = {action.dest: action.help for action in parser._actions}
    assert 'fast, slow, peer)' in helps['methods'] and helps['plots'] == 'folder for the plot (default out_eval)'


def test_numbers_out_of_range_are_a_malformed_command_line():
    check_at_least(1, 1, '--repeats')
    check_not_negative(0, '--index')
    check_positive(0.5, '--tolerance')
    for check, message in (
        (lambda: check_at_least(0, 1, '--repeats'), '--repeats must be at least 1'),
        (lambda: check_not_negative(-1, '--index'), '--index must not be negative'),
        (lambda: check_positive(0.0, '--tolerance'), '--tolerance must be more than 0'),
        (lambda: check_positive(math.nan, '--tolerance'), '--tolerance must be more than 0'),
    ):
        with pytest.raises(CliError, match=message) as refused:
            check()
        assert refused.value.exit_code == 2


def test_folders_and_recordings(tmp_path):
    assert plots_folder(tmp_path / 'a' / 'b').is_dir()
    (tmp_path / 'file').write_text('x')
    with pytest.raises(CliError, match='cannot create the folder for the plots') as refused:
        plots_folder(tmp_path / 'file' / 'plots')
    assert refused.value.exit_code == 1
    check_recordings([tmp_path / 'file'])
    with pytest.raises(CliError, match='missing.mcap: no such recording'):
        check_recordings([tmp_path / 'file', tmp_path / 'missing.mcap'])


def test_a_table_aligns_its_columns_under_a_rule():
    columns = (Column('method', 8, align='<'), Column('n', 3, 'd'), Column('median', 7, '.2f'), Column('ok', 5))
    table = text_table(columns, [('fast', 12, 0.125, '100%'), ('slow', 3, math.nan, '-')])
    assert table.splitlines() == [
        'method     n  median    ok',
        '--------------------------',
        'fast      12    0.12  100%',
        'slow       3     nan     -',
    ]


def test_a_table_without_gap_or_rule_and_a_short_row():
    columns = (Column('world', 8, align='<'), Column('mean', 7, '.1f'), Column('worst', 7, '.1f'))
    table = text_table(columns, [('', '(n=2)'), ('  park', 99.06, 96.91)], gap='', rule=False)
    assert table.splitlines() == ['world      mean  worst', '          (n=2)', '  park     99.1   96.9']
