"""Known parameters held exactly in a fit: ``fit(..., fixed={"delay": h, "dc_gain": k})``
(layer L5).

A delay measured separately or a calibrated gain should not be re-estimated from the FRF.

``"delay"``: h (s, >= 0) is removed from the variables. The model is
``exp(-h s) R(s)``, so ``Phi / G_N - 1 = (Phi exp(j w h)) / R - 1``: the whole fit (every
start, stage and rescue) runs without a delay on the data with the known delay taken out,
``Phi exp(j w h)``, and the model gets ``beta[0] = h`` back. The returned delay is ``h`` bit
for bit, and the relative errors are those of the same problem.

``"dc_gain"``: the low-frequency gain ``k`` (``K0`` of ``K0 / s`` with an integrator, the
static gain ``G(0)`` without; signed) is held by an equality in the NLP: after the fit
(loop and starts with the gain free, the gain a sequential fit finds from the lowest
frequencies), one more stage on all data refits every other parameter with the gain
variable fixed (``lbx = ubx``) in the dc gauge, whose factors have unit DC value so that
the gain variable *is* ``k``. It is started from the fitted model with its gain replaced
by ``k`` (a feasible point) and keeps the better of that start and its solution. A negative
``k`` asks for a negative gain (``gain_sign="negative"``).

The result records the held values in ``FitResult.fixed``; the delta-method covariance
(``FitResult.uncertainty``) treats them as known: they are left out of the inversion,
reported with ``at_bound`` True and a NaN standard deviation, and named in
``ParameterUncertainty.fixed``.
"""

import dataclasses
import math
import numbers

import numpy as np

from ..core.data import FrequencyData
from ..core.metrics import relative_error
from ..core.model import RationalDelayModel
from ..core.objective import Parametrization
from ..core.resolution import default_delay_max
from ..errors import OptionError
from ..options import LoopOptions, solver_options
from ._checks import after_fit, verdict
from .stages import StageKind, StageSolver, keep_better, stage_record
from .verdict import ROUNDING_RMS, residual_noise, with_cause

__all__ = ["FIXED_KEYS", "check_fixed", "fit_with_fixed", "hold_gain", "without_delay"]

#: The parameters ``fit(..., fixed=...)`` can hold.
FIXED_KEYS = ("delay", "dc_gain")


def check_fixed(fixed, *, delay=True, gain_sign="auto"):
    """``fixed`` checked: a dict of known parameters (empty for None) and the gain sign.

    Parameters
    ----------
    fixed : dict or None
        ``{"delay": h}`` (s, finite, >= 0) and/or ``{"dc_gain": k}`` (finite, nonzero).
    delay : bool
        fit's ``delay``: a fixed delay needs ``delay=True`` (the default).
    gain_sign : {"auto", "positive", "negative"}
        fit's ``gain_sign``; a negative ``dc_gain`` makes "auto" "negative".

    Returns
    -------
    fixed : dict of str to float
    gain_sign : str

    Raises
    ------
    OptionError
        Not a mapping, a key outside :data:`FIXED_KEYS`, a value that is not a finite
        real number, a negative delay, a zero gain, or a conflict with ``delay`` or
        ``gain_sign``.
    """
    if fixed is None:
        return {}, gain_sign
    if not hasattr(fixed, "items"):
        raise OptionError(f"fixed must be a dict of known parameters, e.g. "
                          f"fixed={{'delay': 0.0123}}, got {type(fixed).__name__}; allowed "
                          f"keys: {', '.join(FIXED_KEYS)}")
    out = {}
    for key, value in fixed.items():
        if key not in FIXED_KEYS:
            raise OptionError(f"fixed has the unknown key {key!r}; allowed keys: "
                              f"{', '.join(FIXED_KEYS)} (e.g. fixed={{'delay': 0.0123}})")
        if (isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real)
                or not math.isfinite(value)):
            raise OptionError(f"fixed[{key!r}] must be a finite real number, got {value!r}")
        out[key] = float(value)
    if "delay" in out:
        if out["delay"] < 0:
            raise OptionError(f"fixed['delay'] must be >= 0 (s), got {out['delay']!r}")
        if not delay:
            raise OptionError("fixed={'delay': ...} with delay=False: a held delay needs "
                              "delay=True (the default); drop one of them")
    if "dc_gain" in out:
        k = out["dc_gain"]
        if k == 0:
            raise OptionError("fixed['dc_gain'] must be nonzero (the model's low-frequency "
                              "gain K0, or G(0) without an integrator)")
        want = "negative" if k < 0 else "positive"
        if gain_sign not in ("auto", want):
            raise OptionError(f"fixed['dc_gain']={k!r} is {want} but gain_sign={gain_sign!r}; "
                              f"pass gain_sign='auto' or {want!r}")
        gain_sign = want
    return out, gain_sign


