"""Which delta-method intervals to trust: the "not determined" status of a parameter (L4).

The delta method (:mod:`freqid_casadi.uncertainty.covariance`) linearises the model at the
optimum. Its 95 % interval covers the truth 95 % of the time when the estimate is normal
and unbiased to first order; measured by Monte Carlo over a family of systems
(``scripts/coverage.py``, ``results/coverage/``) it is not in these cases, which
:func:`determined_status` names:

``fit status``
    A fit whose status is not "ok" ("poor-fit": the residual has structure well above the
    noise; "not-converged"): the residual is not noise, nothing is determined.
``at its bound``
    A damping at 0 or at the fit's floor, a delay at 0 or at its bound, a missing
    coefficient: the bound, not the data, fixes the value (``at_bound``, NaN std).
``no finite standard deviation``
    The Fisher matrix is singular along the parameter (rounding gave a negative or NaN
    variance).
``near its bound``
    A frequency, damping, root or delay within :data:`Z_BOUND` std of 0: the estimate's
    distribution is cut by the bound and far from normal (a damping known to 30 % of
    itself, a delay the data cannot tell from 0).
``nearly cancelling pair``
    A pole pair and a zero pair whose natural frequencies are within :data:`CANCEL_GAP`
    (relative) and :data:`Z_BOUND` std of each other: the data barely see the pair, and
    where it sits is far from normal (measured: a pair 0.2 % apart, 4 % noise, fitted
    20 % away from its true place, 17 of its std).
``factor outside the band``
    A numerator or denominator factor whose natural frequency (or real root) lies more
    than :data:`FAR` times above the highest (or below the lowest) data frequency. In the
    band the data see only its first terms ``1 + a_1 s + a_2 s^2`` (above) or its
    asymptote (below): its own frequency and damping are not determined, and the
    parameters that trade with it (the delay against ``a_1``: a zero pair far above the
    band adds a phase lead ``a_1 omega``, like a negative delay; the gain and the nearby
    modes against ``a_2``) are biased by its nonlinear, one-sided estimate — which the
    delta method does not see (measured: a 2-mode + 1 zero-pair + delay system fitted
    with 2 sections, whose spare zero pair goes to infinity, covered the truth of the
    delay in 71 % of the replicates). A parameter is "not determined" when more than
    :data:`SHARE_MAX` of its variance is shared with such a factor (its squared multiple
    correlation with the factor's free parameters).
``weakly determined factor``
    The same for a factor in the band whose natural frequency (root) has a relative
    standard deviation above :data:`REL_WEAK` (measured: two spare zero pairs at 1.3 and
    1.8 times the top of the band, known to 9-13 %, moved the delay 10 of its std).

The test uses only the fit (values, covariance, band): it flags the same parameters with
or without a truth to compare with.
"""

import numpy as np

from ..core import physical as _physical

__all__ = ["determined_status", "FAR", "SHARE_MAX", "REL_WEAK", "Z_BOUND", "CANCEL_GAP"]

#: A factor whose natural frequency is more than FAR times above the highest data
#: frequency (or below the lowest) is outside the band.
FAR = 2.0
#: Largest share of a parameter's variance shared with a factor outside the band.
SHARE_MAX = 0.5
#: A factor whose natural frequency (or root) has a relative standard deviation above
#: this is weakly determined (its response is far from linear over its interval).
REL_WEAK = 0.05
#: Largest relative gap between the natural frequencies of a pole pair and a zero pair
#: that may count as nearly cancelling.
CANCEL_GAP = 0.1
#: Standard deviations within which a bound at 0 counts as reached. Not the 95 %
#: quantile: for a parameter truly at 0 (no delay), 2.5 % of the estimates lie more than
#: 1.96 std above it and every one of their intervals misses 0 (measured: 0 of 8 such
#: delays covered); beyond 3 std that is 0.13 %.
Z_BOUND = 3.0


def _label(f):
    part = "numerator" if f.sign > 0 else "denominator"
    return f"the {part} of section {f.section}"


def _outside(par, values, std, omega_min, omega_max):
    """Factors outside the band or weakly determined: list of (slots, label, frequency,
    'above'/'below'/'weak', relative std of the frequency)."""
    out = []
    for f in par.factors:
        if f.kind == _physical.CONSTANT or not f.slots:
            continue
        w = abs(float(values[f.slots[0]]))
        rel = float(std[f.slots[0]]) / w if w > 0 else np.inf
        where = ("above" if w > FAR * omega_max else "below" if w < omega_min / FAR
                 else "weak" if not rel <= REL_WEAK else None)
        if where:
            out.append((f.slots, _label(f), w, where, rel))
    return out


def _outside_reasons(slots, label, w, where, rel, edges, unit):
    """(reason of the factor's own parameters, what it is for the ones that trade)."""
    if where == "weak":
        return (f"{label} ({w:.4g} {unit}) is known to {100 * rel:.3g} % only: its response "
                "is far from linear over its interval",
                f"{label} ({w:.4g} {unit}), known to {100 * rel:.3g} % only")
    edge = edges[1] if where == "above" else edges[0]
    ratio = w / edge if where == "above" else edge / w
    return (f"{label} lies {where} the band ({w:.4g} {unit}, {ratio:.3g} times {where} its "
            "edge): the data see only its asymptote",
            f"{label}, which lies {where} the band ({w:.4g} {unit})")


