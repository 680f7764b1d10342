"""Checks of :func:`freqid_casadi.fitting.fit.fit` before and after the solves (layer L5, private):
the data and options at the entry point, the model class (gain sign, zeros), the damping
floor, the diagnostics of the fitted model and the success rule.
"""

import contextlib
import contextvars
import math
import numbers
import warnings

import numpy as np

from ..core.data import FrequencyData, external_frequency_data
from .diagnostics import (TRIVIAL_RMS, check_delay, check_minimum_phase,
                          check_roots_below_band,
                          check_trivial, rhp_zeros_note)
from ..errors import DataError, FreqidError, OptionError, StructureError
from ..io.loaders import DataWarning
from ..core.model import BASES, ZEROS, Structure
from ..core.resolution import resolution_damping
from .._validate import check_choice
from ..solvers.common import TERMINATION_MESSAGES, Status
from ..solvers.termination import noise_stall_text
from .verdict import FitStatus, ROUNDING_RMS, poor_fit_diagnostic, residual_noise, status_of

__all__ = ["GAIN_SIGNS", "USABLE", "not_usable_between_samples", "spare_far_pair",
           "FAR_FACTOR", "validate", "zeta_min_of",
           "check_model_class", "after_fit",
           "success_of", "verdict", "MAX_DECADES",
           "check_weighted_points", "without_phase_check"]

#: Values of ``fit(gain_sign=...)``.
GAIN_SIGNS = ("auto", "positive", "negative")
#: The widest band (decades of omega) :func:`validate` accepts.
MAX_DECADES = 60
#: False within :func:`without_phase_check`: :func:`after_fit` then skips
#: :func:`~.diagnostics.check_minimum_phase`.
PHASE_CHECK = contextvars.ContextVar("freqid_casadi_phase_check", default=True)


@contextlib.contextmanager
def without_phase_check():
    """Fits within the block skip the ``non-minimum-phase`` check, and with it the
    ``zeros="free"`` alternative the check offers (a context manager, private).

    For callers that keep only a fit's model, errors, success and status: a sweep's
    fitted orders, a bootstrap's refits, the fits on a subset that settle a fit's
    choices (:func:`~freqid_casadi.fitting.core_fits.settle_on_subset`). The check is a
    warning that changes none of them (its free-zeros starts search the delay at each k
    and gain sign: half the time of the sweep of example A, whose low orders are poor
    fits).
    """
    token = PHASE_CHECK.set(False)
    try:
        yield
    finally:
        PHASE_CHECK.reset(token)


def zeta_min_of(min_damping, omega, method, gauge, basis):
    if min_damping is None:
        return None
    if isinstance(min_damping, str):
        if min_damping != "auto":
            raise OptionError(f"unknown min_damping {min_damping!r}; use None, 'auto' or a "
                              "number in [0, 1)")
        value = resolution_damping(omega)
    elif (isinstance(min_damping, (bool, np.bool_))
          or not isinstance(min_damping, numbers.Real)
          or not (0.0 <= float(min_damping) < 1.0)):
        raise OptionError(f"min_damping must be None, 'auto' or a number in [0, 1), got "
                          f"{min_damping!r}")
    else:
        value = float(min_damping)
    if method != "ipopt":
        raise OptionError("min_damping needs method='ipopt' (the barrier-LM method has "
                          "bounds only)")
    if gauge != "dc" or basis != "second-order":
        raise OptionError("min_damping needs gauge='dc' and basis='second-order' (first-order "
                          "sections have real roots and are never narrow)")
    return value


def check_weighted_points(data, n_params, n_sections):
    """DataError when fewer points have a weight > 0 than the model has parameters (the
    fit would be underdetermined: any model through those points is optimal)."""
    if data.weights is None:
        return
    counted = int(np.count_nonzero(data.weights > 0))
    if counted < n_params:
        raise DataError(
            f"too few weighted data points for {n_sections} sections: {counted} points with "
            f"weight > 0 for {n_params} parameters; use fewer sections or give more points "
            "a weight > 0")


