"""The model a ``non-minimum-phase`` diagnostic offers (layer L4).

When the diagnostic says the data need right-half-plane zeros (issue 26 item 4), the fit
with ``zeros="free"`` is made as well, with the same keywords; with ``integrator="auto"``
at the poles at the origin of the diagnostic's best free-zeros start
(``values["free_zeros_integrator"]``), not those of the minimum-phase choice (which,
among starts that all miss the data, can land on any k). It goes into
``FitResult.alternatives["zeros=free"]``; the diagnostic and the message give both errors
and the switch. The result's own model stays minimum phase.
"""

import contextlib
import contextvars
import dataclasses
import warnings

from ..errors import FreqidError
from .verdict import FitStatus

__all__ = ["ORIGIN_AUTO", "origin_auto", "free_zeros_alternative"]

#: True while :func:`~freqid_casadi.fitting.fit.fit` runs with ``integrator="auto"``:
#: the alternative then takes the poles at the origin of the best free-zeros start.
ORIGIN_AUTO = contextvars.ContextVar("freqid_casadi_origin_auto", default=False)


@contextlib.contextmanager
def origin_auto(auto):
    """:data:`ORIGIN_AUTO` set within the block (a context manager).

    Parameters
    ----------
    auto : bool
        Whether the fit runs with ``integrator="auto"``.
    """
    token = ORIGIN_AUTO.set(bool(auto))
    try:
        yield
    finally:
        ORIGIN_AUTO.reset(token)


def free_zeros_alternative(result, refit, kw):
    """``result`` with the ``zeros="free"`` model in ``alternatives`` when its
    ``non-minimum-phase`` diagnostic (a warning) says the data need right-half-plane zeros.

    Parameters
    ----------
    result : FitResult
        A minimum-phase fit.
    refit : callable
        ``k -> FitResult``: the same fit with ``zeros="free"`` (run quietly here), ``k``
        the diagnostic's ``values["free_zeros_integrator"]`` (the caller decides whether
        it replaces the fit's own k).
    kw : dict
        The fit's keywords (``zeros``, ``min_damping``): an alternative is made only for
        a minimum-phase fit without a damping floor, by IPOPT with the gauge "dc".

    Returns
    -------
    FitResult
        ``result``, or a copy with the alternative, the diagnostic's message and values
        (``alternative_rms_rel_error``, ``alternative_max_rel_error``) and, when the
        alternative's RMS is below half the fit's, the message's advice.
    """
    found = [d for d in result.diagnostics
             if d.code == "non-minimum-phase" and d.severity == "warning"]
    loop = result.options.loop if result.options is not None else None
    if (not found or kw["zeros"] != "minimum-phase" or kw["min_damping"] is not None
            or result.method != "ipopt" or loop is None or loop.gauge != "dc"):
        return result
    try:
        with warnings.catch_warnings():       # a fit the user did not ask for: quiet
            warnings.simplefilter("ignore")
            alt = refit(found[0].values.get("free_zeros_integrator",
                                            result.model.origin_order))
    except FreqidError:
        return result
    old = found[0]
    text = (f"minimum phase: RMS {result.rms_rel_error:.3g} (max {result.max_rel_error:.3g}); "
            f"with free zeros: RMS {alt.rms_rel_error:.3g} (max {alt.max_rel_error:.3g}, "
            f"status {FitStatus(alt.status).value}) — pass zeros='free' "
            "(FitResult.alternatives['zeros=free'] holds that model)")
    diag = dataclasses.replace(old, message=f"{text}; {old.message}", values=dict(
        old.values, alternative_rms_rel_error=alt.rms_rel_error,
        alternative_max_rel_error=alt.max_rel_error))
    diags = tuple(diag if d is old else d for d in result.diagnostics)
    message = result.message
    if alt.rms_rel_error < 0.5 * result.rms_rel_error:
        message = (f"{message.split(' — ')[0]}; the data need right-half-plane zeros: "
                   f"zeros='free' reaches RMS {alt.rms_rel_error:.3g} — pass zeros='free' "
                   "(FitResult.alternatives['zeros=free'])")
    return dataclasses.replace(result, diagnostics=diags, message=message,
                               alternatives=dict(result.alternatives, **{"zeros=free": alt}))
