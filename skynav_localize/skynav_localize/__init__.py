"""Rotation-invariant place recognition on a taught route, with SQLite maps."""
