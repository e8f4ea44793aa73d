"""simulate stage of the pipeline."""

__all__ = []
