"""Checks of user options shared by every entry point (root helper): one message shape,
"<name> must be ..., got <value>; pass ...", whichever function takes the option."""

import numbers

import numpy as np

from .errors import OptionError

__all__ = ["check_flag", "check_choice"]


def check_flag(name, value):
    """``bool(value)`` for True/False (numpy's too, and the integers 0 and 1); an
    OptionError naming ``name`` otherwise (a string such as "no" is not False)."""
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, numbers.Integral)
                                               and value in (0, 1)):
        return bool(value)
    raise OptionError(f"{name} must be True or False, got {value!r}; pass {name}=True or "
                      f"{name}=False")


def check_choice(name, value, choices, error=OptionError):
    """Raise ``error`` unless ``value`` is one of the strings ``choices`` (an array or a
    list is refused by its type, not compared element-wise)."""
    if not isinstance(value, str) or value not in choices:
        raise error(f"unknown {name} {value!r}; choose one of {', '.join(choices)}")
