"""The compass's `skynav` commands (found through the skynav.commands entry points)."""
