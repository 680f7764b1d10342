"""Internal scaling of frequency and response (layer L1).

The fitting problem is scale free: the relative error ``|Phi/G_N - 1|`` does not change when
the frequencies are multiplied by ``w`` and the response by ``g``, if the model's frequencies
are multiplied by ``w``, its delay divided by ``w`` and its gain multiplied by ``g`` (and by
``w`` with an integrator). :func:`freqid_casadi.fitting.fit.fit` therefore fits
``omega / w_ref`` and ``response / g_ref`` with ``w_ref`` and ``g_ref`` powers of two near
the data's geometric-mean frequency and median magnitude, and maps the model back with
:func:`unscale_model`: multiplying by a power of two is exact in floating point, so data that
is already O(1) gives the same numbers as without scaling, and data at 1e150 rad/s or with
responses near 1e-310 is fitted as if it were O(1).
"""

import math

import numpy as np

from .data import FrequencyData
from ..errors import DataError, SolverError
from .model import RationalDelayModel

__all__ = ["reference_scales", "scale_data", "unscale_model", "check_finite_result",
           "weight_scale", "normalised_weights", "weighted_span"]


def _pow2(x):
    """The power of two nearest to ``x > 0`` in log scale (never 0 or inf)."""
    k = int(round(math.log2(x)))
    return math.ldexp(1.0, max(min(k, 1000), -1000))


def reference_scales(data):
    """``(w_ref, g_ref)``: powers of two near the geometric mean of ``omega`` (rad/s) and the
    median of ``|response|``.

    Parameters
    ----------
    data : FrequencyData

    Returns
    -------
    (float, float)
    """
    log_w = float(np.mean(np.log2(data.omega)))
    mags = np.abs(data.response)
    # |x| of a complex near 1e300 may overflow: the larger of |re|, |im| has the same scale
    mags = np.where(np.isfinite(mags), mags,
                    np.maximum(np.abs(data.response.real), np.abs(data.response.imag)))
    log_g = float(np.median(np.log2(mags)))
    return _pow2(2.0 ** max(min(log_w, 1000.0), -1000.0)), \
        _pow2(2.0 ** max(min(log_g, 1000.0), -1000.0))


def weight_scale(weights):
    """The power of two nearest to the mean of ``weights`` (1.0 for None).

    The weighted least-squares problem does not change when all weights are multiplied by
    one number, but the solvers' absolute tolerances do: weights of 1e4 (a 1 % noise's
    1/sigma^2) left a perfect fit "not converged", weights of 1e-200 stopped it at the
    start. Dividing by this scale makes the mean weight about 1 (unit weights unchanged).

    Parameters
    ----------
    weights : ndarray of float, shape (M,), or None
        Finite, >= 0, not all zero.

    Returns
    -------
    float
    """
    if weights is None:
        return 1.0
    top = float(np.max(weights))
    return _pow2(top * float(np.mean(weights / top)))     # no overflow of the sum


def normalised_weights(weights):
    """``weights`` divided by :func:`weight_scale` (a power of two: exact, mean about 1), or
    None when they are uniform.

    Only the ratios of the weights matter to a fit; this is the form the solvers see. A
    uniform weight of any size (1e-320, 3.0, 1e300) becomes None, so it fits exactly like
    no weights: dividing by :func:`weight_scale` alone left 1e-320 at 1e-19 (its power of
    two is clamped at 2^-1000) and 3.0 at 0.75, and the solvers' absolute tolerances saw
    those (A: max rel. error 5.8e-8 instead of 2.3e-14 at 1e-320). Other weights keep the
    power-of-two division, so a weighted fit's arithmetic is what it was.

    Parameters
    ----------
    weights : ndarray of float, shape (...), or None
        Finite, >= 0, not all zero.

    Returns
    -------
    ndarray of float like ``weights`` (mean within a factor sqrt(2) of 1), or None
    """
    if weights is None:
        return None
    w = np.asarray(weights, dtype=float)
    if np.all(w == w.flat[0]):
        return None
    out = w / weight_scale(w)
    mean = float(np.mean(out))
    if not 0.5 <= mean <= 2.0:             # weight_scale was clamped (subnormal weights)
        out = np.ldexp(out, -math.frexp(mean)[1])
    return out


