"""``fit(weights="noise")``: weights from the noise level the data show (layer L5).

The fit minimises the relative error with every point weighed alike, which is the
maximum-likelihood fit when the relative noise has one level over the band. An analyser's
noise is mostly additive: a floor of about constant absolute level, so that its relative
level grows as ``1 / |G|`` and varies over the band as much as the response does (a Bode
100 measurement of a filter, 45 dB of range: about 100-fold). Weighed alike, the noisy
points then decide the fit, and a model can stay far above the noise where the data are
quiet (that fit's status is ``poor-fit``, however many sections it has).

``weights="noise"`` fits twice: without weights, then with the inverse relative variances
the first fit's residual shows. The variance at each point is estimated as the status
check estimates the noise (:func:`~freqid_casadi.fitting.verdict.residual_noise`: the
running median of neighbouring differences, which a smooth systematic residual hardly
raises), after the residual is divided by ``|G|^(s/2)``, ``s`` being the power of ``|G|``
its level follows (:func:`noise_exponent`: a regression of the differences' log on
``log |G|`` and ``log omega``, clipped to ``[-2, 0]``; ``-2`` for additive noise, ``0``
for relative noise). The running median follows a level that varies slowly with the
frequency; the power follows the fast changes of ``|G|`` at resonances and
antiresonances, which the median's window cannot.

Measured on corpus systems at their true order, each fitted without weights, with
``weights="noise"`` and with the true inverse variances (``python scripts/noise_weights.py
--force``, results/noise-weights: seed 53, up to 300 points, 51 in-class noisy cases per
kind); the error against the true system in units of the true noise, geometric mean of
its ratio to the unweighted fit's:

- a noise floor (complex Gaussian of constant absolute level, 0.3-3 % of the median
  ``|G|``): 0.17 (true weights 0.18); "ok" 43 fits (without weights 36, true weights 43);
  fits "ok" yet more than 2 noise units from the truth 0 (without weights 5);
- a floor plus 0.1-1 % relative noise: 0.36 (true weights 0.35); "ok" 43 (38, 46);
- the corpus's own relative noise (flat or sloped up to 10-fold): 0.99, every fit "ok"
  with and without weights.

On another draw (seed 11, up to 600 points, floor plus relative noise, 55 cases): 0.36
(true weights 0.56), "ok" 42 (34, 41), and one fit "ok" far from the truth (without
weights 4): high-pass-25, 56 points, whose first fit's rough systematic residual the
estimate took for noise (57 noise units). Such a fit passes the status check against the
weights it made; its residual is not within :data:`LAW_RATIO` of the smooth level the
noise follows (:func:`law_ratio`: 5.26 there), and the weighted fit is then restated
"poor-fit".

Variants that were measured and not kept: the regression's law alone as the profile
(0.23 and 0.46 in the first two), and the running median held within a factor 4 of that
law (0.22 and 0.34, and on a Bode 100 measurement a smooth trend at the top of the band
passed for noise).
"""

import dataclasses
import math
import warnings

import numpy as np

from ..core.data import FrequencyData
from ..errors import FreqidError, OptionError
from .diagnostics import Diagnostic
from .verdict import NOISE_WINDOW, ROUNDING_RMS, FitStatus, local_variance

__all__ = ["noise_exponent", "noise_weights", "fit_with_noise_weights", "law_ratio",
           "MIN_POINTS", "WEIGHT_SPREAD", "LAW_RATIO"]

#: Fewest points for which the noise level is estimated (the running median's window).
MIN_POINTS = NOISE_WINDOW
#: Largest ratio of two weights (the inverse variances are floored at this fraction of
#: the largest variance, so that no point is left out for a near-zero difference).
WEIGHT_SPREAD = 1e8
#: Largest :func:`law_ratio` of a weighted fit whose status stays "ok". The weights come
#: from the residual's own local scatter, so a rough systematic error they take for noise
#: passes the status check; the smooth law that noise follows cannot take it. Measured on
#: 146 weighted fits "ok" within 2 noise units of the truth (corpus systems, seeds 53 and
#: 11, floor, mixed and relative noise) and two Bode 100 exports: at most 1.65 (median
#: 0.98); on the one "ok" fit 57 noise units from the truth (high-pass-25, seed 11): 5.26.
LAW_RATIO = 3.0


