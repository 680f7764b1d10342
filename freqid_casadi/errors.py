"""Exception hierarchy of freqid_casadi (layer L0).

Every error the package raises on bad input derives from :class:`FreqidError` and from a
builtin (``ValueError`` or ``RuntimeError``), after python-control's ``exception.py``, so a
caller may catch either. Messages name the argument, the offending value and the fix.
"""

__all__ = ["FreqidError", "DataError", "StructureError", "OptionError", "SolverError",
           "ResolutionWarning", "ExportWarning", "DataWarning"]


class FreqidError(Exception):
    """Base class of every error raised by freqid_casadi."""


class DataError(FreqidError, ValueError):
    """Frequency-response data (or a data file) is malformed.

    Raised for non-finite, unsorted, duplicated or non-positive frequencies, zero or
    non-finite responses, length mismatches, unreadable files and bad CSV headers.
    """


class StructureError(FreqidError, ValueError):
    """A model structure or parameter vector is invalid (e.g. ``n_sections < 1``)."""


class OptionError(FreqidError, ValueError):
    """An option has an invalid value (unknown method, negative tol, existing output...)."""


class SolverError(FreqidError, RuntimeError):
    """A solver could not be run at all (not raised for mere non-convergence)."""


class ResolutionWarning(UserWarning):
    """A fitted model has poles/zeros narrower than the data's frequency spacing (features
    between the samples that the data does not determine); see
    :func:`freqid_casadi.fitting.validation.check_resolution`."""


class ExportWarning(UserWarning):
    """A model exported to python-control (``to_control``) whose state-space evaluation
    differs from the model's own response by more than
    :data:`freqid_casadi.core.realize.EXPORT_TOLERANCE` (roots spanning too many decades),
    or whose Pade approximation misses the delay within the model's dynamics."""


class DataWarning(UserWarning):
    """A reader changed the data in a stated way (e.g. dropped rows at zero frequency);
    also ``freqid_casadi.io.loaders.DataWarning``."""
