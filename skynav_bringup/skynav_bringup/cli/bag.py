# SPDX-License-Identifier: Apache-2.0
"""Repair recordings: `skynav bag recover` saves the messages of a recording that was never finished."""

HELP = 'repair recordings'
