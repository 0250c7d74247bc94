"""`python -m skynav_bringup.cli` is `skynav`."""

from . import entry

entry()
