"""The relative error of a model against frequency-response data, written once (layer L1).

``|Phi(j w) / G(j w) - 1|`` (SPEC §1) is the package's measure of fit: the fit, the
reports, the sweeps, the resolution safeguard and the baselines all take it from
:func:`relative_error`, and its summary (max, RMS, where) from :class:`ErrorStats`.
Any object with ``frequency_response(omega)`` (a
:class:`~freqid_casadi.core.model.RationalDelayModel`, a baseline's state-space model) can be
measured.
"""

from dataclasses import dataclass

import numpy as np

from .data import FrequencyData
from ..errors import DataError

__all__ = ["ErrorStats", "error_stats", "relative_error", "DelayedResponse"]


@dataclass(frozen=True, eq=False)
class ErrorStats:
    """Relative errors at a set of frequencies and their summary.

    Attributes
    ----------
    values : ndarray of float, shape (M,)
        ``|Phi/G - 1|`` at each frequency.
    max : float
        ``max(values)``.
    rms : float
        ``sqrt(mean(values**2))``.
    argmax : int
        Index of the largest error.
    omega_at_max : float
        Frequency of the largest error, rad/s (nan when no frequencies were given).
    """

    values: np.ndarray
    max: float
    rms: float
    argmax: int
    omega_at_max: float


def error_stats(values, omega=None):
    """:class:`ErrorStats` of precomputed relative errors.

    Parameters
    ----------
    values : array_like of float, shape (M,), M >= 1
        ``|relative error|`` values.
    omega : array_like of float, shape (M,), optional
        Their frequencies (rad/s), for ``omega_at_max``.

    Returns
    -------
    ErrorStats
    """
    values = np.asarray(values, float)
    if values.size == 0:
        raise DataError("no relative-error values: give at least one frequency")
    k = int(np.argmax(values))
    where = float(np.asarray(omega, float)[k]) if omega is not None else float("nan")
    return ErrorStats(values=values, max=float(np.max(values)), rms=_rms(values), argmax=k,
                      omega_at_max=where)


def _rms(values):
    """``sqrt(mean(values**2))``, rescaled by the largest value when the squares overflow
    (values near 1e300) or underflow (near 1e-300)."""
    with np.errstate(over="ignore", under="ignore"):
        plain = float(np.sqrt(np.mean(values ** 2)))
        top = float(np.max(np.abs(values)))
        if (np.isfinite(plain) and plain > 0) or not 0.0 < top < np.inf:
            return plain
        return top * float(np.sqrt(np.mean((values / top) ** 2)))


def relative_error(model, data_or_omega, response=None):
    """Relative error ``|Phi/G - 1|`` of ``model`` against data, with its summary.

    Parameters
    ----------
    model : object with ``frequency_response(omega) -> complex ndarray``
        E.g. a RationalDelayModel or a baseline's model.
    data_or_omega : FrequencyData or array_like of float, shape (M,)
        The data, or the frequencies in rad/s (then ``response`` is required).
    response : array_like of complex, shape (M,), optional
        ``Phi(j omega)`` when ``data_or_omega`` is the frequency array.

    Returns
    -------
    ErrorStats

    Raises
    ------
    DataError
        ``response`` missing or given twice, or shapes that do not agree.
    """
    if isinstance(data_or_omega, FrequencyData):
        if response is not None:
            raise DataError("pass either a FrequencyData or (omega, response), not both")
        omega, response = data_or_omega.omega, data_or_omega.response
    else:
        if response is None:
            raise DataError("response is missing: call relative_error(model, omega, "
                            "response) or relative_error(model, FrequencyData(...))")
        omega = np.asarray(data_or_omega, float)
        response = np.asarray(response)
        if omega.shape != response.shape:
            raise DataError(f"omega and response must have equal shapes, got {omega.shape} "
                            f"and {response.shape}")
    values = np.abs(response / model.frequency_response(omega) - 1.0)
    return error_stats(values, omega)


class DelayedResponse:
    """Mixin of the models: ``G(j w) = exp(-j w h) R(j w)`` from the class's
    ``rational_response(omega)`` and ``delay`` (s), and its :func:`relative_error`."""

    def frequency_response(self, omega):
        """``G(j omega)`` including the delay: complex, shape of ``omega``.

        Parameters
        ----------
        omega : array_like of float (rad/s)
        """
        omega = np.asarray(omega, dtype=float)
        return np.exp(-1j * omega * self.delay) * self.rational_response(omega)

    def relative_error(self, data):
        """``|(Phi - G)/G|`` at the data points, shape (M,) (SPEC §1).

        Parameters
        ----------
        data : FrequencyData

        Returns
        -------
        ndarray of float, shape (M,)
        """
        return relative_error(self, data).values
