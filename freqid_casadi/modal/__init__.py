"""Many FRFs of one structure (layer 6): the shared-pole fit and the stabilization survey."""

__all__ = []
