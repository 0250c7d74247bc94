"""Run one node process: ``python -m skynav_bringup.run_node MODULE:FUNCTION [--ros-args ...]``.

`skynav launch` starts every node this way; FUNCTION is the node's
``main(args=None)`` and receives the remaining arguments for rclpy.
"""

from __future__ import annotations

import importlib
import sys


def main() -> int:
    """Import MODULE, call FUNCTION(args=[...]) and return its exit code."""
    if len(sys.argv) < 2 or ':' not in sys.argv[1]:
        print('usage: python -m skynav_bringup.run_node MODULE:FUNCTION [--ros-args ...]', file=sys.stderr)
        return 2
    module_name, function_name = sys.argv[1].split(':', 1)
    function = getattr(importlib.import_module(module_name), function_name)
    return function(args=sys.argv[1:]) or 0


if __name__ == '__main__':
    sys.exit(main())
