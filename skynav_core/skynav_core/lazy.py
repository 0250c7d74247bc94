# SPDX-License-Identifier: Apache-2.0
"""Public names of a package loaded from its submodules on first use (PEP 562), so importing it stays light."""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from importlib import import_module
from typing import Any


def lazy_exports(
    package: str, exports: Mapping[str, tuple[str, ...]]
) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """Return the __getattr__, __dir__ and __all__ of `package` whose public names are {submodule: names}."""
    module_of = {name: module for module, names in exports.items() for name in names}
    public = sorted(module_of)

    def __getattr__(name: str) -> Any:
        """Import the submodule that defines a public name on first access."""
        module = module_of.get(name)
        if module is None:
            raise AttributeError(f'module {package!r} has no attribute {name!r}')
        value = getattr(import_module(f'{package}.{module}'), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        """List the public names next to the module's own."""
        return sorted(set(vars(sys.modules[package])) | set(public))

    return __getattr__, __dir__, public
