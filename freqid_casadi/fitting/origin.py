"""``fit(integrator="auto")``: the number of poles (or zeros) at the origin, from the fits
(layer L5; issue 26 item 5).

The model has the factor ``s^(-k)``: k poles at the origin (an integrator k = 1, a motor's
current-to-angle response k = 2), or -k zeros there (a high-pass or band-pass filter k = -1
or -2, an accelerance k = -2). The low-frequency log-log slope of the data alone does not
decide k (a pole below the band looks like an integrator; a resonance near the lowest bins
bends the slope), so the slope only proposes the candidates: k = -round(slope) and its two
neighbours, and k = 0, within ``|k| <= MAX_ORIGIN_ORDER``; when the lowest bins do not lie
on a line of a slope an origin order can have (a resonance among them:
:func:`slope_informative`), or when no start of the slope's candidates explains the data
(RMS above :data:`POOR_START`; the starts then also try the data's group delay as their
delay), every ``|k| <= 2`` is a candidate too. Each candidate is judged
by the rational start (:func:`~freqid_casadi.fitting.start.rational_start`: vector fitting
of ``data * (j omega)^k`` with the delay refined; no IPOPT, a fraction of a fit's time) with
either gain sign, by its RMS relative error on the data. Of the candidates within
:data:`PREFER_FACTOR` of the lowest error, the one with the smallest ``|k|`` wins (the
simpler model, when the data do not tell them apart), except that a candidate whose start
puts poles or zeros far below the band (below ``BELOW_BAND`` times the lowest frequency: the
data cannot tell them from roots at the origin) counts as the k it effectively has and
yields to the candidate that has them at the origin (a k = 0 start of accelerance data with
two zeros near 0 is the k = -2 model reached the hard way: the fit's bounds stop such roots
at a floor); that k is tried too when the slope did not propose it (a band-pass whose lowest
bins fall into an antiresonance just above them, on a clean line of slope -1: candidates 0,
1, 2, and the k = 0 start's zero far below the lowest frequency asks for k = -1); when no
candidate near the lowest error agrees with its own start, the winner's start stands for
another k whose own start was less accurate, and both are fitted in full, that k first.
When another candidate, not effectively the same, is within :data:`AMBIGUOUS_FACTOR` of
the winner, the choice is ambiguous: both are fitted (the full fit, up to :data:`MAX_FITS`
close candidates, and k = 0 in any case, since a start is only as good as vector fitting's
model). Of the full fits the lower RMS wins; when another fit, not effectively the
winner's k, is within that factor (typically: the data end too high to show the
low-frequency asymptote) an ``integrator`` warning gives the errors of each choice and the
switch ``integrator=...``.
"""

import dataclasses
import math

import numpy as np

from ..core.model import MAX_ORIGIN_ORDER, Structure
from ..core.resolution import default_delay_max
from ..core.scaling import reference_scales, scale_data
from .diagnostics import (BELOW_BAND, EXACT_START, Diagnostic, low_frequency_line,
                          spell_origin)
from .start import best_signed_start, memo_map
from .verdict import poor_fit_diagnostic

__all__ = ["choose_origin_order", "origin_candidates", "slope_informative", "settle_by_fits",
           "settle_by_results", "restate_roots_below_band",
           "origin_diagnostics", "describe_origin", "PREFER_FACTOR", "AMBIGUOUS_FACTOR",
           "MAX_FITS", "SLOPE_SCATTER", "POOR_START"]

