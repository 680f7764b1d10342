"""Studies built on the public API: reproductions of the thesis and comparisons (layer L6)."""

__all__ = []
