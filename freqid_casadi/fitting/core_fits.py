"""The core fits of :func:`~freqid_casadi.fitting.fit.fit` (its starts and candidates):
one per contender of ``integrator="auto"`` and, where the rational starts do not decide
the gain sign, one per sign; with ``n_jobs > 1`` each in a forked worker process.

Each core fit is independent of the others and deterministic, so the fits are the same,
bit for bit, in a worker or here; only their order in time differs. The two signs' fits
of a refit (the delay hold's, the resolution guard's, the free-zeros alternative's) run
in two workers too, within :func:`~freqid_casadi._workers.allow_jobs`.
"""
import dataclasses
import time

from .._workers import forked_map
from ..core.model import check_origin_order
from .diagnostics import Diagnostic

__all__ = ["either_sign", "either_sign_fits", "core_fits"]


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
    both = {"K > 0" if s > 0 else "K < 0": float(fits[s].rms_rel_error) for s in fits}
    record = {"chosen": kept, "by": "fits", "rms": both}
    text = "; ".join(f"{k}: RMS {v:.3g}" for k, v in both.items())
    found = res.diagnostics
    if kept < 0:
        found = (Diagnostic("negative-gain", (
            "the rational starts did not decide the gain sign, so both signs were fitted "
            f"({text}): fitted with a negative gain (gain_sign='auto'; pass "
            "gain_sign='positive' to force K > 0)"), "info",
            {"rms_positive": both["K > 0"], "rms_negative": both["K < 0"]}),) + found
    return dataclasses.replace(
        res, diagnostics=found, details=dict(res.details, gain_sign=record),
        wall_time=res.wall_time + other.wall_time)


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
