# SPDX-License-Identifier: Apache-2.0
"""The error codes of skynav's actions (docs/interfaces.md, "Driving: teach, follow, home") by name.

Each action's result carries `error_code` (uint8) and names its values as constants (Teach.Result.MAP_EXISTS, ...);
0 is NONE in every one. These helpers read the constants from the generated class, so a client prints the name the
.action file gives without a table of its own.
"""

from __future__ import annotations

from typing import Any

ERROR_NONE = 0  # error_code of a goal that succeeded (or was canceled) in every skynav action


def error_codes(result_type: type) -> dict[int, str]:
    """Return {code: name} of the uint8 constants of an action's Result class (e.g. {1: 'MAP_EXISTS', ...})."""
    metaclass = type(result_type)
    constants: dict[str, Any] = getattr(metaclass, f'_{metaclass.__name__}__constants', {})
    return {int(value): name for name, value in constants.items() if isinstance(value, int)}


def error_name(result: Any) -> str:
    """Return the constant's name for a result's error_code, or 'ERROR_<code>' for a code the type does not name."""
    code = int(result.error_code)
    return error_codes(type(result)).get(code, f'ERROR_{code}')