def _check_span(omega):
    """DataError when the band spans more decades than float64 arithmetic of the model
    carries (the section factors hold (omega/omega_r)^2 for every omega_r in the band)."""
    decades = math.log10(omega[-1]) - math.log10(omega[0])
    if decades > MAX_DECADES:
        raise DataError(
            f"omega spans {decades:.0f} decades ({omega[0]:.3g} to {omega[-1]:.3g} rad/s), "
            f"more than the {MAX_DECADES} the model's float64 arithmetic carries; fit a "
            "narrower band (e.g. split the data)")


def validate(data, response, n_sections, basis, tol, integrator, weights=None):
    if response is None and data is not None:      # python-control FRD, skrf Network
        data = external_frequency_data(data) or data
    if isinstance(data, FrequencyData):
        if response is not None:
            raise DataError("pass either a FrequencyData or (omega, response), not both")
    else:
        if data is None:
            raise DataError("the data are missing: call fit(FrequencyData(...), ...) or "
                            "fit(omega, response, ...)")
        if response is None:
            raise DataError("response is missing: call fit(omega, response, ...) or "
                            "fit(FrequencyData(...), ...)")
        data = FrequencyData(data, response)
    if isinstance(n_sections, bool) or not isinstance(n_sections, (int, np.integer)):
        raise StructureError(f"n_sections must be a positive integer, got {n_sections!r}")
    if n_sections < 1:
        raise StructureError(f"n_sections must be >= 1, got {n_sections}")
    check_choice("basis", basis, BASES)
    if tol is not None and not (isinstance(tol, numbers.Real)
                                and not isinstance(tol, (bool, np.bool_))
                                and math.isfinite(tol) and tol > 0):
        raise OptionError(f"tol must be a number > 0 (a max relative error), got {tol!r}")
    _check_span(data.omega)
    _check_phase(data.response)
    structure = Structure(int(n_sections), integrator, True, basis)
    n_params = structure.n_params
    if data.n_points < n_params:
        most = (data.n_points - 2) // structure.section_size
        advice = (f"use fewer sections (at most {most}) or more data" if most >= 1 else
                  f"even one section needs {Structure(1, integrator, True, basis).n_params}"
                  " points: measure more frequencies")
        raise DataError(
            f"too few data points for {n_sections} sections: {data.n_points} points for "
            f"{n_params} parameters; {advice}")
    if weights is not None:
        data = data.with_weights(weights)
    check_weighted_points(data, n_params, n_sections)
    return data


def _check_phase(response):
    """A DataWarning for a response real at every point, of one sign and not constant: a
    magnitude or a level in dB passed as the response (``fit(omega, np.abs(G))``) looks
    so; a causal system's response does only when it is lossless (undamped modes, whose
    real response changes sign at each resonance, or a band below the first)."""
    r = np.asarray(response)
    if np.any(r.imag != 0) or np.ptp(r.real) <= 1e-12 * np.max(np.abs(r.real)):
        return
    if np.all(r.real > 0) or np.all(r.real < 0):
        what = "a level in dB" if np.all(r.real < 0) else "a magnitude |G|"
        warnings.warn(f"the response is real at every point, of one sign and not constant: "
                      f"is it {what}? A frequency response needs its phase, to which the "
                      "delay and the zeros are fitted: pass the complex response (mag * "
                      "exp(1j * phase)), or load the file with its phase column "
                      "(columns='freq_hz,mag_db,phase_deg'); only a lossless system's "
                      "response is real", DataWarning, stacklevel=5)


def check_model_class(gain_sign, zeros, method, gauge, min_damping):
    if not isinstance(gain_sign, str) or gain_sign not in GAIN_SIGNS:
        raise OptionError(f"unknown gain_sign {gain_sign!r}; choose one of "
                          f"{', '.join(GAIN_SIGNS)}")
    if not isinstance(zeros, str) or zeros not in ZEROS:
        raise OptionError(f"unknown zeros {zeros!r}; choose one of {', '.join(ZEROS)}")
    if zeros == "free":
        if method != "ipopt":
            raise OptionError("zeros='free' needs method='ipopt' (the barrier-LM method "
                              "keeps every parameter inside its log barrier, beta > 0)")
        if gauge != "dc":
            raise OptionError(f"zeros='free' needs LoopOptions(gauge='dc'), got {gauge!r}")
        if min_damping is not None:
            raise OptionError("zeros='free' takes no min_damping (the damping floor is "
                              "written for minimum-phase factors); drop one of them")


