# SPDX-License-Identifier: Apache-2.0
"""Messages as YAML, the way `ros2 topic echo` prints them, with long arrays abbreviated."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import yaml

DEFAULT_TRUNCATE_LENGTH = 16


def to_plain(value: Any, truncate_length: int | None = DEFAULT_TRUNCATE_LENGTH) -> Any:
    """Return a message (rosbags dataclass) as nested dicts, lists and scalars.

    Sequences longer than `truncate_length` keep their first elements followed
    by a note of how many there are; None keeps everything.
    """
    if dataclasses.is_dataclass(value):
        return {
            f.name: to_plain(getattr(value, f.name), truncate_length)
            for f in dataclasses.fields(value)
            if not f.name.startswith('__')  # rosbags' __msgtype__ marker is not a message field
        }
    if isinstance(value, np.ndarray | list | tuple):
        items = value.tolist() if isinstance(value, np.ndarray) else list(value)
        if truncate_length is not None and len(items) > truncate_length:
            note = f'... {len(items) - truncate_length} more, {len(items)} in all'
            return [to_plain(v, truncate_length) for v in items[:truncate_length]] + [note]
        return [to_plain(v, truncate_length) for v in items]
    if isinstance(value, np.generic):
        return value.item()
    return value


def to_yaml(message: Any, truncate_length: int | None = DEFAULT_TRUNCATE_LENGTH) -> str:
    """Return a message as a YAML document (block style, fields in definition order)."""
    return yaml.safe_dump(
        to_plain(message, truncate_length),
        default_flow_style=False,
        sort_keys=False,
        allow_unicode=True,
        width=100,
    )
