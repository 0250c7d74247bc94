# SPDX-License-Identifier: Apache-2.0
"""Fixtures of the repository-level tests."""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable

import pytest

from skynav_bringup.cli import main


def call_skynav(arguments: list[str]) -> tuple[int, str, str]:
    """Run the `skynav` main in this process, as the console script does; return (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(arguments)
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope='session')
def skynav_main() -> Callable[[list[str]], tuple[int, str, str]]:
    """Return a function that runs `skynav ARGUMENTS` in this process: (exit code, stdout, stderr)."""
    return call_skynav
