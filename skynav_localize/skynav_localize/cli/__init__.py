# SPDX-License-Identifier: Apache-2.0
"""Maps of taught routes: one SQLite file per map, with the snapshots the localize node compares against."""

HELP = 'build and inspect maps of taught routes'
