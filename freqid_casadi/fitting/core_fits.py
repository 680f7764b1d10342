"""The core fits of :func:`~freqid_casadi.fitting.fit.fit` (its starts and candidates):
one per contender of ``integrator="auto"`` and, where the rational starts do not decide
the gain sign, one per sign; with ``n_jobs > 1`` each in a forked worker process.

Each core fit is independent of the others and deterministic, so the fits are the same,
bit for bit, in a worker or here; only their order in time differs. The two signs' fits
of a refit (the delay hold's, the resolution guard's, the free-zeros alternative's) run
in two workers too, within :func:`~freqid_casadi._workers.allow_jobs`.

Above :data:`SETTLE_ABOVE` frequencies the choices a fit leaves to fits are made on every
k-th point (:data:`SETTLE_POINTS` of them) when that subset represents each fit's residual
on all points: :func:`choose_on_subset` makes the integrator's rational starts there,
:func:`settle_on_subset` fits the contenders there, :func:`sign_on_subset` both gain signs;
the kept k or sign is then fitted on all points. The fits on the subset run without the
``non-minimum-phase`` check: the choice keeps only their models and RMS.
"""
import dataclasses
import functools
import math
import time

import numpy as np

from .._workers import forked_map
from ..core.data import FrequencyData
from ..core.metrics import relative_error
from ..core.model import check_origin_order
from ..core.resolution import default_delay_max, resolution_damping
from ..core.scaling import weighted_span
from ..options import LoopOptions
from .diagnostics import Diagnostic
from ..errors import FreqidError
from ._checks import without_phase_check
from .origin import choose_origin_order, settle_by_results
from .start import START_POINTS, _subsample
from .verdict import ROUNDING_RMS

__all__ = ["either_sign", "either_sign_fits", "core_fits", "choose_on_subset",
           "settle_on_subset", "settles_on_subset", "sign_on_subset", "settled_sign_fit",
           "SETTLE_ABOVE", "SETTLE_POINTS", "SETTLE_AGREEMENT"]

#: Above this many frequencies (the most the rational starts see: beyond, they take every
#: k-th point) ``integrator="auto"`` settles its contenders on a subset of the points
#: (:func:`settle_on_subset`). Measured on example A's system at 200 000 points and 2
#: sections: three contenders fitted on all points took 140 s, against 10 s on 4096
#: points and 7 s for the kept k's fit on all points; the same k, sign and model.
SETTLE_ABOVE = START_POINTS
#: Points of that subset: every k-th point, the ends kept.
SETTLE_POINTS = 4096
#: The subset settles the choice only when each contender's model, fitted on it, has on
#: all points an RMS relative error within this factor of its RMS on the subset, either
#: way (an RMS below :data:`~freqid_casadi.fitting.verdict.ROUNDING_RMS`, the rounding
#: level, where ratios mean nothing, counts as that value): the subset then samples every
#: contender's residual as all the points do (on smooth, oversampled data the two agree
#: to about a percent). A resonance or a phase turn between the subset's points shows as
#: a larger RMS on all points; the contenders are then fitted on all points.
SETTLE_AGREEMENT = 1.1


def either_sign(guess, fits):
    """Of the fits of both gain signs, the lower RMS (``guess``, the low-frequency phase's
    sign, on a tie), with the record of the choice.

    Parameters
    ----------
    guess : {1, -1}
        The sign the low-frequency phase suggests.
    fits : dict
        ``{+1: FitResult, -1: FitResult}``, each fitted with that gain sign.

    Returns
    -------
    FitResult
        The kept fit: ``details["gain_sign"]`` holds ``{"chosen": sign, "by": "fits",
        "rms": {"K > 0": rms, "K < 0": rms}}``, a ``negative-gain`` "info" diagnostic comes
        first when the negative sign is kept, and ``wall_time`` counts both fits (one
        after the other).
    """
    kept = min(fits, key=lambda s: (fits[s].rms_rel_error, s != guess))
    res, other = fits[kept], fits[-kept]
    res = _signed(res, kept, {s: float(fits[s].rms_rel_error) for s in fits})
    return dataclasses.replace(res, wall_time=res.wall_time + other.wall_time)