def weighted_span(data):
    """``data`` from its first point with a weight > 0 on (``data`` itself if that is the
    first point): points of weight 0 at the low end count in no cost, and the sequential
    loop's first windows (the lowest frequencies) need a point that counts.

    Parameters
    ----------
    data : FrequencyData

    Returns
    -------
    FrequencyData
    """
    if data.weights is None or data.weights[0] > 0:
        return data
    k = int(np.flatnonzero(data.weights > 0)[0])
    return FrequencyData(data.omega[k:], data.response[k:], data.name, data.weights[k:])


def scale_data(data, w_ref, g_ref):
    """``FrequencyData(omega / w_ref, response / g_ref)`` with the name kept and the
    weights normalised by :func:`normalised_weights` (mean about 1; None when uniform).

    Parameters
    ----------
    data : FrequencyData
    w_ref : float
        Reference frequency, rad/s.
    g_ref : float
        Reference magnitude of the response.

    Returns
    -------
    FrequencyData
    """
    weights = normalised_weights(data.weights)
    with np.errstate(under="ignore", over="ignore"):
        response = data.response / g_ref
    bad = (response == 0) | ~np.isfinite(response)
    if bad.any():                   # the message names the user's point, not the scaled one
        i = int(np.flatnonzero(bad)[0])
        raise DataError(
            f"response[{i}]={data.response[i]} at omega={float(data.omega[i])!r} is out of "
            f"float64's range beside the data's median magnitude {g_ref:.3g} (the fit works "
            "on the response divided by it); remove that point or re-measure it")
    return FrequencyData(data.omega / w_ref, response, data.name, weights)


def unscale_model(model, w_ref, g_ref):
    """The model of the original data from the model ``model`` fitted to
    :func:`scale_data` (exact for powers of two, barring overflow).

    Parameters
    ----------
    model : RationalDelayModel
        Fitted to ``scale_data(data, w_ref, g_ref)``.
    w_ref, g_ref : float
        The scales of :func:`scale_data`.

    Returns
    -------
    RationalDelayModel

    Raises
    ------
    SolverError
        If a mapped parameter (gain, delay, a frequency) is not finite in float64.
    """
    st = model.structure
    beta = np.array(model.beta, float)
    with np.errstate(over="ignore", under="ignore"):
        beta[0] = beta[0] / w_ref
        k = st.origin_order
        beta[1] = beta[1] * g_ref * (w_ref if k == 1 else float(w_ref) ** k if k else 1.0)
        secs = beta[2:].reshape(st.n_sections, st.section_size)
        if st.basis == "second-order":
            secs[:, 2] *= w_ref
            secs[:, 5] *= w_ref
        else:
            secs[:, 0] /= w_ref
            secs[:, 2] /= w_ref
    check_finite_result(st, beta)
    return RationalDelayModel(st, beta)


def check_finite_result(structure, beta, rel_error=None):
    """Raise :class:`SolverError` unless the parameters and the error are finite.

    Parameters
    ----------
    structure : Structure
    beta : ndarray of float, shape (structure.n_params,)
    rel_error : ndarray of float, optional
    """
    beta = np.asarray(beta, float)
    if not np.all(np.isfinite(beta)):
        i = int(np.flatnonzero(~np.isfinite(beta))[0])
        raise SolverError(
            f"the fitted model is not representable in float64: "
            f"{structure.param_names()[i]} = {beta[i]} (the data's frequencies or magnitudes "
            "are too extreme for the model in physical units); rescale omega or the response "
            "(e.g. fit omega in krad/s) and fit again")
    if rel_error is not None and not np.all(np.isfinite(rel_error)):
        i = int(np.flatnonzero(~np.isfinite(rel_error))[0])
        raise SolverError(
            f"the relative error of the fit is not finite at point {i} ({rel_error[i]}): the "
            "fit failed numerically; check the data (extreme dynamic range) or fit fewer "
            "sections")
