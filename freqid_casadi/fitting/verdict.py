"""The verdict of a fit: does the model explain the data? (layer L5)

``success`` says whether the optimiser converged; :class:`FitStatus` says more:

``"ok"``
    converged, and the residual is consistent with the noise of the data;
``"poor-fit"``
    converged (or stopped by a diagnostic of severity "error"), but the residual has
    structure well above the noise: the model class, the order, the gain sign or the
    delay is wrong, and a ``poor-fit`` :class:`~.diagnostics.Diagnostic` says which;
``"not-converged"``
    the final all-data stage did not reach its termination test (a stage whose residual
    is the noise and whose last iterations moved the model by far less than its standard
    errors counts as converged: :class:`~freqid_casadi.solvers.termination.NoiseStall`).

The noise is estimated from the residual itself (:func:`residual_noise`): the relative
residual ``e_i = Phi_i / G_N(j w_i) - 1`` of a model that explains the data is the data's
noise, white over frequency, so its point-to-point differences carry twice its variance
(``E|e_{i+1} - e_i|^2 = 2 sigma^2``); a systematic residual (a missed mode, a wrong sign or
delay) is smooth over neighbouring points and its differences are small against its size.
The local noise level is the running median of ``|e_{i+1} - e_i|^2 / (2 ln 2)`` over
:data:`NOISE_WINDOW` differences (the median of a complex Gaussian's ``|z|^2`` is
``ln 2`` times its mean; the median is not raised by a narrow systematic feature, and the
window follows noise whose level varies over the band). With weights (inverse relative
variances, e.g. ``FrfEstimate``'s), the residual is whitened by ``sqrt(w)`` first, so only
their shape matters. The fit is consistent with the noise when the mean of
``|e_i|^2 / sigma_i^2`` is at most :data:`CONSISTENT_RATIO` squared (RMS at most twice
the noise), or when its RMS is at rounding level (:data:`ROUNDING_RMS`: exact data).

Measured (examples A and B, 500 points, complex Gaussian relative noise): white noise
gives a ratio of 0.95..1.0; noise whose neighbouring points correlate by 0.5 (a windowed
spectral estimate) 1.3..1.45; B at 9 sections (max error 0.33, a systematic residual)
614 on exact data, 2..3.4 at 1 % noise, 1.5 at 3 %. The estimate leans towards "ok":
where the systematic residual changes quickly from point to point (a mode the model
misses, sampled by few points) its differences raise the noise estimate too, so a
systematic residual below about 1.5 times the noise is not told from noise.
"""

import dataclasses
import enum
import math

import numpy as np

from .diagnostics import Diagnostic

__all__ = ["FitStatus", "NoiseCheck", "residual_noise", "local_variance", "CONSISTENT_RATIO",
           "ROUNDING_RMS", "NOISE_WINDOW", "SMALL_RESIDUAL", "poor_fit_diagnostic",
           "with_cause", "status_of"]

#: Largest ratio RMS(residual) / noise for a fit consistent with the noise.
CONSISTENT_RATIO = 2.0
#: RMS relative error at or below which a fit counts as exact (rounding level of a model
#: evaluated in float64 over tens of sections: the data's own rounding is ~1e-16).
ROUNDING_RMS = 1e-8
#: RMS relative error below which a poor fit's message adds that the residual is within
#: an analyser's stated calibration accuracy (0.1 dB is 1.2 %, 1 degree 1.7 %).
SMALL_RESIDUAL = 0.01
#: Number of neighbouring differences of the running median of the local noise level.
NOISE_WINDOW = 31


class FitStatus(str, enum.Enum):
    """What a fit's result means (``FitResult.status``, ``SharedFitResult.status``); a
    ``str``, so ``res.status == "ok"`` works."""

    OK = "ok"                          #: converged, residual consistent with the noise
    POOR_FIT = "poor-fit"              #: converged, residual well above the noise
    NOT_CONVERGED = "not-converged"    #: the final stage did not converge

    def __str__(self):
        return self.value


class NoiseCheck(dict):
    """The numbers of :func:`residual_noise` (a dict, for ``FitResult.details``):
    ``rms`` (the residual's RMS), ``noise_rms`` (the noise level it is compared with:
    ``rms / ratio``), ``ratio`` (RMS of the whitened residual over its local noise),
    ``consistent``, ``n_points``, ``runs_z``
    (z-score of the sign changes of the residual's real and imaginary parts: about 0 for
    white noise, strongly negative for a smooth residual) and ``worst_omega`` (frequency
    of the largest (whitened) ``|e_i|``)."""

    @property
    def consistent(self):
        return bool(self["consistent"])


