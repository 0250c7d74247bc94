"""Synthetic UV/green fish-eye recordings with ground truth."""
