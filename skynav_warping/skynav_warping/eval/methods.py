# SPDX-License-Identifier: Apache-2.0
"""The homing methods as they are evaluated, in one registry (homing_eval runs them; `skynav eval homing` lists them).

Plain data that imports nothing heavy: the `skynav` command lists it while it builds its parser.
"""

from __future__ import annotations

#: Name -> what the method is, in the order tables list them.
METHODS = {
    '3d-warping': 'the compass estimate starts the 3D-warping search (as the nodes run)',
    '3d-warping-no-compass': '3D-warping from its own rotational pre-alignment',
    '2d-warping': 'planar baseline on panoramas unwrapped from the skyline masks',
    'min-warping': 'planar baseline on the same panoramas',
}
#: The methods on panoramas: they need the snapshot's skyline mask, so a frame of the recording as the snapshot.
PANORAMA_METHODS = ('2d-warping', 'min-warping')