def _running_median(values, window):
    """Median of ``values`` over a centred window of ``window`` entries (shrunk at the
    ends), shape as ``values``."""
    n = values.size
    half = window // 2
    if n <= window:
        return np.full(n, np.median(values))
    pad = np.pad(values, half, mode="reflect")
    view = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    return np.median(view, axis=1)[:n]


def _runs_z(signs):
    """z-score of the number of sign changes of ``signs`` (bool array) against a random
    sequence of the same counts (Wald-Wolfowitz)."""
    n1, n = int(np.count_nonzero(signs)), signs.size
    n2 = n - n1
    if n1 == 0 or n2 == 0 or n < 3:
        return 0.0
    runs = 1 + int(np.count_nonzero(signs[1:] != signs[:-1]))
    mu = 1.0 + 2.0 * n1 * n2 / n
    var = (mu - 1.0) * (mu - 2.0) / (n - 1.0)
    return float((runs - mu) / math.sqrt(var)) if var > 0 else 0.0


def local_variance(residual, window=NOISE_WINDOW):
    """The noise variance at each point of a residual: the running median of
    ``|e_{i+1} - e_i|^2 / (2 ln 2)`` over ``window`` differences, point i taking the mean
    of its two neighbouring differences' levels (the module docstring).

    Parameters
    ----------
    residual : ndarray of complex, shape (M,), M >= 2
    window : int

    Returns
    -------
    ndarray of float, shape (M,)
    """
    d2 = np.abs(np.diff(residual)) ** 2 / (2.0 * math.log(2.0))
    local = _running_median(d2, window)
    var = np.empty(residual.size)
    var[0], var[-1] = local[0], local[-1]
    var[1:-1] = 0.5 * (local[:-1] + local[1:])
    return var


def residual_noise(residual, omega, weights=None, window=NOISE_WINDOW):
    """Is the complex relative residual consistent with white noise? See the module.

    Parameters
    ----------
    residual : ndarray of complex, shape (M,)
        ``Phi / G_N - 1`` at every point.
    omega : ndarray of float, shape (M,)
        rad/s (any unit: only reported back as ``worst_omega``).
    weights : ndarray of float, shape (M,), optional
        Inverse relative variances (only their ratios matter); points of weight 0 are
        left out.
    window : int
        Differences in the running median of the local noise level.

    Returns
    -------
    NoiseCheck
    """
    e = np.asarray(residual, complex)
    w_om = np.asarray(omega, float)
    keep = np.isfinite(e)
    scale = np.ones(e.size)
    if weights is not None:
        w = np.asarray(weights, float)
        keep &= w > 0
        if np.any(keep):
            scale = np.sqrt(w / np.mean(w[keep]))
    e, scale, w_om = e[keep] * scale[keep], scale[keep], w_om[keep]
    out = NoiseCheck(n_points=int(e.size), noise_rms=math.nan, ratio=math.nan,
                     consistent=False, runs_z=math.nan, worst_omega=math.nan,
                     rms=math.nan)
    if e.size < 4:
        return out
    var = local_variance(e, window)
    floor = (ROUNDING_RMS / CONSISTENT_RATIO) ** 2
    var = np.maximum(var, floor * scale ** 2)
    q = np.abs(e) ** 2 / var
    ratio = float(np.sqrt(np.mean(q)))
    rms = float(np.sqrt(np.mean(np.abs(e / scale) ** 2)))       # weights undone
    runs = 0.5 * (_runs_z(e.real > 0) + _runs_z(e.imag > 0))
    out.update(noise_rms=rms / ratio if ratio > 0 else 0.0, ratio=ratio, runs_z=float(runs),
               worst_omega=float(w_om[int(np.argmax(np.abs(e)))]), rms=rms,
               consistent=bool(ratio <= CONSISTENT_RATIO or rms <= ROUNDING_RMS))
    return out


#: Which diagnostic explains a poor fit, and the step it suggests, in order of priority.
_CAUSES = (
    ("no-better-than-trivial", "the model explains almost nothing of the data"),
    ("negative-gain", "the gain sign"),
    ("integrator", "the count of poles or zeros at the origin, which the data and the "
                   "model do not share"),
    ("non-minimum-phase", "the model class: the data need right-half-plane zeros "
                          "(pass zeros='free')"),
    ("root-below-band", "the structure: a pole or zero at the origin the model lacks "
                        "(pass integrator=k: k poles at the origin, a negative k for zeros; "
                        "integrator='auto' tries them)"),
    ("delay-undetermined", "the delay: it may be larger than the frequency spacing "
                           "resolves (sample more densely or remove a known delay)"),
)


