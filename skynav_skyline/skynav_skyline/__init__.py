"""Sky/ground segmentation of upward-looking UV/green fish-eye images: the skyline."""
