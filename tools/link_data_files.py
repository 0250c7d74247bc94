# SPDX-License-Identifier: Apache-2.0
"""Symlink the data_files of ament_python packages into an install prefix.

    python tools/link_data_files.py PREFIX PACKAGE_DIR...

`pip install -e` does not install a package's data_files (its package.xml,
the ament index marker, config and launch files under share/, as its
setup.cfg declares them), so `get_package_share_directory` would not find
it. This does what colcon's --symlink-install does: each file is linked, so
edits in the source tree are seen at once. Links that point into a package's source but whose file is gone
are removed.
"""

from __future__ import annotations

import configparser
import sys
from pathlib import Path


def data_files(package_dir: Path) -> list[tuple[str, list[str]]]:
    """Return the data_files a package's setup.cfg declares (paths relative to the package, globs expanded)."""
    config = configparser.ConfigParser()
    config.read(package_dir / 'setup.cfg')
    if not config.has_section('options.data_files'):
        return []
    declared = []
    for target, patterns in config.items('options.data_files'):
        files = sorted(
            str(path.relative_to(package_dir)) for pattern in patterns.split() for path in package_dir.glob(pattern)
        )
        declared.append((target, files))
    return declared


def link(prefix: Path, package_dir: Path) -> int:
    """Link one package's data files under `prefix`; return how many links exist now."""
    count = 0
    for target_dir, sources in data_files(package_dir):
        for source in sources:
            src = (package_dir / source).resolve()
            dst = prefix / target_dir / src.name
            dst.parent.mkdir(parents=True, exist_ok=True)
            if dst.is_symlink() or dst.exists():
                dst.unlink()
            dst.symlink_to(src)
            count += 1
    share = prefix / 'share' / package_dir.name
    for path in share.rglob('*') if share.is_dir() else []:
        if path.is_symlink() and not path.exists():
            path.unlink()
    return count


def main() -> int:
    prefix = Path(sys.argv[1]).resolve()
    for package in sys.argv[2:]:
        package_dir = Path(package).resolve()
        print(f'{package_dir.name}: {link(prefix, package_dir)} data files linked into {prefix}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