#: A candidate with a smaller ``|k|`` whose start's RMS error is within this factor of the
#: best candidate's is chosen instead (the simpler model when the data do not decide).
PREFER_FACTOR = 1.5
#: Another candidate within this factor of the chosen one's error: the choice is stated as
#: ambiguous (an ``integrator`` warning with the errors of each choice).
AMBIGUOUS_FACTOR = 3.0
#: RMS error of the positive-gain start below which the negative sign is not tried (the
#: data explained to rounding; the gain-sign check's cut-off, :data:`EXACT_START`). It
#: was 0.25: on a 140-220 GHz transmission measurement (tx190_s21, 5 sections) the
#: positive start at RMS 0.16 then hid the negative one at 0.0086 and the fit ended at
#: 0.0111 with two zeros at the origin instead of 0.0073.
#: fit's own sign check runs the same starts (rational_start_memo), so trying both costs
#: at most one start per candidate.
DECISIVE_RMS = EXACT_START
#: Most full fits an ambiguous choice runs of the contenders within AMBIGUOUS_FACTOR (k = 0
#: is fitted too, beyond them).
MAX_FITS = 3
#: RMS (natural log of |G|) of the lowest points about their fitted line above which the
#: slope does not propose the candidates alone (:func:`slope_informative`): four times
#: the log scatter of the noisiest corpus data (5 % noise); the lowest bins of 58 of 765
#: corpus FRFs (seeds 0, 11, 23, 37) exceed it, a resonance among them.
SLOPE_SCATTER = 0.2
#: The k tried too when the slope is not informative, or when no start of the slope's
#: candidates explains the data (:data:`POOR_START`).
UNINFORMED = (0, 1, -1, 2, -2)
#: RMS relative error of the best start above which the slope's candidates are taken to
#: have missed the origin order and every ``|k| <= 2`` is tried too: four times the
#: noisiest corpus data's 5 % (a motor's k = 2 data whose lowest bins rise at slope +1
#: on a clean line, from a zero pair just above them: candidates 0, -1, -2, best start
#: 0.57; the k = 2 start fits to the noise).
POOR_START = 0.2


def origin_candidates(slope, informative=True):
    """The k tried by ``integrator="auto"``.

    Parameters
    ----------
    slope : float
        Low-frequency log-log slope of |G| (decades per decade).
    informative : bool, optional
        False when the lowest points do not lie on a line of a slope an origin order can
        have (:func:`slope_informative`): then every k with ``|k| <= 2`` is tried too.

    Returns
    -------
    tuple of int
        ``-round(slope)`` and its neighbours, and 0, within ``|k| <= MAX_ORIGIN_ORDER``,
        sorted by ``|k|`` (then k); just ``(0, 1, -1)`` when the slope is not finite.
    """
    if not math.isfinite(slope):
        return (0, 1, -1)
    c = int(np.clip(-round(slope), -MAX_ORIGIN_ORDER, MAX_ORIGIN_ORDER))
    ks = {0} | {k for k in (c - 1, c, c + 1) if abs(k) <= MAX_ORIGIN_ORDER}
    if not informative:
        ks |= set(UNINFORMED)
    return tuple(sorted(ks, key=lambda k: (abs(k), k)))


def slope_informative(data, slope, scatter=None):
    """Whether the low-frequency slope can propose the origin order: its magnitude at most
    ``MAX_ORIGIN_ORDER + 0.5`` and the lowest points' ``log|G|`` within
    :data:`SLOPE_SCATTER` (RMS) of the fitted line. A resonance among the lowest bins
    fails it: the bins then rise or fall with the resonance, not with the roots at the
    origin (an integrator whose lowest bins span a resonance and the antiresonance after
    it: slope -4.5, candidates 0, 2, 3 and never the true 1).

    Parameters
    ----------
    data : FrequencyData
    slope : float
        :func:`~freqid_casadi.fitting.diagnostics.low_frequency_slope` of ``data``.
    scatter : float, optional
        The lowest points' scatter about that line when already known
        (:func:`~freqid_casadi.fitting.diagnostics.low_frequency_line`).

    Returns
    -------
    bool
    """
    if not math.isfinite(slope) or abs(slope) > MAX_ORIGIN_ORDER + 0.5:
        return False
    if scatter is None:
        scatter = low_frequency_line(data, 0)[1]
    return bool(scatter <= SLOPE_SCATTER)


