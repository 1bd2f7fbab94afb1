"""The pipeline's stages by name, in the order they run: one list that the pipeline, its
state file and the report share (the report must not import the pipeline)."""

STAGES = ("campaign", "sensitivity", "surrogate", "field", "estimate", "validate", "report")
