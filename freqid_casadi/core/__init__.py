"""The model and what it is measured against (layer 1): data, the model G_N with its
validators, metrics, scaling, gauges, the objective and its derivatives, resolution,
physical parameters and modes."""

__all__ = []
