# SPDX-License-Identifier: Apache-2.0
"""Run one node in a process of its own: ``python -m skynav_core.run_node MODULE:CLASS [--ros-args ...]``.

`skynav launch` starts every node this way.
"""

from __future__ import annotations

import importlib
import sys

from .ros import run_node


def main() -> int:
    """Import MODULE, run CLASS until Ctrl-C and return the exit code."""
    if len(sys.argv) < 2 or ':' not in sys.argv[1]:
        print('usage: python -m skynav_core.run_node MODULE:CLASS [--ros-args ...]', file=sys.stderr)
        return 2
    module_name, class_name = sys.argv[1].split(':', 1)
    node_class = getattr(importlib.import_module(module_name), class_name)
    return run_node(node_class, args=sys.argv[1:])


if __name__ == '__main__':
    sys.exit(main())
