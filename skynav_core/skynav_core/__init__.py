# SPDX-License-Identifier: Apache-2.0
"""The foundation every skynav package builds on: nodes, messages, recordings, cameras, geometry and errors.

Nothing here knows a stage (skyline, SH, localize, compass, warping) or the `skynav` command: stages and
commands import from this package, never the other way round (docs/architecture.md).
"""