def _delay_std(model, data, delay_max, noise=None):
    """The delay's standard deviation from the parameter covariance, or None (``noise``:
    the fit's :func:`~.verdict.residual_noise`, computed here when not given)."""
    if not model.structure.delay or model.delay <= 0 or model.delay >= 0.98 * delay_max:
        return None
    from ..uncertainty.covariance import parameter_uncertainty

    # the noise level as FitResult.uncertainty takes it (the local level when the residual
    # is noise, as an "ok" fit's is), so the diagnostic and the report's table agree
    if noise is None:
        with np.errstate(all="ignore"):
            residual = data.response / model.frequency_response(data.omega) - 1.0
        noise = residual_noise(residual, data.omega, data.weights)
    consistent = noise.consistent
    try:
        std = parameter_uncertainty(model, data, weights=data.weights,
                                    noise_level="local" if consistent else "constant"
                                    ).delay_std
    except (FreqidError, np.linalg.LinAlgError, ArithmeticError):
        return None
    return float(std) if math.isfinite(std) else None


def after_fit(model, data, stats, delay_max, noise=None):
    """Diagnostics of the fitted model on the user's data (see :mod:`.diagnostics`;
    ``noise``: the fit's residual check, when the caller has it)."""
    found = check_trivial(stats.max, stats.rms)
    found += check_delay(model, data, delay_max, stats.rms,
                         delay_std=_delay_std(model, data, delay_max, noise))
    if model.structure.zeros == "free":
        found += rhp_zeros_note(model)
    elif PHASE_CHECK.get():
        found += check_minimum_phase(model, data, stats.max, stats.rms)
    return found + check_roots_below_band(model, data)


def success_of(last, stats):
    """``(success, message)`` of a fit from its last stage record and its error (the
    optimiser's verdict only; :func:`verdict` is the fit's)."""
    if not stats.rms < 1.0:
        return False, (f"the RMS relative error {stats.rms:.3g} >= 1: no better than an "
                       "infinite-gain model (a stationary point at infinity); try "
                       "start='rational', another structure or fewer sections")
    if last.success:
        return True, last.message or "converged"
    if at_noise(last):
        return True, noise_stall_text(last.details["noise_stall"])
    return False, _not_converged(last, stats)


def at_noise(last):
    """True when the final stage ``last`` (a StageRecord) failed the strict stationarity
    test but is converged to the data's noise
    (:class:`~freqid_casadi.solvers.termination.NoiseStall`; ``IpoptOptions.noise_stall``):
    the fit's verdict counts it converged."""
    return not last.success and "noise_stall" in (last.details or {})


def _next_step(last, stats, start=None, found=()):
    """What to pass to let an unconverged final stage continue (``start``: the fit's
    start option, None if unknown; ``found``: the fit's diagnostics)."""
    limit = last.details.get("max_iter")
    lm = last.details.get("method") == "barrier-lm"
    fell = last.details.get("termination", {}).get("rms_fall_per_iteration")
    if stats.rms <= ROUNDING_RMS:
        # example C at 27 sections: 1.1e-10; 2000 iterations gave 1.9e-10 and asked for
        # 20000: the data are matched, the iterations move sections they do not need
        return ("the model reproduces the data to rounding: more iterations only move "
                "sections the data do not need (fewer sections shed them)")
    if not stats.rms < TRIVIAL_RMS and (fell is None or fell < SLOW_FALL
                                        or last.status != Status.MAX_ITER):
        # (an impact test's accelerance at 6 sections: RMS 0.994 "still falling 0.00048 %
        # per iteration" had been sent to ten times the iterations; a stage stopped early
        # by its limit while the error still falls fast is sent on, below)
        return (TRIVIAL_ADVICE + ": see the diagnostics (gain sign, model class, delay, "
                "zeros='free' for right-half-plane zeros, another number of sections) "
                "before iterating further")
    if last.status == Status.MAX_ITER and limit and not (fell is not None and fell <= 0):
        kind = "BarrierLMOptions" if lm else "IpoptOptions"
        return f"pass method={kind}(final_max_iter={10 * int(limit)}) to continue"
    if last.status == Status.MAX_ITER and lm:
        return ("pass method=BarrierLMOptions(max_inner=5000) to let its inner solves run "
                "further, or method='ipopt'")
    if any(d.code == "delay-undetermined" and "delay_std" in d.values for d in found):
        return ("the data do not determine the delay (see the delay-undetermined "
                "diagnostic): fit fewer sections, or without a delay (delay=False)")
    if start == "best":
        return "both starts were run: try another number of sections"
    return ("try start='best' (both starts, the better kept) or another number of "
            "sections")


