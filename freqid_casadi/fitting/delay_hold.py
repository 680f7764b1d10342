"""A delay the data do not determine is held at the lower order's (layer L5).

With a delay and sections whose roots may lie above the band, the data determine only a
combination of the two: in the band a zero at ``z`` far above it acts like
``exp(s / z)`` (a negative delay ``1/z``), a pole like a delay ``1/p``. At an order where
one more section can place such roots, the fitted delay slides along a near-flat valley
of optima (measured on the actuator at 3 sections: optima with delays 6.96-15.6 ms within
4 % RMS of each other, the free fit's delay std 1.2e3 s from the covariance), so the
delay would wander with the order although the data have not changed.

:func:`hold_undetermined_delay` states and resolves that case. When a converged fit's
delay has a standard deviation above half its value (the ``delay-undetermined`` test of
:func:`~freqid_casadi.fitting.diagnostics.check_delay`), the same fit is repeated with
``n_sections - 1`` (recursively held in turn); if that fit converged with a determined
positive delay ``h``, the ``n_sections`` fit is repeated with the delay held at ``h``
(the data multiplied by ``exp(j w h)``, fitted without a delay) and kept when it
converged with max and RMS relative errors within
:data:`~freqid_casadi.fitting.candidates.NEAR` of the free fit's (the factor by which
:func:`~freqid_casadi.fitting.candidates.choose` calls fits equally good). The kept result carries
a ``delay-undetermined`` diagnostic that names the
free fit's delay, its std and both fits' errors; ``LoopOptions(hold_delay=False)`` keeps
the free fit.

A fit that did not converge is not at an optimum, and its covariance says nothing of a
valley of optima; but when its delay is near its bound 0 (within one standard deviation
of it, and a lag of at most ``ZERO_LAG`` rad at the band's top: a delay creeping along
the valley at its bound), the same fit without a delay is tried, and
kept, its delay held at 0, when it converged within ``NEAR`` of the free fit's errors.

What it does not do: the held value is the lower order's, so it includes whatever lag
that order's delay absorbed when the data at ``n_sections`` cannot tell it apart (a
resonance above the band: measured 12.6 ms held where the system's dead time is 5 ms and
the free fit gives 11.7 ms, both equally good). The delay the data do determine is the
delay plus the high-frequency lag of the roots above the band.
"""

import dataclasses
import time
import warnings

import numpy as np

from ._checks import after_fit, verdict
from .candidates import NEAR
from ..core.data import FrequencyData
from .diagnostics import Diagnostic
from .stages import Kept, StageKind
from ..errors import ResolutionWarning
from ..core.metrics import relative_error
from ..core.model import RationalDelayModel

__all__ = ["hold_undetermined_delay", "undetermined_by_std", "HELD_FROM", "ZERO_LAG"]

#: Key of the ``delay-undetermined`` diagnostic's values naming the order whose delay was
#: held (its presence marks a held delay; 0: held at 0, the free fit did not converge).
HELD_FROM = "held_from_n_sections"
#: Largest lag ``omega_max * delay`` (rad) at the band's top of an unconverged fit's
#: undetermined delay that is held at 0 (:func:`hold_undetermined_delay`): a delay near its
#: bound. (Example C's unconverged fits, a lag of 26 rad, are not refitted: 8 s for
#: nothing.)
ZERO_LAG = 0.1


def undetermined_by_std(result):
    """The ``delay-undetermined`` diagnostic of ``result`` raised by the delay's standard
    deviation (not by its bound or a poor fit), or None.

    Parameters
    ----------
    result : FitResult

    Returns
    -------
    Diagnostic or None
    """
    for diag in result.diagnostics:
        if diag.code == "delay-undetermined" and "delay_std" in diag.values:
            return diag
    return None


def _determined(result):
    """True when ``result`` converged with a positive delay the data determine (or one
    held at a lower order's determined delay); a delay of 0 (the "at h=0" candidate won)
    is not a delay the data determined."""
    if not result.success or not result.model.structure.delay or not result.model.delay > 0:
        return False
    return all(d.code != "delay-undetermined" or HELD_FROM in d.values
               for d in result.diagnostics)


def hold_undetermined_delay(result, refit):
    """``result``, or the same fit with its undetermined delay held at the delay of the
    fit with one section fewer (see the module's docstring).

    Parameters
    ----------
    result : FitResult
        The free fit.
    refit : callable
        ``refit(data, n_sections, delay)`` runs the same fit (same options) on ``data``
        (FrequencyData, the user's units) with ``n_sections`` sections, with or without
        a delay, and returns its FitResult (itself passed through this function).

    Returns
    -------
    FitResult
        ``result`` unless the held fit is kept; then the held fit on ``result.data`` with
        the model's delay at the held value, ``candidate_max_rel_errors["free delay"]``
        the free fit's max error and a ``delay-undetermined`` diagnostic saying what
        was held.
    """
    t0 = time.perf_counter()
    found = undetermined_by_std(result)
    st = result.model.structure
    loop = result.options.loop if result.options is not None else None
    if found is None or loop is None or not loop.hold_delay:
        return result
    if not result.success:
        # a fit that did not converge is not at an optimum: its covariance says nothing
        # about a valley of optima (example C: 15 s of refits for nothing); only a delay
        # at its bound 0 is held, there
        return _held_at_zero(result, refit, found, t0)
    if st.n_sections < 2:
        return result
    with warnings.catch_warnings():         # a fit the user did not ask for: no warnings
        warnings.simplefilter("ignore", ResolutionWarning)
        lower = refit(result.data, st.n_sections - 1, True)
    if not _determined(lower):
        return result
    h, data = float(lower.model.delay), result.data
    shifted = FrequencyData(data.omega, data.response * np.exp(1j * data.omega * h),
                            data.name, data.weights, data.unit)
    return _kept(result, refit(shifted, st.n_sections, False), h, lower, found, t0)