def _start_error(scaled, structure, dmax, group_delay_trial=False):
    """(RMS, max, effective k) of the rational start of ``structure`` on ``scaled``, the
    better of the two gain signs (the negative one only when the positive start's RMS is
    not below :data:`DECISIVE_RMS`; inf when neither start is usable); the effective k
    counts the start's poles (minus zeros) far below the band as poles at the origin."""
    best = best_signed_start(scaled, structure, (1, -1), delay_max=dmax,
                             exact=DECISIVE_RMS, group_delay_trial=group_delay_trial)
    if best is None:
        return math.inf, math.inf, structure.origin_order
    rms, worst, start = best
    return rms, worst, _effective_order(start.model, scaled.omega[0])


def _effective_order(model, omega_min):
    """The model's k plus its poles, minus its zeros, below ``BELOW_BAND * omega_min``
    (which the data cannot tell from roots at the origin)."""
    k = model.origin_order
    low = BELOW_BAND * float(omega_min)
    poles = model.poles()[max(k, 0):]
    zeros = model.zeros()[max(-k, 0):]
    return int(k + np.sum(np.abs(poles) < low) - np.sum(np.abs(zeros) < low))


def choose_origin_order(data, n_sections, delay, basis, zeros, delay_max=None):
    """The poles at the origin ``integrator="auto"`` fits (see the module docstring).

    Parameters
    ----------
    data : FrequencyData
        The data as given (the choice scales them itself).
    n_sections : int
        Sections of the model to fit (each candidate's start has as many).
    delay : bool
    basis : {"second-order", "first-order"}
    zeros : {"minimum-phase", "free"}
    delay_max : float, optional
        Largest delay the starts try (s, in the data's units); default the data's own
        bound (:func:`~freqid_casadi.core.resolution.default_delay_max`).

    Returns
    -------
    k : int
        The chosen number of poles at the origin (negative: zeros).
    record : dict
        ``{"auto": True, "chosen": k, "candidates": [k, ...], "rms": {k: RMS}, "max":
        {k: max}, "effective": {k: k + roots below the band}, "low_frequency_slope": slope,
        "slope_informative": bool, "poor_starts": bool, "ambiguous": bool, "runner_up": k
        or None}``, the
        errors being those of each candidate's rational start on the data (either gain
        sign), for ``FitResult.details["integrator"]``.
    With more than one k in ``record["contenders"]`` the caller fits each and settles the
    choice (:func:`settle_by_fits`): when ``record["ambiguous"]``, the chosen k, the
    runner-up and, up to :data:`MAX_FITS`, the others within :data:`AMBIGUOUS_FACTOR`,
    then k = 0 in any case; when the chosen start is effectively another candidate's k
    (its roots far below the band) and no other is close, that k and the chosen one, that
    k first. :func:`origin_diagnostics` then states it: an
    ``integrator`` record, "info" when a k other than 0 is chosen clearly, "warning"
    (with the errors of each choice and ``pass integrator=...``) when it stays ambiguous.
    """
    slope, scatter = low_frequency_line(data, 0)         # one line fit for both
    informative = slope_informative(data, slope, scatter)
    cands = origin_candidates(slope, informative)
    w_ref, g_ref = reference_scales(data)
    scaled = scale_data(data, w_ref, g_ref)
    dmax = (default_delay_max(scaled.omega) if delay_max is None
            else float(delay_max) * w_ref)            # (as the fit scales its own bound)

    def starts(ks, group_delay_trial=False):
        """{k: _start_error} of each k of ``ks`` (independent: in workers where the fit
        allows them, :func:`~freqid_casadi.fitting.start.memo_map`)."""
        return dict(zip(ks, memo_map(_start_error, [
            (scaled, Structure(int(n_sections), k, delay, basis, zeros), dmax,
             group_delay_trial) for k in ks])))

    errors = starts(cands)
    # a start whose roots far below the band make it effectively another k asks for that
    # k: it is tried too (the slope's candidates may miss it)
    errors.update(starts([k for k in sorted({errors[k][2] for k in cands} - set(cands),
                                            key=lambda k: (abs(k), k))
                          if abs(k) <= MAX_ORIGIN_ORDER]))
    # no start explains the data: the slope may have proposed the wrong orders, and the
    # starts' delay updates may have run off (each start tries the data's group delay too)
    poor = not min(e[0] for e in errors.values()) <= POOR_START
    if poor:
        errors.update(starts(sorted(set(errors) | set(UNINFORMED),
                                    key=lambda k: (abs(k), k)), group_delay_trial=True))
    cands = tuple(sorted(errors, key=lambda k: (abs(k), k)))
    rms = {k: errors[k][0] for k in cands}
    eff = {k: errors[k][2] for k in cands}
    best = min(cands, key=lambda k: (rms[k], abs(k)))
    if math.isfinite(rms[best]):
        near = [k for k in cands if rms[k] <= PREFER_FACTOR * rms[best]]
        # a start that puts roots far below the band asks for them at the origin: among
        # the near-best, the candidates whose start agrees with its own k come first
        chosen = min(near, key=lambda k: (eff[k] != k, abs(k), rms[k]))
    else:
        chosen = 0
    others = [k for k in cands if k != chosen and eff[k] != chosen]
    close = [k for k in others if rms[k] <= AMBIGUOUS_FACTOR * max(rms[chosen], 1e-300)]
    runner = (min(close, key=lambda k: (eff[k] != k, rms[k])) if close else
              min(others, key=lambda k: rms[k]) if others else None)
    usable = math.isfinite(rms[chosen])
    ambiguous = bool(not usable or runner is not None and
                     rms[runner] <= AMBIGUOUS_FACTOR * max(rms[chosen], 1e-300))
    contenders = _contenders(chosen, runner, close, ambiguous, rms, cands)
    apparent = eff[chosen]
    if not ambiguous and apparent != chosen and math.isfinite(rms.get(apparent, math.inf)):
        # the chosen start itself puts roots far below the band: the model of the candidate
        # that has them at the origin, reached the hard way, whose own start was not near
        # enough to be preferred (vector fitting's accuracy, not the data's): both are
        # fitted, that candidate first (it wins a tie), and the fits decide
        contenders, chosen, runner = [int(apparent), int(chosen)], apparent, chosen
    record = {"auto": True, "chosen": int(chosen), "candidates": [int(k) for k in cands],
              "contenders": contenders,
              "rms": {int(k): rms[k] for k in cands},
              "max": {int(k): errors[k][1] for k in cands},
              "effective": {int(k): int(eff[k]) for k in cands},
              "low_frequency_slope": float(slope), "slope_informative": informative,
              "poor_starts": poor,
              "ambiguous": ambiguous,
              "runner_up": None if runner is None else int(runner)}
    return int(chosen), record