#: Fall of the RMS per iteration (relative) below which more iterations of a fit that
#: explains almost nothing are not advised.
SLOW_FALL = 1e-3

#: The advice of an unconverged fit that explains almost nothing (RMS near 1): more
#: iterations or a damping floor do not change that.
TRIVIAL_ADVICE = "the model explains almost nothing"


#: Factor above the highest data frequency beyond which a pole and a zero that an
#: unconverged fit pushes outwards together read as a spare pair (:func:`spare_far_pair`).
FAR_FACTOR = 100.0


def spare_far_pair(message, model, data):
    """``message`` of an unconverged fit with advice added when poles and zeros lie
    beyond :data:`FAR_FACTOR` times the highest frequency: a pair cancelling on its way to
    infinity, each iteration lowering the error a little (-3 e^{-0.1 s} / (s + 1) at one
    second-order section: 3.2e-11 "still falling 2 % per iteration", a pole at 8e4 and a
    zero pair at 1.5e5 rad/s against data up to 100 rad/s).

    Parameters
    ----------
    message : str
    model : RationalDelayModel
    data : FrequencyData
        The fitted data (its highest frequency and unit).

    Returns
    -------
    str
    """
    if not message.startswith("not-converged") or model.structure.basis != "second-order":
        return message
    unit = getattr(data, "unit", "rad/s")
    far = FAR_FACTOR * float(data.omega[-1])
    p = [abs(x) for x in model.poles() if abs(x) > far]
    z = [abs(x) for x in model.zeros() if abs(x) > far]
    if not p or not z:
        return message
    return (f"{message}; {len(p)} pole(s) and {len(z)} zero(s) lie beyond {FAR_FACTOR:g} "
            f"times the highest frequency (from {min(p):.3g} and {min(z):.3g} {unit}), "
            "drifting outwards together: the data have fewer poles than the model (a "
            "first-order system: pass basis='first-order'; else fewer sections)")


#: The words of an unconverged fit's message whose residual is at the noise.
USABLE = "usable: the residual is consistent with the noise"


def not_usable_between_samples(message, check, min_damping="given"):
    """``message`` of an unconverged fit at the noise (:data:`USABLE`) restated when its
    resolution check failed: consistent at the samples, not determined between them (a
    published dam test: an undamped pole at the band's first point, +45 dB between the
    samples).

    Parameters
    ----------
    message : str
        The fit's message.
    check : ResolutionCheck or None
        Its resolution check (:func:`~freqid_casadi.fitting.validation.check_resolution`).
    min_damping : None, str or float
        The fit's ``min_damping``: None (no floor given), an unconverged fit's advice
        starts with one (a transistor's S21: 554 s for ten times the iterations, 19 s to
        "ok" with ``min_damping='auto'``).

    Returns
    -------
    str
    """
    if check is None or check.ok:
        return message
    if message.startswith("ok:") and "exact to rounding" not in message:
        # a published resonator's S21 at 7 sections with min_damping="auto": "ok" beside a
        # pair of damping 1.7e-4 that drew a 3 dB spike between two samples
        return (f"{message}; but {len(check.flags) + len(check.unresolved)} pole(s)/zero(s) "
                "are narrower than the frequency spacing: the model between the samples is "
                "not determined there (FitResult.resolution lists them)")
    if message.startswith("not-converged") and min_damping is None and " — " in message \
            and "to rounding" not in message and TRIVIAL_ADVICE not in message:
        n = len(check.flags) + len(check.unresolved)
        head, _, advice = message.partition(" — ")
        message = (f"{head} — {n} pole(s)/zero(s) are narrower than the frequency spacing: "
                   "refit with min_damping='auto' (a damping floor from the spacing), or "
                   f"{advice}")
    if USABLE not in message:
        return message
    return message.replace(USABLE, (
        f"the residual is consistent with the noise, but "
        f"{len(check.flags) + len(check.unresolved)} pole(s)/zero(s) are narrower than the "
        "frequency spacing: the model between the samples is not determined"), 1)