def noise_exponent(residual, size, omega):
    """The power ``s`` of ``|G|`` that the residual's local level follows: the
    coefficient of ``log |G|`` in a least-squares fit of ``log |e_{i+1} - e_i|^2`` on
    ``1, log omega, log |G|`` (midpoints), clipped to ``[-2, 0]``.

    Parameters
    ----------
    residual : ndarray of complex, shape (M,)
        Relative residual ``Phi / G - 1`` by increasing frequency.
    size : ndarray of float, shape (M,)
        ``|G|`` of the model at the same points.
    omega : ndarray of float, shape (M,)
        rad/s.

    Returns
    -------
    float
        -2 for noise of constant absolute level, 0 for constant relative level.
    """
    design, y, keep = _differences(residual, size, omega)
    if np.count_nonzero(keep) < 4 or np.ptp(design[keep, 2]) <= 0:
        return 0.0
    coef = np.linalg.lstsq(design[keep], y[keep], rcond=None)[0]
    return float(np.clip(coef[2], -2.0, 0.0)) if np.isfinite(coef[2]) else 0.0


def _differences(residual, size, omega):
    """``(design, y, keep)`` of the regression of ``y = log |e_{i+1} - e_i|^2`` on the
    columns ``1, log omega, log |G|`` of ``design`` (at the midpoints, shape (M-1, 3));
    ``keep``: the differences that are nonzero with a finite ``log |G|``."""
    d2 = np.abs(np.diff(residual)) ** 2
    x = 0.5 * np.log(size[1:] * size[:-1])
    t = np.log(0.5 * (omega[1:] + omega[:-1]))
    keep = (d2 > 0) & np.isfinite(x)
    with np.errstate(divide="ignore"):
        y = np.log(d2)
    return np.column_stack([np.ones(t.size), t, x]), y, keep


def law_ratio(residual, size, omega):
    """The RMS of a residual over the smooth noise level it shows: the level of each point
    from a least-squares fit of ``log |e_{i+1} - e_i|^2`` on ``1, log omega, log |G|``
    (:func:`noise_exponent`'s regression, unclipped: a power law in omega and ``|G|``),
    the mean of that log being the log of the mean minus Euler's constant; about 1 for
    noise that follows such a law.

    Parameters
    ----------
    residual, size, omega : ndarray, shape (M,)
        As :func:`noise_exponent`'s: the relative residual, ``|G|`` and rad/s.

    Returns
    -------
    ratio : float
        NaN when fewer than 4 differences are nonzero.
    worst : int
        Index of the point of the largest ``|e_i|^2`` over its level (-1 with NaN).
    """
    design, y, keep = _differences(residual, size, omega)
    if np.count_nonzero(keep) < 4:
        return math.nan, -1
    coef = np.linalg.lstsq(design[keep], y[keep], rcond=None)[0]
    half = 0.5 * np.exp(design @ coef + np.euler_gamma)    # a point's share of a difference
    level = np.empty(residual.size)
    level[0], level[-1] = half[0], half[-1]
    level[1:-1] = 0.5 * (half[:-1] + half[1:])
    z = np.abs(residual) ** 2 / level
    if not np.all(np.isfinite(z)):
        return math.nan, -1
    return float(np.sqrt(np.mean(z))), int(np.argmax(z))


def noise_weights(model, data):
    """Inverse relative noise variances of ``data`` estimated from ``model``'s residual.

    Parameters
    ----------
    model : RationalDelayModel
        A fit of ``data`` (without weights).
    data : FrequencyData

    Returns
    -------
    weights : ndarray of float, shape (M,)
        Mean 1.
    info : dict
        ``exponent`` (:func:`noise_exponent`) and ``spread``: the ratio of the largest to
        the smallest estimated noise level (RMS).
    """
    g = model.frequency_response(data.omega)
    size = np.abs(g)
    e = data.response / g - 1.0
    s = noise_exponent(e, size, data.omega)
    var = local_variance(e * size ** (-0.5 * s)) * size ** s
    var = np.maximum(var, np.max(var) / WEIGHT_SPREAD)
    if not np.all(np.isfinite(var)) or not np.max(var) > 0:
        return np.ones(data.omega.size), {"exponent": s, "spread": 1.0}
    w = 1.0 / var
    return w / np.mean(w), {"exponent": s, "spread": float(np.sqrt(np.max(var) / np.min(var)))}


