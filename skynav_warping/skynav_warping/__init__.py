"""Homing by 3D-warping: the home vector from the current view to a snapshot."""