def _contenders(chosen, runner, close, ambiguous, rms, cands):
    """The k an ambiguous choice fits in full: the chosen one, the runner-up, the other
    close ones by their starts' errors up to :data:`MAX_FITS`, and k = 0; ``[chosen]`` when
    the choice is clear."""
    if not ambiguous:
        return [int(chosen)]
    contenders = [int(chosen)] + sorted(
        (int(k) for k in close if k != runner), key=lambda k: rms[k])[:MAX_FITS - 2]
    if runner is not None:
        contenders.insert(1, int(runner))
    if 0 in cands and 0 not in contenders:
        # the starts rank the candidates only as well as vector fitting finds each model:
        # the model without roots at the origin is fitted too (beyond MAX_FITS: when the
        # slope is not informative, candidates with close starts can fill them)
        contenders.append(0)
    return contenders


def settle_by_fits(record, fits, effective=None):
    """The record once the choice among several contenders was settled by full fits.

    The lowest error wins unless the first contender (the starts' choice) is within
    :data:`PREFER_FACTOR` of it (differences at the noise level do not move the choice),
    and a contender with fewer roots at the origin (a smaller ``|k|``) and a lower error
    than that choice wins over it (unless its model has the choice's roots below the band);
    still ambiguous when another is within :data:`AMBIGUOUS_FACTOR` of the winner, unless
    that one's fitted model is effectively the winner's k (its roots far below the band
    stand for the winner's roots at the origin: the same model, no alternative).

    Parameters
    ----------
    record : dict
        The choice of :func:`choose_origin_order` (its ``"contenders"``).
    fits : dict of int to float
        Each contender k to the RMS relative error of ``fit(..., integrator=k)``.
    effective : dict of int to int, optional
        Each contender k to its fitted model's k plus its poles, minus its zeros, below
        the band (:func:`settle_by_results`); default: each its own k.

    Returns
    -------
    dict
        ``record`` with ``"chosen"``, ``"ambiguous"`` and ``"fit_rms"`` updated.
    """
    first = record["contenders"][0]
    lowest = min(fits, key=lambda k: (fits[k], record["contenders"].index(k)))
    chosen = first if fits[first] <= PREFER_FACTOR * fits[lowest] else lowest
    eff = effective or {}
    # fewer roots at the origin and a lower error: nothing argues for the chosen one's
    # extra roots (a stepped line's S21: the starts chose k = -2, RMS 0.0572, where k = 0
    # fitted to 0.0465); not when its model has the chosen one's roots below the band
    simpler = [k for k in fits if abs(k) < abs(chosen) and fits[k] < fits[chosen]
               and eff.get(k, k) != eff.get(chosen, chosen)]
    if simpler:
        chosen = min(simpler, key=lambda k: (fits[k], record["contenders"].index(k)))
    others = [k for k in fits if k != chosen and eff.get(k, k) != chosen]
    loser = min(others, key=lambda k: fits[k]) if others else None
    ambiguous = bool(loser is not None
                     and fits[loser] <= AMBIGUOUS_FACTOR * max(fits[chosen], 1e-300))
    return dict(record, chosen=int(chosen), ambiguous=ambiguous,
                runner_up=None if loser is None else int(loser),
                fit_rms={int(k): float(v) for k, v in fits.items()})


