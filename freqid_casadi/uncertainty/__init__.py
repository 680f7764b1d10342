"""What the data determine (layer 4): parameter covariance, confidence bands and the
multiplicative uncertainty weight W(s)."""

__all__ = []