def _not_converged(last, stats, usable=False, start=None, found=()):
    """The message of a fit whose final stage did not converge (``usable``: its residual
    is consistent with the noise all the same; ``start``, ``found``: the fit's start
    option and diagnostics, for the advice)."""
    d = last.details
    limit = d.get("max_iter")
    fell = d.get("termination", {}).get("rms_fall_per_iteration")
    if last.status == Status.MAX_ITER and limit:
        how = f"reached its iteration limit ({int(limit)})"
        if fell is not None and math.isfinite(fell):
            how += (f" while the error still fell {100 * fell:.2g} % per iteration" if fell > 0
                    else " with the error no longer falling")
    elif last.status == Status.MAX_ITER and d.get("method") == "barrier-lm":
        how = "reached the barrier-LM's limit of trial steps per inner solve (max_inner)"
    elif last.status == Status.STALLED:
        how = "stalled (the error stopped falling) at a point that is not stationary"
    else:
        how = f"stopped ({TERMINATION_MESSAGES[last.status]})"
    state = (USABLE if usable else
             "the model is feasible and these errors are measured")
    return (f"not-converged: the final stage {how}; max rel. error {stats.max:.2g}, "
            f"RMS {stats.rms:.2g} ({state}) — {_next_step(last, stats, start, found)}")


def verdict(last, stats, residual, data, found, n_sections, start=None, noise=None):
    """The fit's verdict: ``(success, status, message, details, diagnostics)``.

    ``success`` is the optimiser's (:func:`success_of`, False also on a diagnostic of
    severity "error"); ``status`` a :class:`~.verdict.FitStatus` from it and the
    residual's consistency with the noise (:func:`~.verdict.residual_noise`); a
    ``poor-fit`` diagnostic is added to ``found`` when a converged fit's residual is well
    above the noise.

    Parameters
    ----------
    last : StageRecord
        The final all-data stage.
    stats : ErrorStats
    residual : ndarray of complex, shape (M,)
        ``Phi / G_N - 1``.
    data : FrequencyData
        The user's data (weights and unit).
    found : tuple of Diagnostic
    n_sections : int
    start : str, optional
        The fit's ``start`` option (the advice of an unconverged fit does not offer a
        start it ran).
    noise : NoiseCheck, optional
        ``residual_noise`` of ``residual``, when the caller has it.

    Returns
    -------
    (bool, FitStatus, str, dict, tuple of Diagnostic)
    """
    success, message = success_of(last, stats)
    check = residual_noise(residual, data.omega, data.weights) if noise is None else noise
    errors = [d for d in found if d.severity == "error"]
    converged = bool(last.success) or at_noise(last)
    status = status_of(converged, bool(errors) or not stats.rms < 1.0, check)
    details = {"final_stage": dict(last.details, message=last.message, stage=last.stage,
                                   iterations=int(last.nit)),
               "noise": dict(check)}
    if status == FitStatus.POOR_FIT:
        if not check.consistent:
            diag = poor_fit_diagnostic(check, found, n_sections, data.unit)
            found = tuple(found) + (diag,)
            message = f"poor-fit: converged, but {diag.message}"
        if errors:
            success, message = False, f"poor-fit: {errors[0].code}: {errors[0].message}"
        elif not stats.rms < 1.0:
            message = f"poor-fit: {message}"
    elif status == FitStatus.NOT_CONVERGED and stats.rms < 1.0:
        message = _not_converged(last, stats, usable=check.consistent, start=start,
                                 found=found)
    elif status == FitStatus.NOT_CONVERGED:
        message = f"not-converged: {message}"
    elif status == FitStatus.OK:
        how = "converged to the noise" if at_noise(last) else "converged"
        message = (f"ok: {how}; max rel. error {stats.max:.3g}, RMS {stats.rms:.3g}, "
                   "consistent with the noise"
                   + (" (the fit is exact to rounding)" if check["rms"] <= ROUNDING_RMS
                      else f" ({check['noise_rms']:.3g} from the residual's scatter)"))
    return success, status, message, details, tuple(found)
