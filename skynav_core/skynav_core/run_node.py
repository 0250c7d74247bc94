# SPDX-License-Identifier: Apache-2.0
"""Run one node in a process of its own: ``python -m skynav_core.run_node MODULE:CLASS [--ros-args ...]``.

`skynav launch` starts every node this way.
"""

from __future__ import annotations

import faulthandler
import importlib
import signal
import sys
from types import FrameType
from typing import NoReturn

#: On this signal the node writes every thread's Python stack to stderr and goes on (`skynav launch` sends it to a
#: node that has not stopped before it kills the node).
STACKS_SIGNAL = signal.SIGUSR1


def _stop_while_loading(signum: int, frame: FrameType | None) -> NoReturn:
    """End the process quietly: a Ctrl-C or SIGINT that came before the node ran has nothing to clean up."""
    raise SystemExit(0)


def main() -> int:
    """Import MODULE, run CLASS until Ctrl-C and return the exit code."""
    if len(sys.argv) < 2 or ':' not in sys.argv[1]:
        print('usage: python -m skynav_core.run_node MODULE:CLASS [--ros-args ...]', file=sys.stderr)
        return 2
    module_name, class_name = sys.argv[1].split(':', 1)
    faulthandler.register(STACKS_SIGNAL, all_threads=True)  # a node that will not stop shows where it hangs
    signal.signal(signal.SIGINT, _stop_while_loading)
    from .ros import run_node  # noqa: PLC0415 (rclpy loads after the handler that makes an early Ctrl-C quiet)

    node_class = getattr(importlib.import_module(module_name), class_name)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # from here run_node's own handling applies
    return run_node(node_class, args=sys.argv[1:])


if __name__ == '__main__':
    sys.exit(main())
