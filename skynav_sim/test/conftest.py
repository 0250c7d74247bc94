# SPDX-License-Identifier: Apache-2.0
"""Small hand-made worlds for geometry tests."""

import numpy as np
import pytest

from skynav_sim.materials import Surface
from skynav_sim.terrain import Terrain
from skynav_sim.world import World


def flat_world(primitives, extent=40.0, cells=161, height=0.0):
    """Return a world of flat grass at `height` with the given primitives, each its own object."""
    terrain = Terrain(np.full((cells, cells), height), np.full((cells, cells), Surface.GRASS, np.uint8), extent)
    groups = [np.array([i]) for i in range(len(primitives))]
    return World('test', 0, terrain, list(primitives), [], groups, np.ones((81, 81), bool))


@pytest.fixture
def make_flat_world():
    return flat_world
