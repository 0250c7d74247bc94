# SPDX-License-Identifier: Apache-2.0
"""Launch, parameters and the `skynav` command."""
