# SPDX-License-Identifier: Apache-2.0
"""skynav_core.names and docs/interfaces.md name the same topics, actions and frames, and the node names are
those of the `skynav.nodes` entry points: the module and the page cannot drift apart."""

from __future__ import annotations

import configparser
import re
import subprocess
import sys
from pathlib import Path

from skynav_core import names

ROOT = Path(__file__).resolve().parents[1]


def constants(suffix: str = '') -> dict[str, str]:
    """Return the module's string constants (those whose name ends with `suffix`)."""
    return {k: v for k, v in vars(names).items() if k.isupper() and isinstance(v, str) and k.endswith(suffix)}


def table_names(text: str) -> set[str]:
    """Return the names in the first column of every table row of a markdown page (`| `name` | ...`)."""
    return set(re.findall(r'^\| `([^`]+)`(?: \(.*?\))? \|', text, re.M))


def test_every_topic_and_action_is_in_the_tables_of_the_interfaces_page_and_back():
    documented = {name for name in table_names((ROOT / 'docs' / 'interfaces.md').read_text()) if name.startswith('/')}
    in_module = {v for v in constants().values() if v.startswith('/')}
    assert in_module == documented


def test_the_frames_are_those_of_the_interfaces_page():
    text = (ROOT / 'docs' / 'interfaces.md').read_text()
    section = text[text.index('## Frames and angles') : text.index('## Camera model')]
    assert set(constants('_FRAME').values()) == table_names(section)


def test_a_name_is_written_once_in_the_module():
    values = list(constants().values())
    assert sorted(v for v in set(values) if values.count(v) > 1) == []


def test_the_node_names_are_the_entry_points_of_the_packages():
    entry_points = set()
    for path in ROOT.glob('*/setup.cfg'):
        config = configparser.ConfigParser()
        config.read(path)
        if config.has_option('options.entry_points', 'skynav.nodes'):
            lines = config.get('options.entry_points', 'skynav.nodes').strip().splitlines()
            entry_points |= {line.partition('=')[0].strip() for line in lines}
    assert set(constants('_NODE').values()) == entry_points


def test_importing_the_module_loads_no_ros():
    code = 'import sys, skynav_core.names; print(sorted(m for m in sys.modules if m.startswith(("rclpy", "numpy"))))'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == '[]'
