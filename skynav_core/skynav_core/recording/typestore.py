# SPDX-License-Identifier: Apache-2.0
"""Message definitions for (de)serialising CDR without rclpy: rosbags' Jazzy store plus installed interfaces.

The store starts with every standard Jazzy type that rosbags knows. Any other
type (skynav_msgs, a user's own package) is loaded on first use from the
``.msg`` file its package installed (``share/<pkg>/msg/<Name>.msg`` under an
ament prefix) or from the definition a bag carries. The messages of an action
that travel on topics (``pkg/action/<Name>_FeedbackMessage`` on
``<action>/_action/feedback``, with its ``_Goal``, ``_Result`` and ``_Feedback``
parts) are made from the installed ``share/<pkg>/action/<Name>.action``.
"""

from __future__ import annotations

import os
import re
from functools import cache
from typing import TYPE_CHECKING

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

from ..errors import SkynavError
from ..process.environment import ament_prefixes

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


KINDS = ('msg', 'action')  # the interface kinds whose messages travel on topics
ACTION_PARTS = ('Goal', 'Result', 'Feedback')  # the sections of an .action file, in order
#: The message an action server publishes on <action>/_action/feedback (as rosidl generates it).
FEEDBACK_MESSAGE = 'unique_identifier_msgs/UUID goal_id\n{package}/action/{action}_Feedback feedback\n'


class UnknownMessageType(SkynavError, LookupError):
    """A message type whose definition is neither known nor installed."""


class BadMessageType(SkynavError, ValueError):
    """A message type name that is not package/msg/Name with plain identifiers (a damaged or crafted file)."""


# One part of a type name: an identifier that starts with a letter (no leading dot, slash or underscore).
TYPE_NAME_PART = re.compile(r'[A-Za-z][A-Za-z0-9_]*')


@cache
def typestore() -> Typestore:
    """Return the process-wide type store (ROS 2 Jazzy standard types, more added on demand)."""

    return get_typestore(Stores.ROS2_JAZZY)


def split_type(msgtype: str) -> tuple[str, str, str]:
    """Split 'pkg/msg/Name' ('pkg/Name', 'pkg/action/Name_Part') into (package, kind, name); BadMessageType if not.

    Each part must be an identifier without '__': names like '../msg/X', '.evil/msg/X' or
    'std_msgs/msg/__class__' never reach an import, a path or an attribute lookup.
    """
    parts = msgtype.split('/') if isinstance(msgtype, str) else []
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if (
        len(parts) != 3
        or parts[1] not in KINDS
        or not all(TYPE_NAME_PART.fullmatch(part) and '__' not in part for part in parts)
    ):
        shown = repr(msgtype)[:80]
        raise BadMessageType(f'not a message type name: {shown} (expected package/msg/Name, each part an identifier)')
    return parts[0], parts[1], parts[2]


def action_part(name: str) -> tuple[str, str]:
    """Split an action message's name 'Teach_FeedbackMessage' into ('Teach', 'FeedbackMessage'); ValueError if none."""
    action, _, part = name.rpartition('_')
    if not action or part not in (*ACTION_PARTS, 'FeedbackMessage'):
        raise ValueError(
            f'not a message of an action: {name!r} (expected Name_Goal, _Result, _Feedback, _FeedbackMessage)'
        )
    return action, part


def normalise_type(msgtype: str) -> str:
    """Return a message type name in its full form 'pkg/msg/Name'."""
    return '/'.join(split_type(msgtype))


def find_msg_file(msgtype: str) -> str | None:
    """Return the installed .msg text of `msgtype` (an action's part: from its .action file); None if not installed."""
    package, kind, name = split_type(msgtype)
    if kind == 'action':
        action, part = action_part(name)
        if part == 'FeedbackMessage':
            return FEEDBACK_MESSAGE.format(package=package, action=action)
        for prefix in ament_prefixes(os.environ):
            path = prefix / 'share' / package / 'action' / f'{action}.action'
            if path.is_file():
                return re.split(r'^---[ \t]*$', path.read_text(), flags=re.M)[ACTION_PARTS.index(part)]
        return None
    for prefix in ament_prefixes(os.environ):
        path = prefix / 'share' / package / kind / f'{name}.msg'
        if path.is_file():
            return path.read_text()
    return None


def ensure_type(msgtype: str, msgdef: str = '', store: Typestore | None = None) -> str:
    """Make `msgtype` and everything it references known to the store; return its full name.

    `msgdef` is an optional ros2msg definition (as bags carry them, dependencies
    included); without it the installed .msg files are read.
    """

    store = typestore() if store is None else store
    msgtype = normalise_type(msgtype)
    pending = [msgtype]
    while pending:
        name = pending.pop()
        if name in store.fielddefs:
            continue
        text = msgdef if (msgdef and name == msgtype) else find_msg_file(name)
        if text is None:
            raise UnknownMessageType(f'no definition of {name}: its package is not installed under any ament prefix')
        types = get_types_from_msg(text, name)
        store.register(types)
        for _, fields in types.values():
            for _, desc in fields:
                if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                    desc = desc[1][0]  # an array's or sequence's element: a base type or a name, never nested
                if desc[0] == Nodetype.NAME and desc[1] not in store.fielddefs:
                    pending.append(desc[1])
    return msgtype


def ros2msg_definition(msgtype: str) -> str:
    """Return the full ros2msg definition of `msgtype`: its fields, then each type it uses after a `MSG:` line.

    This is the text an MCAP recording's schema carries and Foxglove reads; UnknownMessageType if not installed.
    """
    msgtype = ensure_type(msgtype)
    if split_type(msgtype)[1] != 'msg':  # rosbags writes definitions of pkg/msg/ types only
        raise UnknownMessageType(f'no ros2msg definition of {msgtype} (a message of an action)')
    return typestore().generate_msgdef(msgtype, ros_version=2)[0]
