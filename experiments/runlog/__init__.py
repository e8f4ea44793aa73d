"""tracking stage of the pipeline."""

__all__ = []