def without_delay(data, delay):
    """``data`` with a known delay taken out: ``Phi exp(j w h)`` (same grid and weights).

    Parameters
    ----------
    data : FrequencyData
    delay : float
        h, in the data's time unit.

    Returns
    -------
    FrequencyData
    """
    return FrequencyData(data.omega, data.response * np.exp(1j * data.omega * delay),
                         data.name, data.weights, data.unit)


@dataclasses.dataclass(frozen=True)
class _GainHeld(Parametrization):
    """A dc-gauge parametrization whose gain variable is fixed at 1 (``lbx = ubx``),
    ``gain_ref`` being the held gain: ``K = gain_ref * 1`` exactly."""

    def bounds(self):
        lb, ub = super().bounds()
        lb[1] = ub[1] = 1.0
        return lb, ub


def hold_gain(model, data, dc_gain, *, method="ipopt", loop=None, delay_max=None,
              zeta_min=None):
    """Refit ``model`` on ``data`` with its low-frequency gain held at ``dc_gain``.

    Parameters
    ----------
    model : RationalDelayModel
        The start (e.g. the free fit).
    data : FrequencyData
    dc_gain : float
        ``K0`` (integrator) or ``G(0)``, signed as the model's gain.
    method, loop, delay_max, zeta_min
        As :func:`~freqid_casadi.fitting.stages.polish` (the gauge is "dc" always).

    Returns
    -------
    model : RationalDelayModel
        Its gain (``model.gain`` times the sections' DC values) is ``dc_gain`` to rounding.
    result : StageResult
        The stage's solve.
    record : StageRecord
        The stage as the fit's stages record it (a final all-data stage).
    """
    solver = solver_options(method)
    loop = LoopOptions() if loop is None else loop
    st, sign = model.structure, model.structure.gain_sign
    if sign == -1:                       # the stage fits |K|: work on -Phi, sign back after
        data = FrequencyData(data.omega, -data.response, data.name, data.weights, data.unit)
        st = dataclasses.replace(st, gain_sign=1)
    if delay_max is None:
        delay_max = max(default_delay_max(data.omega), model.delay)
    refs = []
    for row in model.sections():
        w = row[-1]
        if st.basis == "second-order" and row[3] > 0:
            w = w / math.sqrt(row[3])
        refs.append(float(w) if np.isfinite(w) and w > 0 else float(data.omega[0]))
    param = _GainHeld(st, "dc", tuple(refs), abs(float(dc_gain)), float(delay_max),
                      loop.scaled, (), loop.root_floor * float(data.omega[0]))
    lb, ub = param.bounds()
    z0 = param.from_beta(np.array(model.beta))
    z0[1] = 1.0
    z0 = np.clip(z0, lb, ub)
    if zeta_min is not None:
        z0 = param.project_damping(z0, zeta_min)
    res = StageSolver(solver, dataclasses.replace(loop, gauge="dc"), zeta_min,
                      onto_bounds=True)(param, data, z0, None,
                                        max_iter=solver.final_max_iter, final=True)
    z, _, kept = keep_better(param, data, z0, np.zeros_like(z0), res)
    z[1] = 1.0
    held = param.to_model(z)
    record = stage_record(st.n_sections + 1, param, z, data, data.n_points, float("nan"), res,
                          res.nit, res.nfev, res.wall_time, kept, StageKind.FINAL)
    return RationalDelayModel(dataclasses.replace(held.structure, gain_sign=sign),
                              held.beta), res, record


#: Diagnostics of the fitted model itself, made again for the model a held gain returns
#: (the others, of the data and the fit's choices, are kept).
_MODEL_CODES = ("no-better-than-trivial", "delay-undetermined", "non-minimum-phase",
                "root-below-band", "poor-fit")