def settle_by_results(record, results, data, rms=None):
    """:func:`settle_by_fits` of the contenders' fits.

    Parameters
    ----------
    record : dict
        The choice of :func:`choose_origin_order`.
    results : dict of int to FitResult
        Each contender k to ``fit(..., integrator=k)``.
    data : FrequencyData
        The data fitted (its lowest frequency bounds the band).
    rms : dict of int to float, optional
        Each contender's RMS relative error to compare (default: its fit's own,
        ``rms_rel_error``).

    Returns
    -------
    dict
        As :func:`settle_by_fits`, each contender's effective k from its fitted model.
    """
    omega_min = float(data.omega[0])
    if rms is None:
        rms = {k: r.rms_rel_error for k, r in results.items()}
    return settle_by_fits(record, rms,
                          {int(k): _effective_order(r.model, omega_min)
                           for k, r in results.items()})


def restate_roots_below_band(diagnostics, record):
    """``diagnostics`` with each ``root-below-band`` record whose asked-for k
    (``values["integrator_asked"]``) ``integrator="auto"`` fitted and did not keep saying
    so, with both fits' RMS errors (the advice "refit with integrator=k" is then already
    answered).

    Parameters
    ----------
    diagnostics : sequence of Diagnostic
        The kept fit's records.
    record : dict
        The settled choice (:func:`settle_by_fits`: its ``"fit_rms"``).

    Returns
    -------
    tuple of Diagnostic
    """
    fits, chosen = record.get("fit_rms") or {}, record["chosen"]
    out = []
    for d in diagnostics:
        asked = d.values.get("integrator_asked") if d.code == "root-below-band" else None
        if asked in fits and asked != chosen and chosen in fits:
            other = f"integrator={spell_origin(asked)}"
            d = dataclasses.replace(d, message=(
                f"{d.message}; integrator='auto' fitted {other} too and kept this model "
                f"(its RMS {fits[chosen]:.3g}; {other}'s {fits[asked]:.3g})"),
                values=dict(d.values, asked_fit_rms=float(fits[asked])))
        out.append(d)
    return tuple(out)