def _signed(res, kept, rms, settled_on=None):
    """``res`` (fitted with gain sign ``kept``) with the record of the sign's choice
    (``rms``: {sign: RMS}, in the order the signs were fitted; ``settled_on``: the subset
    the two signs were fitted on)."""
    both = {"K > 0" if s > 0 else "K < 0": rms[s] for s in rms}
    record = {"chosen": kept, "by": "fits", "rms": both}
    text = "; ".join(f"{k}: RMS {v:.3g}" for k, v in both.items())
    if settled_on is not None:
        record["settled_on"] = settled_on
        text = (f"on {settled_on['points']} of the {settled_on['of']} points; their models' "
                f"RMS on all points: {text}")
    found = res.diagnostics
    if kept < 0:
        found = (Diagnostic("negative-gain", (
            "the rational starts did not decide the gain sign, so both signs were fitted "
            f"({text}): fitted with a negative gain (gain_sign='auto'; pass "
            "gain_sign='positive' to force K > 0)"), "info",
            {"rms_positive": both["K > 0"], "rms_negative": both["K < 0"]}),) + found
    return dataclasses.replace(res, diagnostics=found, details=dict(res.details,
                                                                    gain_sign=record))


def core_fits(fit_one, sign_guess, args, ks, k, emit, n_jobs, kw):
    """The core fit of each contender ``j`` of ``ks`` (poles at the origin).

    Parameters
    ----------
    fit_one : callable
        ``fit_one(*args, kw)``: one core fit, quiet (a module-level function: the workers
        receive it pickled); ``kw["sign"]`` +1 or -1 fits that gain sign only, None lets
        the fit decide (and fit both signs itself when the starts do not).
    sign_guess : callable
        ``sign_guess(*args, kw)``: the sign the fit would guess before fitting both, or
        None when the rational starts decide it (run here, before the workers start: its
        rational starts are then shared with them).
    args : tuple
        ``(data_or_omega, response)``.
    ks : sequence of int
        The contenders.
    k : int
        The provisional choice, whose records the progress channel ``emit`` shows.
    emit : callable or False
    n_jobs : int
        Worker processes; with more than one (and a process that can fork), each
        contender's fit, or each sign's fit where the sign is a guess, runs in a worker,
        and ``k``'s records are shown when it returns.
    kw : dict
        The fit's keywords but ``integrator`` and ``progress``.

    Returns
    -------
    dict
        ``{j: FitResult}``.
    """
    jobs = {j: dict(kw, integrator=check_origin_order(j)) for j in ks}
    if n_jobs > 1:
        guesses = {j: sign_guess(*args, jobs[j]) for j in ks}
        split = [(j, s) for j in ks
                 for s in ((guesses[j], -guesses[j]) if guesses[j] else (None,))]
        fits = forked_map(fit_one, [(*args, dict(jobs[j], progress=False, sign=s))
                                    for j, s in split], n_jobs)
        if fits is not None:
            done = dict(zip(split, fits))
            core = {j: either_sign(g, {s: done[j, s] for s in (g, -g)}) if g
                    else done[j, None] for j, g in guesses.items()}
            for rec in core[k].stages:
                emit(rec)
            return core
    return {j: fit_one(*args, dict(jobs[j], progress=emit if j == k else False))
            for j in ks}


def either_sign_fits(fit_one, args, kw, guess):
    """:func:`either_sign` of the fits of both gain signs, ``guess`` first; in two forked
    workers where the fit allows them (:func:`~freqid_casadi._workers.allow_jobs`), their
    records then reaching the progress channel ``kw["progress"]`` when both return, in
    the same order.

    Parameters
    ----------
    fit_one : callable
        ``fit_one(*args, kw)``: one quiet fit, ``kw["sign"]`` the gain sign fitted (a
        module-level function).
    args : tuple
        ``(data_or_omega, response)``.
    kw : dict
        The fit's keywords (``progress``: a callable, or False).
    guess : {1, -1}

    Returns
    -------
    FitResult
        ``wall_time``: the seconds both fits took, in workers or one after the other.
    """
    t0 = time.perf_counter()
    signs = (guess, -guess)
    fits = forked_map(fit_one, [(*args, dict(kw, progress=False, sign=s)) for s in signs])
    if fits is None:
        fits = [fit_one(*args, dict(kw, sign=s)) for s in signs]
    elif callable(kw.get("progress")):
        for res in fits:
            for rec in res.stages:
                kw["progress"](rec)
    res = either_sign(guess, dict(zip(signs, fits)))
    return dataclasses.replace(res, wall_time=time.perf_counter() - t0)


