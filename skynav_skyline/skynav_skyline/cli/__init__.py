"""Learn and evaluate sky/ground segmentation on labelled recordings (with /ground_truth/mask)."""

HELP = 'learn and evaluate sky/ground segmentation'