def _cancelling(par, values, cov, reasons, unit):
    """Mark the quadratic pole and zero factors the data cannot tell apart (their natural
    frequencies within :data:`CANCEL_GAP` and :data:`Z_BOUND` std of each other: a pair
    that nearly cancels, whose place the data barely see)."""
    quad = [f for f in par.factors if f.kind == _physical.QUADRATIC]
    for fn in (f for f in quad if f.sign > 0):
        for fd in (f for f in quad if f.sign < 0):
            i, j = fn.slots[0], fd.slots[0]
            var = cov[i, i] + cov[j, j] - 2 * cov[i, j]
            if not (np.isfinite(var) and var > 0):
                continue
            gap = abs(values[i] - values[j])
            if gap <= Z_BOUND * np.sqrt(var) and gap <= CANCEL_GAP * min(values[i], values[j]):
                why = (f"{_label(fn)} ({values[i]:.5g} {unit}) and {_label(fd)} "
                       f"({values[j]:.5g} {unit}) nearly cancel (their gap {gap:.3g} is "
                       f"within {Z_BOUND:g} std): the data barely see the pair")
                for k in fn.slots + fd.slots:
                    if not reasons[k]:
                        reasons[k] = why


def _share(cov, j, slots):
    """Share of Var(theta_j) explained by the parameters ``slots`` (squared multiple
    correlation, invariant to how the factor is parametrised); NaN when undefined."""
    s = [k for k in slots if k != j and np.isfinite(cov[k, k]) and cov[k, k] > 0]
    if not s or not (np.isfinite(cov[j, j]) and cov[j, j] > 0):
        return np.nan
    c = cov[np.ix_(s, s)]
    b = cov[s, j]
    try:
        val = float(b @ np.linalg.lstsq(c, b, rcond=1e-12)[0] / cov[j, j])
    except np.linalg.LinAlgError:
        return np.nan
    return min(max(val, 0.0), 1.0)


def determined_status(par, values, cov, std, omega, unit="rad/s", fit_status=None):
    """Whether each parameter's delta-method interval can be trusted, and why not.

    Parameters
    ----------
    par : freqid_casadi.core.physical.Parametrization
        The fit's parameters (names, factors, ``at_bound``).
    values, std : ndarray of float, shape (P,)
        Parameter values and standard deviations (NaN at a bound).
    cov : ndarray of float, shape (P, P)
        Their covariance (NaN rows and columns at a bound).
    omega : ndarray of float, shape (M,)
        The data frequencies, rad/s.
    unit : str
        Frequency unit named in the reasons.
    fit_status : str, optional
        The fit's ``FitResult.status``; other than None or "ok", every parameter is not
        determined (poor-fit: the residual is not noise, the intervals describe a model
        error; not-converged: the point is not an optimum, where the intervals hold).

    Returns
    -------
    determined : ndarray of bool, shape (P,)
    reasons : tuple of str, length P
        "" where determined, else a sentence saying why not (see the module notes).
    """
    p = len(par.names)
    reasons = [""] * p
    omega_min, omega_max = float(np.min(omega)), float(np.max(omega))
    if fit_status not in (None, "ok"):
        why = (f"the fit's status is {fit_status!r}: " + (
            "it stopped before an optimum (the final stage did not converge), where the "
            "intervals, which hold at an optimum, do not apply; continue it (a higher "
            "final_max_iter) to get them" if str(fit_status) == "not-converged" else
            "its residual is not the noise, so the intervals describe a model error, "
            "not the data's uncertainty"))
        determined = np.zeros(p, dtype=bool)
        determined.setflags(write=False)
        return determined, tuple([why] * p)
    for j, name in enumerate(par.names):
        if par.at_bound[j]:
            reasons[j] = "at its bound: the bound, not the data, fixes it"
        elif not np.isfinite(std[j]):
            reasons[j] = "no finite standard deviation (the Fisher matrix is singular)"
        elif name != "log_gain" and abs(values[j]) <= Z_BOUND * std[j]:
            reasons[j] = (f"it lies within {Z_BOUND:g} std of its bound 0 (value "
                          f"{values[j]:.4g}, std {std[j]:.3g}): the bound may hold it and "
                          "the estimate is far from normal")
    _cancelling(par, values, cov, reasons, unit)
    for slots, label, w, where, rel in _outside(par, values, std, omega_min, omega_max):
        own, what = _outside_reasons(slots, label, w, where, rel, (omega_min, omega_max),
                                     unit)
        for k in slots:
            if not reasons[k]:
                reasons[k] = own
        for j in range(p):
            if reasons[j] or j in slots:
                continue
            share = _share(cov, j, slots)
            if share > SHARE_MAX:
                reasons[j] = (f"trades with {what}: {100 * share:.0f} % of its variance is "
                              "shared with it, and that factor's estimate is one-sided or "
                              "curved (the delta method does not see the bias)")
    determined = np.array([not r for r in reasons])
    determined.setflags(write=False)
    return determined, tuple(reasons)
