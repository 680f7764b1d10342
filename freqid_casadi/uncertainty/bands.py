"""Confidence bands of a fitted model's response and relative error (layer L4).

The delta method through the same Jacobian as :func:`freqid_casadi.uncertainty.covariance.
parameter_uncertainty`: with ``g = d ln G_N / d theta`` at a frequency and ``C`` the
covariance of the free physical parameters, ``var ln|G_N| = Re(g) C Re(g)^T`` and
``var arg G_N = Im(g) C Im(g)^T``. :func:`fit_band_weight` fits the multiplicative
uncertainty weight of :mod:`freqid_casadi.uncertainty.weight` to the upper edge of the
relative-error band instead of the fitted error curve.
"""

from dataclasses import dataclass

import numpy as np

from ..core import physical as _physical
from .covariance import ParameterUncertainty, z_quantile
from ..errors import DataError, OptionError

__all__ = ["ResponseBand", "response_band", "fit_band_weight"]

@dataclass(frozen=True)
class ResponseBand:
    """Delta-method band of the model's response and relative error.

    Attributes
    ----------
    omega : ndarray of float, shape (M,)
        rad/s.
    response : ndarray of complex, shape (M,)
        ``G_N(j omega)``.
    magnitude, magnitude_lower, magnitude_upper : ndarray of float, shape (M,)
        ``|G_N|`` and ``|G_N| exp(-+ z std(ln|G_N|))``.
    phase, phase_lower, phase_upper : ndarray of float, shape (M,)
        Unwrapped phase and ``phase -+ z std(phase)``, rad.
    rel_std : ndarray of float, shape (M,)
        ``sqrt(E|dG_N/G_N|^2)``: relative standard deviation of the model's response.
    rel_error, rel_error_std, rel_error_upper : ndarray of float, shape (M,) or None
        With data: ``e = |Phi/G_N - 1|``, ``|Phi/G_N| rel_std`` (an upper bound of the
        delta-method std of ``e``, finite where ``e = 0``) and ``e + z rel_error_std``.
    level : float
        Confidence level of the bounds; ``z`` its normal quantile.
    """

    omega: np.ndarray
    response: np.ndarray
    magnitude: np.ndarray
    magnitude_lower: np.ndarray
    magnitude_upper: np.ndarray
    phase: np.ndarray
    phase_lower: np.ndarray
    phase_upper: np.ndarray
    rel_std: np.ndarray
    level: float
    rel_error: np.ndarray = None
    rel_error_std: np.ndarray = None
    rel_error_upper: np.ndarray = None


def _check(unc):
    if not isinstance(unc, ParameterUncertainty):
        raise OptionError(f"expected a ParameterUncertainty (from parameter_uncertainty or "
                          f"bootstrap), got {type(unc).__name__}")


def response_band(unc, omega=None, data=None, *, level=0.95):
    """Confidence band of ``G_N(j omega)`` and of the relative error (delta method).

    Parameters
    ----------
    unc : ParameterUncertainty
        From :func:`parameter_uncertainty` or :func:`bootstrap`.
    omega : array_like of float, shape (M,), optional
        Frequencies in rad/s (default ``data.omega``).
    data : FrequencyData, optional
        With data (and ``omega`` None), the relative-error band is added.
    level : float
        Confidence level in (0, 1) (normal quantile).

    Returns
    -------
    ResponseBand

    Notes
    -----
    With ``g = d ln G_N / d theta`` (free parameters) and ``C`` the covariance (its
    part over the directions the data determine, ``response_factor``, when there is one:
    the response does not move along the others):
    ``var ln|G_N| = Re(g) C Re(g)^T``, ``var phase = Im(g) C Im(g)^T``, ``rel_std^2`` their
    sum.
    """
    _check(unc)
    par = _physical.parametrize(unc.model)
    z = z_quantile(level)
    if omega is None:
        if data is None:
            raise DataError("give omega or data: the frequencies of the band")
        omega = data.omega
    omega = np.asarray(omega, dtype=float)
    if omega.ndim != 1 or omega.size == 0 or not np.all(np.isfinite(omega) & (omega > 0)):
        raise DataError("omega must be a nonempty 1-D array of finite frequencies > 0 (rad/s)")
    free = ~unc.at_bound
    _, dlog = _physical.log_response(par, unc.values, omega)
    g = dlog[:, free]
    if unc.response_factor is not None:
        f = unc.response_factor[free]
        var_mag = np.sum((g.real @ f) ** 2, axis=1)
        var_ph = np.sum((g.imag @ f) ** 2, axis=1)
    else:
        cov = unc.covariance[np.ix_(free, free)]
        var_mag = np.einsum("ij,jk,ik->i", g.real, cov, g.real)
        var_ph = np.einsum("ij,jk,ik->i", g.imag, cov, g.imag)
    sd_mag, sd_ph = np.sqrt(np.maximum(var_mag, 0)), np.sqrt(np.maximum(var_ph, 0))
    resp = unc.model.frequency_response(omega)
    mag, ph = np.abs(resp), np.unwrap(np.angle(resp))
    rel_std = np.sqrt(sd_mag ** 2 + sd_ph ** 2)
    extra = {}
    if data is not None and data.n_points == omega.size and np.array_equal(data.omega, omega):
        ratio = data.response / resp
        e = np.abs(ratio - 1)
        e_std = np.abs(ratio) * rel_std
        extra = dict(rel_error=e, rel_error_std=e_std, rel_error_upper=e + z * e_std)
    return ResponseBand(omega=omega, response=resp, magnitude=mag,
                        magnitude_lower=mag * np.exp(-z * sd_mag),
                        magnitude_upper=mag * np.exp(z * sd_mag), phase=ph,
                        phase_lower=ph - z * sd_ph, phase_upper=ph + z * sd_ph,
                        rel_std=rel_std, level=float(level), **extra)


def fit_band_weight(unc, data, *, k=2.0, **options):
    """Uncertainty weight ``W`` covering the model's error band ``e + k std(e)``.

    Parameters
    ----------
    unc : ParameterUncertainty
    data : FrequencyData
        The data the model was fitted to (M points).
    k : float
        Number of standard deviations (>= 0) added to the relative error.
    **options
        Passed to :func:`freqid_casadi.uncertainty.weight.fit_uncertainty_weight` (``order``,
        ``margin``, ``min_damping``, ``max_iter``, ``verbose``).

    Returns
    -------
    freqid_casadi.uncertainty.weight.WeightResult
        Its ``rel_error`` is the band ``e + k * rel_error_std`` (see :class:`ResponseBand`).
    """
    from .weight import fit_uncertainty_weight

    if not (isinstance(k, (int, float)) and np.isfinite(k) and k >= 0):
        raise OptionError(f"k must be a finite number >= 0, got {k!r}")
    band = response_band(unc, data=data)
    upper = band.rel_error + k * band.rel_error_std
    return fit_uncertainty_weight(data.omega, upper, **options)
