"""Report folders (layer 8): summaries, formatting, where a command may write."""

__all__ = []
