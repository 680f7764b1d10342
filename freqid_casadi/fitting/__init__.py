"""The fit (layer 5): the public pipeline, the main loop and its stages, starts,
candidates and their rescues, diagnostics, validation, sweep, batch and bootstrap."""

__all__ = []
