# SPDX-License-Identifier: Apache-2.0
"""The simulator's worlds and scenarios by name: light enough for the `skynav` command to build its parser with."""

from __future__ import annotations

#: Synthetic world styles.
STYLES = ('garden', 'park', 'mineral')
#: Real Stellarium landscapes (their horizons and ground under a synthetic sky), fetched on first use.
LANDSCAPES = ('garching', 'guereins', 'hurricane', 'geneva')
#: Every world name skynav_sim.world.generate takes.
WORLDS = STYLES + LANDSCAPES
#: The recordings `skynav sim bag` writes.
SCENARIOS = ('teach', 'repeat', 'homing', 'compass', 'skyline')