def _held_at_zero(free, refit, found, t0):
    """``free`` (a fit that did not converge, whose delay ``found`` says is undetermined),
    or the same fit without a delay when its delay is near its bound 0 (within one
    standard deviation of it, and a lag of at most :data:`ZERO_LAG` at the band's top) and
    the fit without a delay converged within :data:`NEAR` of its errors (the delay then
    held at 0 in the kept model).

    Measured on a Bode 100 impedance export (401 points, 4 sections): the free fit ends at
    its iteration limit with a delay of 4.2e-8 s (std 7.7e-4 s) creeping along the valley
    the delay and a zero far above the band make; without a delay the same fit converges
    at the same errors (RMS 3.663e-4 against 3.662e-4)."""
    lag = free.model.delay * float(np.max(free.data.omega))
    if not (lag <= ZERO_LAG and free.model.delay <= float(found.values["delay_std"])):
        return free
    with warnings.catch_warnings():         # a fit the user did not ask for: no warnings
        warnings.simplefilter("ignore")
        held = refit(free.data, free.model.n_sections, False)
    return _kept(free, held, 0.0, None, found, t0)


def _kept(free, held, h, lower, found, t0):
    """The held fit (``held``: fitted without a delay on the data shifted by ``h``) as a
    FitResult with its delay at ``h`` (:func:`_held_result`), when it converged within
    :data:`NEAR` of the free fit's max and RMS errors; else ``free``."""
    if not (held.success and held.max_rel_error <= NEAR * free.max_rel_error
            and held.rms_rel_error <= NEAR * free.rms_rel_error):
        return free
    beta = np.array(held.model.beta, float)
    beta[0] = h
    model = RationalDelayModel(dataclasses.replace(held.model.structure, delay=True), beta)
    return _held_result(free, held, model, lower, found, time.perf_counter() - t0)


def _held_result(free, held, model, lower, found, extra_time):
    """The FitResult of the held fit on the free fit's data, with its diagnostics."""
    data, h = free.data, model.delay
    tu = data.time_unit
    stats = relative_error(model, data)
    values = {"delay": h, "delay_max": free.delay_max, "delay_free": free.model.delay,
              "delay_free_std": float(found.values["delay_std"]),
              HELD_FROM: lower.model.n_sections if lower is not None else 0,
              "max_rel_error_free": free.max_rel_error,
              "rms_rel_error_free": free.rms_rel_error}
    held_at = (f"the {lower.model.n_sections}-section fit's" if lower is not None else
               "as the free fit did not converge (its delay crept along that valley) and "
               "the fit without a delay did")
    message = (f"the free fit's delay {free.model.delay:.6g} {tu} has a standard deviation of "
               f"{values['delay_free_std']:.3g} {tu}: at {model.n_sections} sections the data "
               "do not determine it (it trades against roots above the band); the delay "
               f"is held at {h:.6g} {tu}, {held_at} (max rel. "
               f"error {stats.max:.4g}, RMS {stats.rms:.4g}; free {free.max_rel_error:.4g}, "
               f"{free.rms_rel_error:.4g}); LoopOptions(hold_delay=False) keeps the free fit")
    with np.errstate(all="ignore"):
        found_now = after_fit(model, data, stats, free.delay_max)
    before = tuple(d for d in held.diagnostics if d.code == "negative-gain")  # pre-fit
    diags = before + (Diagnostic("delay-undetermined", message, "warning", values),) + tuple(
        d for d in found_now if d.code != "delay-undetermined")
    stages = tuple(dataclasses.replace(r, delay=h) for r in held.stages)
    cands = dict(held.candidate_max_rel_errors, **{"free delay": free.max_rel_error})
    final = [r for r in stages if r.kept != Kept.MINIMAX_REJECTED
             and r.kind != StageKind.RATIONAL_START] or stages
    with np.errstate(all="ignore"):
        residual = data.response / model.frequency_response(data.omega) - 1.0
    success, status, message, details, diags = verdict(
        final[-1], stats, residual, data, diags, model.n_sections,
        free.options.start if free.options is not None else None)
    if status != "poor-fit":
        message += f"; the delay is held at {h:.6g} {tu} (see the delay-undetermined diagnostic)"
    return dataclasses.replace(
        held, model=model, data=data, rel_error=stats.values, max_rel_error=stats.max,
        rms_rel_error=stats.rms, stages=stages, options=free.options,
        candidate_max_rel_errors=cands, delay_max=free.delay_max, diagnostics=diags,
        success=success, status=status, message=message, details=details,
        wall_time=free.wall_time + extra_time)
