# SPDX-License-Identifier: Apache-2.0
"""The README and the pages of docs/: every relative link leads to a file that exists, and to a heading of it.

The README is the five-minute page (issue 31): it stays short, and the reference lives in docs/, so the links
between them are what a reader follows. Anchors are GitHub's: the heading lowered, every character that is not a
word character, a hyphen or a space dropped, spaces turned into hyphens.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).parents[1]
PAGES = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
README_LINES = 300  # issue 31: a README a newcomer reads in five minutes


def prose(text: str) -> str:
    """Return a page without its fenced blocks."""
    return re.sub(r'^```.*?^```', '', text, flags=re.M | re.S)


def slug(heading: str) -> str:
    """Return the anchor GitHub gives a Markdown heading."""
    return re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')


def anchors(page: Path) -> set[str]:
    """Return the anchors of a Markdown page's headings."""
    return {slug(heading) for heading in re.findall(r'^#+ (.+)$', prose(page.read_text()), re.M)}


def test_every_link_of_the_readme_and_docs_leads_to_a_file_and_heading_that_exist():
    failures = []
    for page in PAGES:
        for link in re.findall(r'\]\(([^)\s]+)\)', prose(page.read_text())):
            if re.match(r'\w+://', link):
                continue
            path, _, anchor = link.partition('#')
            target = (page.parent / path).resolve() if path else page
            where = f'{page.relative_to(ROOT)}: {link}'
            if not target.exists():
                failures.append(f'{where}: no file {target}')
            elif anchor and (target.suffix != '.md' or anchor not in anchors(target)):
                failures.append(f'{where}: no heading #{anchor}')
    assert not failures, '\n'.join(failures)


def test_the_readme_stays_short_and_keeps_the_two_commands():
    text = (ROOT / 'README.md').read_text()
    assert len(text.splitlines()) <= README_LINES
    assert 'make demo' in text and 'make test' in text


def test_slug_is_githubs():
    assert slug('What the nodes report: `/diagnostics`') == 'what-the-nodes-report-diagnostics'
    assert slug('Sky/ground segmentation') == 'skyground-segmentation'