def settle_on_subset(fit_one, sign_guess, data, record, n_jobs, kw):
    """The choice among ``record["contenders"]`` settled on every k-th point of ``data``
    (:data:`SETTLE_POINTS`), or None when ``data`` has at most :data:`SETTLE_ABOVE`
    points or the subset does not represent a contender's residual
    (:data:`SETTLE_AGREEMENT`): then the contenders are to be fitted on all points.

    Each contender is fitted on the subset (its core fit, :func:`core_fits`) with the
    delay bound and damping floor of all the points (the subset's coarser spacing would
    lower the first and raise the second); the choice (:func:`~freqid_casadi.fitting.
    origin.settle_by_results`) compares the RMS relative error of each contender's model on
    all points.

    Parameters
    ----------
    fit_one, sign_guess : callable
        As :func:`core_fits` takes them, called with ``(subset, None, kw)``.
    data : FrequencyData
        The validated data (weights included).
    record : dict
        The choice of :func:`~freqid_casadi.fitting.origin.choose_origin_order`.
    n_jobs : int
        Worker processes for the contenders' fits (:func:`core_fits`).
    kw : dict
        The fit's keywords but ``integrator`` and ``progress`` (``weights`` None: they
        are the data's).

    Returns
    -------
    dict or None
        The settled record (:func:`~freqid_casadi.fitting.origin.settle_by_results`), its
        ``"fit_rms"`` the RMS on all points of each contender's model fitted on the subset,
        and ``"settled_on"``: ``{"points": subset size, "of": data's points}``.
    """
    if not settles_on_subset(data.n_points):
        return None
    ks = record["contenders"]
    try:                            # (e.g. no point of the subset with a weight > 0)
        sub, sub_kw = _subset(data, kw)
        fits = core_fits(_unchecked(fit_one), sign_guess, (sub, None), ks, ks[0],
                         lambda rec: None, n_jobs, sub_kw)
    except FreqidError:
        return None
    rms = _rms_on_all(fits, data)
    if rms is None:
        return None
    settled = settle_by_results(record, fits, data, rms)
    return dict(settled, settled_on={"points": int(sub.n_points), "of": int(data.n_points)})


def choose_on_subset(data, n_sections, delay, basis, zeros):
    """:func:`~freqid_casadi.fitting.origin.choose_origin_order` of ``data``, or, above
    :data:`SETTLE_ABOVE` points, of the subset :func:`settle_on_subset` fits the
    contenders on, with the delay bound of all the points: the starts then see what the
    contenders' fits see, and those fits reuse them (the fit's memo,
    :func:`~freqid_casadi.fitting.start.rational_start_memo`).

    Parameters
    ----------
    data : FrequencyData
        The validated data (weights included).
    n_sections : int
    delay : bool
    basis : {"second-order", "first-order"}
    zeros : {"minimum-phase", "free"}

    Returns
    -------
    (int, dict)
        As :func:`~freqid_casadi.fitting.origin.choose_origin_order`; on the subset the
        record adds ``"starts_on": {"points": subset size, "of": data's points}``.
    """
    if settles_on_subset(data.n_points):
        try:                        # (e.g. no point of the subset with a weight > 0)
            sub, kw = _subset(data, {"loop": None, "min_damping": None})
            k, record = choose_origin_order(sub, n_sections, delay, basis, zeros,
                                            delay_max=kw["loop"].delay_max)
            return k, dict(record, starts_on={"points": int(sub.n_points),
                                              "of": int(data.n_points)})
        except FreqidError:
            pass
    return choose_origin_order(data, n_sections, delay, basis, zeros)


def _subset(data, kw):
    """Every k-th point of ``data`` (:data:`SETTLE_POINTS`, the ends and the weights
    kept) and the fit's keywords ``kw`` for it: the delay bound and damping floor of all
    the points (the subset's coarser spacing would lower the first and raise the second),
    ``weights`` None (they are the subset's own)."""
    idx = _subsample(data.n_points, SETTLE_POINTS)
    span = weighted_span(data).omega
    loop = kw["loop"] if kw["loop"] is not None else LoopOptions()
    if loop.delay_max is None:
        loop = dataclasses.replace(loop, delay_max=default_delay_max(span))
    floor = kw["min_damping"]
    if floor == "auto":
        floor = resolution_damping(span)
    sub = FrequencyData(data.omega[idx], data.response[idx], data.name,
                        None if data.weights is None else data.weights[idx], data.unit)
    return sub, dict(kw, loop=loop, min_damping=floor, weights=None)


def _unchecked(fit_one):
    """``fit_one`` for a fit on the subset: without the ``non-minimum-phase`` check
    (:func:`~freqid_casadi.fitting._checks.without_phase_check`), whose diagnostic changes
    neither the model nor its RMS, the only parts of that fit the choice keeps (the kept k
    or sign is fitted on all points, with its check). A partial of module-level
    functions: a worker receives it pickled."""
    return functools.partial(_without_phase_check, fit_one)