def _held_verdict(res, model, data, record, dc_gain):
    """``res`` (the free fit) with the verdict of ``model``, its gain held at ``dc_gain``
    by the stage ``record``: status, message, diagnostics and success are the held
    model's (a held gain the data do not support is a poor fit, blamed on the gain when
    the free fit does at least twice as well), the stage appended."""
    stats = relative_error(model, data)
    with np.errstate(all="ignore"):
        residual = data.response / model.frequency_response(data.omega) - 1.0
    noise = residual_noise(residual, data.omega, data.weights)
    found = tuple(d for d in res.diagnostics if d.code not in _MODEL_CODES)
    found += after_fit(model, data, stats, res.delay_max, noise=noise)
    success, status, message, details, found = verdict(
        record, stats, residual, data, found, model.n_sections, res.start, noise=noise)
    poor = [d for d in found if d.code == "poor-fit"]
    if poor and res.rms_rel_error <= 0.5 * stats.rms:
        diag = with_cause(poor[0], "held-gain", (
            f"the held dc_gain {dc_gain:.6g}: without it the fit reaches RMS "
            f"{res.rms_rel_error:.3g} (max rel. error {res.max_rel_error:.3g}); check the "
            "value, or fit without it"))
        found = tuple(diag if d is poor[0] else d for d in found)
        message = f"poor-fit: converged, but {diag.message}"
    return dataclasses.replace(res, model=model, success=success, status=status,
                               rel_error=stats.values, max_rel_error=stats.max,
                               rms_rel_error=stats.rms,
                               message=message, details=dict(res.details, **details),
                               diagnostics=found, stages=tuple(res.stages) + (record,))


def fit_with_fixed(run, data, fixed, *, delay, loop, method):
    """:func:`~freqid_casadi.fitting.fit.fit` with known parameters (module notes).

    Parameters
    ----------
    run : callable
        ``run(data, delay) -> FitResult``: the fit on ``data`` (FrequencyData with the
        weights already applied), with or without a delay.
    data : FrequencyData
        The user's data, weights applied.
    fixed : dict
        From :func:`check_fixed`.
    delay : bool
    loop : LoopOptions or None
    method : str or option object
        fit's ``loop`` and ``method`` (for the held-gain stage, which also takes the fit's
        damping floor ``FitResult.zeta_min`` and delay bound).

    Returns
    -------
    FitResult
        ``model.delay == fixed["delay"]`` exactly; ``fixed`` the held values; the errors
        those of the returned model on ``data``.
    """
    h = fixed.get("delay")
    fit_data = data if h is None else without_delay(data, h)
    res = run(fit_data, delay if h is None else False)
    model, notes, success = res.model, [], res.success
    if "dc_gain" in fixed:
        free = res
        model, stage, record = hold_gain(model, fit_data, fixed["dc_gain"], method=method,
                                         loop=loop, delay_max=res.delay_max,
                                         zeta_min=res.zeta_min)
        res = _held_verdict(res, model, fit_data, record, fixed["dc_gain"])
        success = res.success
        blamed = any(d.values.get("cause") == "held-gain" for d in res.diagnostics)
        cost = (f"; without it max rel. error {free.max_rel_error:.3g}, RMS "
                f"{free.rms_rel_error:.3g}" if res.rms_rel_error > 1.1 * free.rms_rel_error
                and res.rms_rel_error > ROUNDING_RMS and not blamed else "")
        k = model.structure.origin_order
        form = {1: "K0/s", -1: "K0 s"}.get(k, f"K0/s^{k}" if k > 0 else f"K0 s^{-k}")
        what = ("" if k == 0 else f" as K0 of {form} (the model has {abs(k)} "
                f"{'pole' if k > 0 else 'zero'}(s) at the origin; integrator=False holds "
                "G(0))")
        notes.append(f"dc_gain held at {fixed['dc_gain']:.6g}{what} by a final stage "
                     f"({stage.solver_status}){cost}")
    options = res.options
    if h is not None:
        beta = np.array(model.beta)
        beta[0] = h
        model = RationalDelayModel(dataclasses.replace(model.structure, delay=True), beta)
        notes.append(f"delay held at {h:.6g} {data.time_unit}")
        options = dataclasses.replace(options, delay=True) if options is not None else None
    stats = relative_error(model, data)
    message = res.message + "".join(f"; {n}" for n in notes)
    return dataclasses.replace(res, model=model, data=data, rel_error=stats.values,
                               max_rel_error=stats.max, rms_rel_error=stats.rms,
                               success=bool(success), message=message, options=options,
                               fixed=dict(fixed))
