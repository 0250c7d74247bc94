# SPDX-License-Identifier: Apache-2.0
"""docs/results.md's regenerated blocks: the page and tools/results.py name the same evaluations and commands, and
regenerating a block writes what its command prints (run here on the bundled synthetic skyline sets)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from skynav_testing import run_skynav

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / 'docs' / 'results.md'
TOOL = ROOT / 'tools' / 'results.py'


def block(page: str, name: str) -> str:
    """Return the body of block `name` of the page."""
    return re.search(rf'<!-- results: {name} -->\n(.*?)<!-- /results -->', page, re.S)[1]


def test_the_page_shows_every_evaluation_with_the_commands_that_measure_it():
    done = subprocess.run([sys.executable, str(TOOL), '--check'], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout
    assert 'agrees with tools/results.py' in done.stdout


def test_a_regenerated_block_holds_its_commands_output_and_the_others_stay(tmp_path):
    page = tmp_path / 'results.md'
    text = PAGE.read_text()
    commands = re.match(r'```sh\n(.*?)\n```', block(text, 'skyline'), re.S)[1]
    stale = text.replace(block(text, 'skyline'), f'```sh\n{commands}\n```\n\nstale\n')
    page.write_text(stale)
    done = subprocess.run(
        [sys.executable, str(TOOL), '--page', str(page), '--only', 'skyline'], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stdout + done.stderr
    written = page.read_text()
    assert 'stale' not in block(written, 'skyline')
    # every other block and line of the page as it was
    assert written.replace(block(written, 'skyline'), '') == stale.replace(block(stale, 'skyline'), '')
    # the block's output is what its command prints here (the plot's line, a file in a scratch folder, left out)
    [command] = commands.splitlines()
    words = command.split()[1:]
    words[words.index('--plot') + 1] = str(tmp_path / 'skyline.png')
    printed = run_skynav(*words, cwd=ROOT)
    assert printed.returncode == 0, printed.stderr
    figures = [line.rstrip() for line in printed.stdout.splitlines() if line.strip() and 'saved' not in line]
    shown = re.search(r'```text\n(.*?)\n```', block(written, 'skyline'), re.S)[1]
    assert [line for line in shown.splitlines() if line.strip()] == figures
    assert re.search(r'At [0-9a-f]{7,}( and uncommitted changes)?, synthetic data', block(written, 'skyline'))