def fit_with_noise_weights(fit_one, data_or_omega, response, spelt="noise"):
    """``fit(..., weights="noise")`` (module docstring): ``fit_one(data, response,
    weights) -> FitResult`` is the fit with the call's other options.

    Parameters
    ----------
    fit_one : callable
    data_or_omega, response
        As :func:`~freqid_casadi.fitting.fit.fit`.
    spelt : str
        The ``weights=`` given (anything but "noise" is refused).

    Returns
    -------
    FitResult
        The weighted fit (its ``data`` carry the weights) with a ``noise-weights``
        diagnostic and ``details["noise_weights"]``: ``exponent``, ``spread`` and the
        unweighted fit's ``rms``, ``status`` and noise ``ratio``; the unweighted fit itself
        when the data are too few (:data:`MIN_POINTS`) or it is exact to rounding.

    Raises
    ------
    OptionError
        ``spelt`` is not "noise", or the data carry weights of their own.
    """
    if spelt != "noise":
        raise OptionError(f"weights must be an array of one weight per frequency or 'noise' "
                          f"(estimated from the data), got {spelt!r}")
    if isinstance(data_or_omega, FrequencyData) and data_or_omega.weights is not None:
        raise OptionError("weights='noise' estimates the weights from the data, which carry "
                          "their own (FrequencyData.weights): drop weights='noise' to use "
                          "them, or pass the data without weights")
    with warnings.catch_warnings(record=True) as caught:   # issued only if it is kept
        warnings.simplefilter("always")
        first = fit_one(data_or_omega, response, None)
    data = first.data
    first_numbers = {"rms": float(first.rms_rel_error), "status": str(first.status),
                     "ratio": float(first.details.get("noise", {}).get("ratio", math.nan))}
    if data.n_points < MIN_POINTS or first.rms_rel_error <= ROUNDING_RMS:
        why = (f"fewer than {MIN_POINTS} points" if data.n_points < MIN_POINTS
               else "the fit without weights is exact to rounding")
        diag = Diagnostic("noise-weights", f"weights='noise': not estimated ({why}); the fit "
                          "is the one without weights", "info",
                          dict(first_numbers, estimated=False))
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return _with(first, diag, first_numbers)
    weights, info = noise_weights(first.model, data)
    second = fit_one(data, None, weights)
    s = info["exponent"]
    kind = ("" if s > -0.5 else
            f", and as |G|^{0.5 * s:.2g} at the resonances"
            + (" (a noise floor of constant absolute level)" if s <= -1.5 else ""))
    noise = second.details.get("noise", {})
    msg = (f"weights='noise': the unweighted fit's residual shows a noise level that varies "
           f"{info['spread']:.3g}-fold over the band{kind}; "
           f"weighed by its inverse variance, the fit reaches RMS "
           f"{second.rms_rel_error:.3g}, {noise.get('ratio', math.nan):.3g} times its noise "
           f"(without weights: RMS {first.rms_rel_error:.3g}, {first_numbers['ratio']:.3g} "
           f"times, {first.status})")
    g = second.model.frequency_response(data.omega)
    with np.errstate(all="ignore"):
        law, worst = law_ratio(data.response / g - 1.0, np.abs(g), data.omega)
    values = dict(info, estimated=True, unweighted=first_numbers, law_ratio=law)
    result = _with(second, Diagnostic("noise-weights", msg, "info", values), values)
    if second.status == FitStatus.OK and law > LAW_RATIO:
        return _not_the_noise(result, law, float(data.omega[worst]), data.unit)
    return result


def _not_the_noise(result, law, where, unit):
    """``result`` (a weighted fit "ok" by its own weights) restated as ``poor-fit``: its
    residual is :func:`law_ratio` = ``law`` times the smooth noise level, largest near
    ``where``."""
    ratio = float(result.details.get("noise", {}).get("ratio", math.nan))
    text = (f"the residual (RMS {result.rms_rel_error:.3g}) is {ratio:.3g} times the noise "
            f"level the weights estimate from it, but {law:.3g} times the smooth level "
            f"(a power law in omega and |G|) that noise follows over the band, most near "
            f"omega = {where:.4g} {unit}: the weights took a systematic error for noise, and "
            "the model does not explain the data there; try another number of sections, or "
            "compare the fit without weights='noise'")
    diag = Diagnostic("poor-fit", text, "warning",
                      {"rms": float(result.rms_rel_error), "ratio": law,
                       "noise_rms": float(result.rms_rel_error) / law, "local_ratio": ratio,
                       "worst_omega": where, "cause": "noise-weights"})
    return dataclasses.replace(result, status=FitStatus.POOR_FIT,
                               message=f"poor-fit: converged, but {text}",
                               diagnostics=tuple(result.diagnostics) + (diag,))


def _with(result, diag, values):
    try:
        return dataclasses.replace(result, diagnostics=tuple(result.diagnostics) + (diag,),
                                   details=dict(result.details, noise_weights=values))
    except (TypeError, FreqidError):        # a result type without diagnostics
        return result
