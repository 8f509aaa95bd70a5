"""The field route: self-calibration from the images of a marker field,
the one-step joint refinement, its bounds and quality checks, the held-out checks."""
