# SPDX-License-Identifier: Apache-2.0
"""Write skynav_bringup/config/skynav.yaml from the installed nodes' parameter tables.

.venv/bin/python tools/write_parameters.py
"""

from skynav_bringup.parameters import SHIPPED, shipped_parameter_file

if __name__ == '__main__':
    SHIPPED.write_text(shipped_parameter_file())
    print(f'wrote {SHIPPED}')