def poor_fit_diagnostic(check, found, n_sections, unit="rad/s"):
    """The ``poor-fit`` record of a converged fit whose residual is well above the noise.

    Parameters
    ----------
    check : NoiseCheck
    found : sequence of Diagnostic
        The fit's other diagnostics (they name the cause when there is one).
    n_sections : int
    unit : str
        Unit of omega for the message.

    Returns
    -------
    Diagnostic
        Its ``values["cause"]``: the code of the diagnostic that explains it, or "order"
        (``n_sections='auto'`` restates that as "not-the-order" when it fitted more
        sections without a significant fall of the RMS).
    """
    # a delay the data do not determine explains a poor fit only when it sits in the upper
    # half of its range (aliased); a tiny or traded delay is a finding of its own
    # and a negative gain the fits chose (gain_sign="auto": the other sign was worse,
    # an "info") explains nothing; only a sign forced against the data does
    codes = [d.code for d in found
             if (d.code != "delay-undetermined"
                 or d.values.get("delay", 0.0) >= 0.5 * d.values.get("delay_max", math.inf))
             and (d.code != "negative-gain" or d.severity != "info")
             # (the integrator records of integrator="auto" state a choice, not a cause)
             and (d.code != "integrator" or "origin_mismatch" in d.values)
             # (a root below the band whose refit integrator="auto" made and did not keep,
             # restate_roots_below_band's asked_fit_rms: advising it again goes in a circle)
             and (d.code != "root-below-band" or "asked_fit_rms" not in d.values)
             # (nor one with a partner below the band: a spare lag-lead step, not k)
             and (d.code != "root-below-band" or "partner_roots" not in d.values)]
    cause = next(((code, text) for code, text in _CAUSES if code in codes), None)
    if cause is None:
        why = ("the order: the residual is largest near omega = "
               f"{check['worst_omega']:.4g} {unit}, a feature the model misses; pass "
               f"n_sections={n_sections + 1} or more (or min_damping='auto' if that "
               "feature is noise)")
        cause_code = "order"
    else:
        why = f"{cause[1]} (see the {cause[0]} diagnostic)"
        cause_code = cause[0]
    values = {k: (float(v) if isinstance(v, (float, np.floating)) else v)
              for k, v in check.items()}
    return with_cause(Diagnostic("poor-fit", "", "warning", values), cause_code, why)


def with_cause(diag, code, why):
    """A ``poor-fit`` record with its likely cause stated anew (its numbers as they are).

    Parameters
    ----------
    diag : Diagnostic
        A ``poor-fit`` record (:func:`poor_fit_diagnostic`).
    code : str
        ``values["cause"]``.
    why : str
        The cause's text, after "the likely cause is ".

    Returns
    -------
    Diagnostic
    """
    v = diag.values
    msg = (f"the residual (RMS {v['rms']:.3g}) is {v['ratio']:.3g} times the noise "
           f"its point-to-point scatter shows ({v['noise_rms']:.2g}), so the model does "
           f"not explain the data; the likely cause is {why}")
    if v["rms"] <= SMALL_RESIDUAL:
        # a Siglent Bode export fitted to 0.42 % RMS, smooth, 9 times its scatter
        msg += (f"; the residual is small (RMS {100 * v['rms']:.2g} %: about "
                f"{20 * math.log10(1 + v['rms']):.2g} dB and {math.degrees(v['rms']):.2g} deg), "
                "within the accuracy analysers state for their calibration (about 0.1 dB "
                "and 1 deg): if it is the analyser's own smooth error, which the "
                "point-to-point scatter does not show, the model is as good as the data "
                "allow")
    return dataclasses.replace(diag, message=msg, values=dict(v, cause=code))


def status_of(converged, errors_found, check):
    """The :class:`FitStatus` of a fit.

    Parameters
    ----------
    converged : bool
        The final all-data stage converged.
    errors_found : bool
        A diagnostic of severity "error" was found (or the model is no better than an
        infinite gain).
    check : NoiseCheck
        The residual's consistency with the noise (:func:`residual_noise`).

    Returns
    -------
    FitStatus
    """
    if not converged:
        return FitStatus.NOT_CONVERGED
    if errors_found or not check.consistent:
        return FitStatus.POOR_FIT
    return FitStatus.OK
