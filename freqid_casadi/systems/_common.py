"""Shared helpers of the benchmark systems: the thesis's grid and argument checks."""

import math

import numpy as np

from ..core.data import FrequencyData
from ..errors import OptionError

__all__ = ["thesis_grid"]


def thesis_grid(n_points=500, omega_min=1e-2, omega_max=1e3):
    """Logarithmically spaced frequency grid (the thesis's data grid by default).

    Parameters
    ----------
    n_points : int, optional
        Number of points M >= 2 (default 500).
    omega_min, omega_max : float, optional
        First and last frequency in rad/s, ``0 < omega_min < omega_max`` (default 1e-2, 1e3).

    Returns
    -------
    omega : ndarray of float, shape (n_points,)
        Strictly increasing frequencies in rad/s; the end points are exactly
        ``omega_min`` and ``omega_max``.

    Raises
    ------
    OptionError
        If ``n_points`` is not an integer >= 2 or the bounds are not finite with
        ``0 < omega_min < omega_max``.

    Notes
    -----
    SPEC §4: M = 500 log-spaced points, omega from 1e-2 to 1e3 rad/s.
    """
    if isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer)):
        raise OptionError(f"n_points must be an integer >= 2, got {n_points!r}")
    if n_points < 2:
        raise OptionError(f"n_points must be >= 2, got {n_points}; a grid needs two ends")
    lo = _real_scalar(omega_min, "omega_min")
    hi = _real_scalar(omega_max, "omega_max")
    if not 0 < lo < hi:
        raise OptionError(
            f"need 0 < omega_min < omega_max (rad/s), got omega_min={lo!r}, omega_max={hi!r}")
    omega = np.logspace(math.log10(lo), math.log10(hi), int(n_points))
    omega[0], omega[-1] = lo, hi
    return omega


def _real_scalar(value, name):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(x):
        raise OptionError(f"{name} must be finite, got {value!r}")
    return x


def _positive(value, name, allow_zero=False):
    x = _real_scalar(value, name)
    if x < 0 or (x == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise OptionError(f"{name} must be {bound}, got {value!r}")
    return x


def _omega(omega, default):
    """Validated frequency vector (DataError naming ``omega``), or the default grid."""
    if omega is None:
        return default()
    # FrequencyData does the validation (finite, > 0, strictly increasing, 1-D).
    return FrequencyData(omega, np.ones(np.size(omega), dtype=complex)).omega


def _data(omega, response, name):
    return FrequencyData(omega, response, name)
