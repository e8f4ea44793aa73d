"""tracking stage of the pipeline."""
