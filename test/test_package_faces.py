# SPDX-License-Identifier: Apache-2.0
"""Lazy public names: importing a package loads no submodule, and every exported name resolves."""

import subprocess
import sys
from importlib import import_module

import pytest

PACKAGES = ('skynav_sh', 'skynav_localize', 'skynav_compass', 'skynav_warping')


@pytest.mark.parametrize('package', PACKAGES)
def test_every_exported_name_resolves(package):
    module = import_module(package)
    for name in module.__all__:
        assert getattr(module, name) is not None and name in dir(module)
    with pytest.raises(AttributeError, match='no attribute'):
        _ = module.not_a_public_name


def test_importing_the_packages_loads_no_submodule_and_no_scipy():
    code = (
        f'import sys; import {", ".join(PACKAGES)}; '
        f'loaded = [m for m in sys.modules if m.startswith({PACKAGES!r}) and m.count(".") == 1 '
        f'and not m.endswith(".lazy")]; print(loaded, "scipy" in sys.modules)'
    )
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == '[] False'