def _without_phase_check(fit_one, *args):
    with without_phase_check():
        return fit_one(*args)


def _rms_on_all(fits, data):
    """``{key: RMS relative error on all points of data}`` of the models of ``fits``
    (``{key: FitResult}``, fitted on a subset), or None when one of them is not within
    :data:`SETTLE_AGREEMENT` of its RMS on the subset (the subset does not sample that
    residual as all the points do)."""
    out = {}
    for key, res in fits.items():
        with np.errstate(all="ignore"):
            rms = float(relative_error(res.model, data).rms)
        # (exact fits: two RMS at the rounding level agree whatever their ratio)
        lo, hi = sorted((max(rms, ROUNDING_RMS), max(res.rms_rel_error, ROUNDING_RMS)))
        if not (math.isfinite(hi) and hi <= SETTLE_AGREEMENT * lo):
            return None
        out[key] = rms
    return out


def settles_on_subset(n_points):
    """Whether a fit of ``n_points`` frequencies settles its undecided choices (the
    integrator's contenders, the gain sign) on a subset of them.

    Parameters
    ----------
    n_points : int
        The data's frequencies.

    Returns
    -------
    bool
        True above :data:`SETTLE_ABOVE`.
    """
    return n_points > SETTLE_ABOVE


def sign_on_subset(fit_one, data, kw, guess):
    """The gain sign, which the rational starts did not decide, settled by fitting both
    signs on every k-th point of ``data`` (:data:`SETTLE_POINTS`), or None when ``data``
    has at most :data:`SETTLE_ABOVE` points or the subset does not represent a sign's
    residual (:data:`SETTLE_AGREEMENT`): then both signs are to be fitted on all points
    (:func:`either_sign_fits`).

    Each sign is fitted on the subset as :func:`settle_on_subset` fits a contender (the
    delay bound and damping floor of all the points; in two forked workers where the fit
    allows them); the kept sign is the lower RMS relative error of the two models on all
    points (``guess`` on a tie), as :func:`either_sign` keeps the lower RMS of two fits.

    Parameters
    ----------
    fit_one : callable
        As :func:`either_sign_fits` takes it, called with ``(subset, None, kw)``.
    data : FrequencyData
        The validated data (weights included).
    kw : dict
        The fit's keywords (``weights``: None or the data's, ``sign`` not set).
    guess : {1, -1}
        The sign the low-frequency phase suggests.

    Returns
    -------
    (int, dict, dict, float) or None
        The kept sign, ``{sign: RMS on all points}``, ``{"points": subset size, "of":
        data's points}`` and the seconds the subset's fits took.
    """
    if not settles_on_subset(data.n_points):
        return None
    t0 = time.perf_counter()
    signs = (guess, -guess)
    try:
        sub, sub_kw = _subset(data, kw)
        jobs = [(sub, None, dict(sub_kw, progress=False, sign=s)) for s in signs]
        unchecked = _unchecked(fit_one)
        fits = forked_map(unchecked, jobs)
        if fits is None:
            fits = [unchecked(*job) for job in jobs]
    except FreqidError:
        return None
    rms = _rms_on_all(dict(zip(signs, fits)), data)
    if rms is None:
        return None
    lo, hi = sorted(rms.values())
    if not hi > SETTLE_AGREEMENT * max(lo, ROUNDING_RMS):
        return None             # too close to call on the subset: the fits on all points
    kept = min(signs, key=lambda s: (rms[s], s != guess))
    return (kept, rms, {"points": int(sub.n_points), "of": int(data.n_points)},
            time.perf_counter() - t0)


def settled_sign_fit(fit_one, args, kw, settled):
    """The fit of the sign :func:`sign_on_subset` kept, on all points, with the record
    of the choice.

    Parameters
    ----------
    fit_one : callable
        As :func:`either_sign_fits` takes it.
    args : tuple
        ``(data_or_omega, response)``, as the fit was given them.
    kw : dict
        The fit's keywords (``sign`` not set).
    settled : tuple
        What :func:`sign_on_subset` returned.

    Returns
    -------
    FitResult
        ``fit_one(*args, kw)`` with ``kw["sign"]`` the kept sign: ``details["gain_sign"]``
        as :func:`either_sign` gives it, its ``"rms"`` those of the subset's models on all
        points, and ``"settled_on"`` the subset's size; ``wall_time`` counts the subset's
        fits.
    """
    kept, rms, settled_on, seconds = settled
    res = _signed(fit_one(*args, dict(kw, sign=kept)), kept, rms, settled_on)
    return dataclasses.replace(res, wall_time=res.wall_time + seconds)
