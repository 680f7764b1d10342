"""Checks of user options shared by every entry point (root helper), one rule and one
message shape whichever function takes the option: a flag is True or False (numpy's booleans
and the integers 0 and 1 count, a string such as "no" does not) and reads "<name> must be
True or False, got <value>; pass <name>=True or <name>=False"; a choice is one of its
strings and reads "unknown <name> <value>; choose one of a, b, c". The error class is the
caller's (OptionError for options, StructureError for a model's structure)."""

import numbers

import numpy as np

from .errors import OptionError

__all__ = ["check_flag", "check_choice", "check_jobs"]


def check_flag(name, value, error=OptionError):
    """``bool(value)`` for True/False (numpy's too, and the integers 0 and 1); ``error``
    naming ``name`` otherwise (a string such as "no" is not False)."""
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, numbers.Integral)
                                               and value in (0, 1)):
        return bool(value)
    raise error(f"{name} must be True or False, got {value!r}; pass {name}=True or "
                f"{name}=False")


def check_choice(name, value, choices, error=OptionError, owner=None):
    """Raise ``error`` unless ``value`` is one of the strings ``choices`` (an array or a
    list is refused by its type, not compared element-wise); ``owner`` (an option class's
    name) says where the field lives."""
    if not isinstance(value, str) or value not in choices:
        where = f" ({owner}.{name})" if owner else ""
        raise error(f"unknown {name} {value!r}{where}; choose one of {', '.join(choices)}")


def check_jobs(n_jobs, every_core=False, error=OptionError):
    """``n_jobs`` (worker processes) as an int: a positive integer, or with ``every_core``
    also -1 (returned as the number of cores); ``error`` otherwise (a bool or a float is
    refused)."""
    if isinstance(n_jobs, (bool, np.bool_)) or not isinstance(n_jobs, numbers.Integral) \
            or not (n_jobs >= 1 or every_core and n_jobs == -1):
        also = " or -1 (every core)" if every_core else ""
        raise error(f"n_jobs must be a positive integer (worker processes){also}, got "
                    f"{n_jobs!r}")
    if n_jobs == -1:
        import os

        return int(os.cpu_count() or 1)
    return int(n_jobs)
