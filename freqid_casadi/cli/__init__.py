"""The ``freqid`` command line (layer 10): :mod:`.app` parses the arguments and dispatches,
one module per command family (:mod:`.frf`, :mod:`.batch`, :mod:`.modal`, :mod:`.ablation`)."""

from .app import main

__all__ = ["main"]
