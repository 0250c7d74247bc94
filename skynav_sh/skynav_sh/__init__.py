"""Real spherical harmonics of fish-eye views: transform, rotation, spectra, translation."""