def recause_poor_fit(diagnostics, message, n_sections, unit="rad/s"):
    """``(diagnostics, message)`` with a ``poor-fit`` record whose cause was a
    ``root-below-band`` that ``integrator="auto"`` answered (it fitted the k asked for and
    did not keep it: :func:`restate_roots_below_band`'s ``asked_fit_rms``, which
    :func:`~freqid_casadi.fitting.verdict.poor_fit_diagnostic` then passes over) given the
    next cause in line: advising that refit again would send the user in a circle (a
    Siglent export: integrator=-1 fitted at RMS 0.00156 against 0.00153, and the poor fit
    still blamed the zero at the origin).

    Parameters
    ----------
    diagnostics : sequence of Diagnostic
    message : str
        The result's message (the old cause's text in it is replaced).
    n_sections : int
    unit : str

    Returns
    -------
    (tuple of Diagnostic, str)
    """
    diagnostics = tuple(diagnostics)
    poor = next((d for d in diagnostics if d.code == "poor-fit"
                 and d.values.get("cause") == "root-below-band"), None)
    if poor is None:
        return diagnostics, message
    new = poor_fit_diagnostic({k: v for k, v in poor.values.items() if k != "cause"},
                              [d for d in diagnostics if d is not poor], n_sections, unit)
    if new.values["cause"] == "root-below-band":
        return diagnostics, message
    return (tuple(new if d is poor else d for d in diagnostics),
            message.replace(poor.message, new.message))


def describe_origin(k):
    """Words for k poles at the origin.

    Parameters
    ----------
    k : int
        Poles at the origin (negative: zeros).

    Returns
    -------
    str
        "no pole or zero at the origin", "2 poles at the origin", "1 zero at the
        origin", ...
    """
    if k == 0:
        return "no pole or zero at the origin"
    n, what = abs(k), "pole" if k > 0 else "zero"
    return f"{n} {what}{'s' if n > 1 else ''} at the origin"


def origin_diagnostics(record, data):
    """The ``integrator`` diagnostic of an ``integrator="auto"`` choice.

    Parameters
    ----------
    record : dict
        The choice (:func:`choose_origin_order`, :func:`settle_by_fits`).
    data : FrequencyData
        The data fitted (its lowest frequency is named).

    Returns
    -------
    tuple of Diagnostic
        () for a clear k = 0.
    """
    k, rms = record["chosen"], record["rms"]
    table = "; ".join(f"integrator={spell_origin(j)}: RMS {rms[j]:.3g}"
                      for j in sorted(rms, key=lambda j: (abs(j), j)))
    table = f"rational starts: {table}"
    if "fit_rms" in record:
        on = record.get("settled_on")
        fits = ("fits" if not on else f"fits on {on['points']} of the {on['of']} points "
                "(the kept k then on all), their RMS on all")
        table += f"; {fits}: " + "; ".join(f"integrator={spell_origin(j)}: RMS {v:.3g}"
                                          for j, v in record["fit_rms"].items())
    values = {"chosen": k, "candidates": record["candidates"],
              "rms": [rms[j] for j in record["candidates"]],
              "low_frequency_slope": record["low_frequency_slope"]}
    if record["ambiguous"]:
        other = record["runner_up"]
        lowest = float(data.omega[0])
        msg = (f"integrator='auto' chose {describe_origin(k)} (integrator={spell_origin(k)}) "
               f"but the fits hardly tell it from "
               + (f"integrator={spell_origin(other)}" if other is not None else "the others")
               + f" ({table}); the data may end too high (lowest {lowest:.4g} {data.unit}) "
               f"to show the low-frequency asymptote: pass integrator="
               f"{spell_origin(k)} or integrator={spell_origin(other)} if you know it")
        return (Diagnostic("integrator", msg, "warning", values),)
    if k == 0:
        return ()
    msg = (f"integrator='auto' fits {describe_origin(k)} (integrator={spell_origin(k)}), "
           f"clearly better than the other choices ({table})")
    return (Diagnostic("integrator", msg, "info", values),)
