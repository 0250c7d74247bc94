# SPDX-License-Identifier: Apache-2.0
"""CDR that every reader takes: messages serialised by rclpy, re-serialised by rosbags where the two disagree.

rclpy serialises with Fast-CDR, which aligns the elements of a sequence of
8-byte numbers to 8 bytes even when the sequence is empty; rosbags (and the
CDR rule it follows) aligns only elements that exist. A message with such an
empty sequence then carries 4 bytes that rosbags refuses ("CDR message size
mismatch"), e.g. a PlaceMatch of an empty map: 76 bytes from rclpy, 72 from
rosbags. Recordings store what rosbags reads; rclpy reads either form.
"""

from __future__ import annotations

from functools import cache
from typing import Any, cast

import numpy as np
from rclpy.serialization import deserialize_message
from rosbags.typesys.base import Nodetype

from ..ros import message_class
from .typestore import ensure_type, typestore

# Primitive types CDR aligns to 8 bytes.
EIGHT_BYTE_TYPES = frozenset({'float64', 'int64', 'uint64'})
# numpy types of rosbags' arrays of primitives.
NUMPY_TYPES = {
    'bool': np.bool_,
    'byte': np.uint8,
    'octet': np.uint8,
    'char': np.uint8,
    'int8': np.int8,
    'uint8': np.uint8,
    'int16': np.int16,
    'uint16': np.uint16,
    'int32': np.int32,
    'uint32': np.uint32,
    'int64': np.int64,
    'uint64': np.uint64,
    'float32': np.float32,
    'float64': np.float64,
}


@cache
def has_eight_byte_sequence(msgtype: str) -> bool:
    """Return whether `msgtype` holds, anywhere, a sequence of 8-byte numbers (where rclpy and rosbags may differ)."""
    store = typestore()
    ensure_type(msgtype)
    for _, (kind, detail) in store.fielddefs[msgtype][1]:
        if kind == Nodetype.NAME and has_eight_byte_sequence(detail):
            return True
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (element, name), _ = cast('tuple[tuple[Nodetype, Any], int]', detail)  # an array's: ((kind, name), size)
            if kind == Nodetype.SEQUENCE and element == Nodetype.BASE and name[0] in EIGHT_BYTE_TYPES:
                return True
            if element == Nodetype.NAME and has_eight_byte_sequence(name):
                return True
    return False


def _value(value: Any, kind: int, detail: Any) -> Any:
    """Return one rclpy field value as rosbags holds it."""
    if kind == Nodetype.NAME:
        return to_rosbags(value, detail)
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        (element, name), _ = detail
        if element == Nodetype.BASE and name[0] in NUMPY_TYPES:
            if len(value) and isinstance(value[0], bytes):  # rclpy's byte[] and char[]: one bytes per element
                return np.frombuffer(b''.join(value), np.uint8)
            return np.asarray(value, dtype=NUMPY_TYPES[name[0]])
        return [_value(item, element, name) for item in value]
    if isinstance(value, bytes):  # a single byte or char
        return value[0]
    return value


def to_rosbags(message: Any, msgtype: str) -> object:
    """Return an rclpy message as the rosbags message of type `msgtype` with the same values."""
    fields = typestore().fielddefs[msgtype][1]
    return typestore().types[msgtype](*(_value(getattr(message, name), *spec) for name, spec in fields))


def rosbags_cdr(msgtype: str, data: bytes) -> bytes:
    """Return CDR of `msgtype` in a form rosbags reads: `data` itself, or re-serialised when rosbags refuses it."""
    if not has_eight_byte_sequence(msgtype):
        return data
    store = typestore()
    try:
        store.deserialize_cdr(data, msgtype)
        return data
    except Exception:  # rosbags raises several kinds for bytes it does not take
        pass
    try:
        message = deserialize_message(data, message_class(msgtype))
    except Exception:  # not a message rclpy reads either: kept as received, readers will say so
        return data
    return bytes(store.serialize_cdr(to_rosbags(message, msgtype), msgtype))
