"""Automatic order: the smallest order whose residual is consistent with the noise (layer L5).

``fit(data, n_sections="auto")`` (or a range of orders, ``n_sections=range(1, 9)``) fits
N = 1, 2, ... sections (as :func:`~freqid_casadi.fitting.sweep.sweep` does, one whole fit
per order, with the call's other options) and stops at the smallest N whose model explains
the data:

1. **consistent with the noise**: the relative residual ``r_i = Phi_i / G_N(j w_i) - 1``
   (times ``sqrt(w_i)`` with weights) is no rougher than white noise would be -- its RMS is
   at most :data:`WHITE_RATIO` times its point-to-point roughness
   ``sqrt(mean |r_{i+1} - r_i|^2 / 2)``, which equals the RMS for white noise and is far
   below it when the residual has structure (a missed mode, a wrong delay), and within
   :data:`~freqid_casadi.fitting.verdict.CONSISTENT_RATIO` of the local noise level, as
   the fit's status requires (noise whose level varies over the band can dominate the
   roughness while the residual is smooth where the data are quiet) -- or the RMS is at
   the rounding level (:data:`EXACT_RMS`, exact data);
2. **not bettered by one more section**: N + 1 sections lower the RMS by less than
   :func:`significant` (a share that shrinks with the number of points, as fitting noise
   with 6 more parameters would) and not significantly by the nested-model F-test
   (:func:`beats_noise`: the residual being noise, the fall of its sum of squares per
   added parameter against the rest, at level :data:`ORDER_ALPHA`, with a fall of at
   least :data:`MIN_FALL`);
3. **its modes are stable**: every pole of N inside the band has a pole of N + 1 within
   :data:`MODE_TOLERANCE` (relative).

Without a consistent order it stops after :data:`PATIENCE` orders in a row that do not
lower the RMS significantly, but not before as many sections as the data show resonance
peaks (:func:`resonance_count`: with fifteen modes, one more section lowers the RMS by a few
per cent, below the significance floor, until the last modes are fitted) (for a structured residual the share fitting noise could take
shrinks with the noise's share of its mean square, :func:`noise_share`;
``"no-improvement"``: the model class, not the order, limits the fit; the smallest of the
best orders is kept; orders no better than the trivial model, RMS >= ``TRIVIAL_RMS``, do
not count) or at ``max_sections``. When the minimum-phase search ends without a consistent
order, :func:`with_free_zeros` runs it with ``zeros="free"`` and offers that model. The
result's
diagnostics carry an ``order-chosen`` record with the reason, every order's RMS and
roughness ratio.

Data outside the class: when an order's minimum-phase fit is not consistent with the noise
but the ``zeros="free"`` model that fit offers (``FitResult.alternatives``, computed when
its ``non-minimum-phase`` check fires) reaches at most :data:`FREE_ZEROS_GAIN` times its
RMS, the rule reads that order's residual and poles from the offered model
(:func:`explaining_step`). The search then stops at the smallest order whose offered model
explains the data (reason ``"free-zeros"``: the result is that order's minimum-phase fit,
its ``alternatives["zeros=free"]`` the model to use) instead of adding minimum-phase
sections that imitate right-half-plane zeros up to ``max_sections``.

This module takes the fit as a callable (``fit_one(n) -> FitResult``), so the pipeline
(:mod:`freqid_casadi.fitting.fit`) dispatches to it without an import cycle.
"""

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..core.objective import relative_residual
from ..errors import DataError, FreqidError, OptionError, StructureError
from .diagnostics import TRIVIAL_RMS, Diagnostic
from .verdict import CONSISTENT_RATIO, residual_noise, with_cause

__all__ = ["OrderStep", "OrderChoice", "choose_order", "decide", "with_order_record",
           "explaining_step", "fit_step",
           "whiteness", "significant", "beats_noise", "noise_share", "with_free_zeros",
           "WHITE_RATIO", "EXACT_RMS", "MODE_TOLERANCE", "PATIENCE", "MAX_SECTIONS",
           "FREE_ZEROS_GAIN", "ORDER_ALPHA", "MIN_FALL", "resonance_count",
           "PEAK_PROMINENCE_DB", "PEAK_NOISE"]

#: RMS / roughness of a residual consistent with white noise (1 for white noise; the
#: estimate scatters by about 1/sqrt(M)).
WHITE_RATIO = 1.3
#: RMS relative error at or below which the data are explained exactly.
EXACT_RMS = 1e-8
#: Relative distance within which a pole of N sections is "the same" pole at N + 1.
MODE_TOLERANCE = 0.05
#: Orders in a row without a significant improvement after which the search stops.
PATIENCE = 2
#: The largest order ``n_sections="auto"`` tries.
MAX_SECTIONS = 16
#: Level of the F-test (:func:`beats_noise`) by which one more section betters an order
#: whose residual is consistent with the noise. Measured (``python scripts/corpus_order.py``,
#: 128 noisy corpus cases): without it, 7 searches stopped one mode short with that mode
#: lowering the RMS by 3-19 % on 51-120 points (the 12 / M share asks 10-24 %), 4 of which
#: the test keeps; 3 searches then end at the true order + 1 instead of the true order.
ORDER_ALPHA = 0.01
#: The least RMS fall the F-test counts: on thousands of points it alone would keep a
#: section for a fall of 0.3 %, which a small systematic error of real data gives.
MIN_FALL = 0.03
#: Least prominence of a resonance peak of ``|G|`` that :func:`resonance_count` counts, dB.
PEAK_PROMINENCE_DB = 6.0
#: ... and in multiples of the noise of ``log |G|`` (its point-to-point spread): a measured
#: FRF's heavy-tailed noise (an electro-mechanical positioning system's published FRF, 1024
#: points) gave local maxima up to 15 of these above their surroundings without the running
#: median, 5 peaks where it has no resonance (none with the median, at 10 or 20 of these).
PEAK_NOISE = 20.0
#: A minimum-phase order search that found no consistent order offers the free-zeros one
#: when that reaches at most this fraction of its RMS (as fit's ``non-minimum-phase``
#: diagnostic: ``check_minimum_phase``'s ratio).
FREE_ZEROS_GAIN = 0.5


@dataclass(frozen=True)
class OrderStep:
    """One order tried.

    Attributes
    ----------
    n_sections : int
    rms : float
        RMS relative error (weighted when the data have weights).
    ratio : float
        RMS / point-to-point roughness of the residual (about 1: white).
    success : bool
    n_params : int
        Real parameters the data determine: the gain, the delay, and one per pole and per
        zero (4 per second-order section, 2 per first-order one; the unit-DC gauge fixes
        the rest of ``Structure.n_params``). 0: unknown, taken as ``2 + 4 n_sections``.
    free : bool
        The numbers are those of the order's ``zeros="free"`` alternative, the model that
        explains the data better (:func:`explaining_step`).
    local_ratio : float
        RMS over the local noise level, the fit's status check
        (:func:`~freqid_casadi.fitting.verdict.residual_noise`); 0 when not measured.
    """

    n_sections: int
    rms: float
    ratio: float
    success: bool
    n_params: int = 0
    free: bool = False
    local_ratio: float = 0.0


@dataclass(frozen=True, eq=False)
class OrderChoice:
    """The chosen order.

    Attributes
    ----------
    result : FitResult
        The fit at the chosen order.
    n_sections : int
    reason : {"consistent", "free-zeros", "no-improvement", "max-sections", "data-limit"}
        ``"free-zeros"``: the order's minimum-phase fit is not consistent with the noise,
        its ``zeros="free"`` alternative is.
    steps : tuple of OrderStep
        Every order tried, in order.
    message : str
        One sentence: the order, why, and the numbers.
    peaks : int
        Resonance peaks of the data (:func:`resonance_count`), below which the search did
        not stop for want of improvement.
    """

    result: object
    n_sections: int
    reason: str
    steps: tuple
    message: str
    peaks: int = 0


def whiteness(residual, weights=None):
    """RMS of a residual and its ratio to the point-to-point roughness.

    Parameters
    ----------
    residual : ndarray of complex, shape (M,)
        Relative residual by increasing frequency.
    weights : ndarray of float, shape (M,), optional
        Only their ratios matter; points of weight 0 are left out.

    Returns
    -------
    (float, float)
        ``(rms, rms / sqrt(mean |diff|^2 / 2))``; the ratio is about 1 for white noise,
        large for a smooth (structured) residual, inf for a constant one.
    """
    r = np.asarray(residual, complex)
    if weights is not None:
        w = np.asarray(weights, float)
        r = r[w > 0] * np.sqrt(w[w > 0] / np.mean(w[w > 0]))
    rms = float(np.sqrt(np.mean(np.abs(r) ** 2)))
    rough = float(np.sqrt(np.mean(np.abs(np.diff(r)) ** 2) / 2)) if r.size > 1 else 0.0
    return rms, (rms / rough if rough > 0 else (math.inf if rms > 0 else 1.0))


def significant(rms_before, rms_after, n_points, share=1.0):
    """Whether one more section lowered the RMS by more than fitting noise would.

    Six more parameters fitted to white noise lower the RMS by about 3/M; an improvement
    counts when the RMS falls below ``rms_before * (1 - max(0.1, 12 / M * share))``.
    ``share`` is the share of the mean square that is noise, ``(sigma / RMS)^2``: 1
    for a residual consistent with the noise; for a structured one, fitting noise lowers
    its RMS by only that share of 3/M (:func:`noise_share`), and the 0.1 floor remains.

    Parameters
    ----------
    rms_before, rms_after : float
        RMS relative error at N and N + 1 sections.
    n_points : int
        M.
    share : float
        In (0, 1].

    Returns
    -------
    bool
    """
    return rms_after < rms_before * (1 - max(0.1, 12.0 / n_points * share))


def beats_noise(before, after, n_points, alpha=ORDER_ALPHA, min_fall=MIN_FALL):
    """Whether one more section lowered a residual that is noise by more than chance.

    The nested-model F-test on the ``2 M`` real residuals: with ``p`` parameters after and
    ``q`` more than before, ``F = ((rms_before / rms_after)^2 - 1) (2 M - p) / q`` against
    the upper ``alpha`` quantile of F(q, 2 M - p); the RMS must also fall by at least
    ``min_fall``. (A section placed where the noise helps most is a search over the band,
    so the test is somewhat lenient: on the corpus it kept one more section than the true
    order in 3 of about 110 searches.)

    Parameters
    ----------
    before, after : OrderStep
        N and N + 1 sections.
    n_points : int
        M (complex points).
    alpha : float
        Level of the test, in (0, 1); 0 never counts.
    min_fall : float
        Least relative RMS fall.

    Returns
    -------
    bool
    """
    from scipy.special import fdtri

    p_before = before.n_params or _determined(before.n_sections)
    p_after = after.n_params or _determined(after.n_sections)
    q, dof = p_after - p_before, 2 * int(n_points) - p_after
    if not (alpha > 0 and q > 0 and dof > 0 and 0 < after.rms < before.rms * (1 - min_fall)):
        return False
    f = ((before.rms / after.rms) ** 2 - 1) * dof / q
    return bool(f > fdtri(q, dof, 1 - alpha))


def noise_share(step):
    """``(sigma / RMS)^2`` of an order's residual: 1 when it is consistent with the noise,
    else ``1 / ratio^2`` (the point-to-point roughness estimates sigma).

    Measured (``python scripts/corpus_order.py``): with the share 1 throughout, a search
    on 63 points needs a 19 % fall per order, which three sections missing one of four
    modes each at RMS 0.69 / 0.61 / 0.58 (x4.7 / x3.4 / x9 their roughness) do not give,
    and stopped at 1 section of 4 (negative-gain-148; 4 sections reach 0.013).

    Parameters
    ----------
    step : OrderStep
        One order's residual numbers (``rms``, ``ratio``).

    Returns
    -------
    float
        In (0, 1].
    """
    if _consistent(step) or not math.isfinite(step.ratio) or step.ratio <= 0:
        return 1.0
    return min(1.0, 1.0 / step.ratio ** 2)


def resonance_count(omega, response, weights=None):
    """Resonance peaks the data show: local maxima of ``log |G|`` over frequency, after a
    running median of 3 points (a single outlying point makes no peak), whose prominence is
    at least :data:`PEAK_PROMINENCE_DB` and :data:`PEAK_NOISE` times the noise of ``log
    |G|`` (from the median absolute second difference, as white noise would give it). Each
    needs a lightly damped pole pair, one section; close modes that merge into one peak,
    heavily damped ones and those the noise hides are not counted, so the count is a lower
    bound on the sections the data need (measured on 300 corpus cases: at most the true
    sections in 297, one more in 3).

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        Frequencies by increasing value (their unit does not matter).
    response : ndarray of complex, shape (M,)
    weights : ndarray of float, shape (M,), optional
        Points of weight 0 are left out.

    Returns
    -------
    int
    """
    from scipy.signal import find_peaks

    g = np.asarray(response, complex)
    keep = np.isfinite(g) & (np.abs(g) > 0)
    if weights is not None:
        keep &= np.asarray(weights, float) > 0
    y = np.log(np.abs(g[keep]))
    if y.size < 5:
        return 0
    noise = float(np.median(np.abs(np.diff(y, 2)))) / 0.6745 / math.sqrt(6.0)
    least = max(PEAK_PROMINENCE_DB / 20 * math.log(10), PEAK_NOISE * noise)
    smooth = y.copy()
    smooth[1:-1] = np.median(np.stack([y[:-2], y[1:-1], y[2:]]), axis=0)
    return int(find_peaks(smooth, prominence=least)[0].size)


def explaining_step(step, free=None):
    """The step the order rule reads for one order: ``step`` (the minimum-phase fit), or
    ``free`` (its ``zeros="free"`` alternative) when ``step`` is not consistent with the
    noise and ``free`` reaches at most :data:`FREE_ZEROS_GAIN` times its RMS.

    Parameters
    ----------
    step : OrderStep
        The order's fit.
    free : OrderStep, optional
        The fit's ``zeros="free"`` alternative, when it offers one.

    Returns
    -------
    OrderStep
        ``step``, or ``free`` with ``free=True``.
    """
    if free is None or _consistent(step) or not free.rms <= FREE_ZEROS_GAIN * step.rms:
        return step
    return dataclasses.replace(free, free=True)


def fit_step(res):
    """The :class:`OrderStep` of one fit: its relative residual's RMS and roughness ratio
    (:func:`whiteness`, with the data's weights), ``success`` and the parameters the data
    determine.

    Parameters
    ----------
    res : FitResult

    Returns
    -------
    OrderStep
    """
    residual = relative_residual(res.model, res.data.omega, res.data.response)
    rms, ratio = whiteness(residual, res.data.weights)
    local = residual_noise(residual, res.data.omega, res.data.weights)["ratio"]
    s = res.model.structure
    return OrderStep(res.model.n_sections, rms, ratio, bool(res.success),
                     _determined(s.n_sections, s.basis, s.delay),
                     local_ratio=float(local) if math.isfinite(local) else 0.0)


def _step(res):
    """The order's :class:`OrderStep` (:func:`explaining_step` of the fit and its
    ``zeros="free"`` alternative) and the poles of the model it describes."""
    alt = getattr(res, "alternatives", {}).get("zeros=free")
    step = explaining_step(fit_step(res), None if alt is None else fit_step(alt))
    return step, (alt if step.free else res).model.poles()


def _determined(n_sections, basis="second-order", delay=True):
    """Real parameters the data determine: the gain, the delay, one per pole and zero."""
    per = 2 if basis == "second-order" else 1        # poles (and zeros) per section
    return 1 + int(bool(delay)) + 2 * per * int(n_sections)


def _consistent(step):
    """The order's residual is consistent with the noise: no rougher than white noise
    (:data:`WHITE_RATIO`) and, as the fit's status requires, within
    :data:`~freqid_casadi.fitting.verdict.CONSISTENT_RATIO` of the local noise level (a
    smooth residual where the data are quiet, beside a band whose noise dominates the
    roughness, is not), or exact."""
    return step.rms <= EXACT_RMS or (step.ratio <= WHITE_RATIO
                                     and not step.local_ratio > CONSISTENT_RATIO)


def _modes_stable(lower, higher, omega):
    """Largest relative distance from each in-band pole of ``lower`` to the nearest pole of
    ``higher`` (poles, ndarray of complex; 0 when ``lower`` has none in the band)."""
    p, q = np.asarray(lower, complex), np.asarray(higher, complex)
    p = p[(np.abs(p) >= omega[0]) & (np.abs(p) <= omega[-1])]
    if p.size == 0 or q.size == 0:
        return 0.0 if p.size == 0 else math.inf
    return float(max(np.min(np.abs(q - x)) / abs(x) for x in p))


def _stale(steps, n_points, share=noise_share):
    """Orders in a row, at the end of ``steps``, that did not lower the RMS significantly;
    an order no better than the trivial model explains nothing yet and does not count
    (six lightly damped modes leave 1..5 sections near RMS 1, measured on pyuff's impact
    accelerances, then 6 reach 0.05)."""
    stale = 0
    for prev, cur in zip(steps, steps[1:]):
        better = significant(prev.rms, cur.rms, n_points, share(prev))
        stale = 0 if better or not cur.rms < TRIVIAL_RMS else stale + 1
    return stale


def _best(steps, n_points, share=noise_share):
    """Index of the smallest order whose RMS the best one does not significantly beat."""
    best = min(s.rms for s in steps)
    return next(i for i, s in enumerate(steps)
                if not significant(s.rms, best, n_points, share(s)))


def decide(steps, poles, omega, n_points, *, end=None, share=noise_share, alpha=ORDER_ALPHA,
           peaks=0):
    """The rule of :func:`choose_order` (module docstring), on the orders tried so far.

    Parameters
    ----------
    steps : list of OrderStep
        The orders tried, ``min_sections, min_sections + 1, ...``.
    poles : list of ndarray of complex
        The poles of each order's model, rad/s.
    omega : ndarray of float
        The band (only its first and last entries are used), rad/s.
    n_points : int
        M.
    end : {None, "max-sections", "data-limit"}
        None while the search may go on; else why it cannot.
    share : callable
        ``OrderStep -> float``, the noise share of :func:`significant` (default
        :func:`noise_share`; ``lambda step: 1.0`` is the rule before it).
    alpha : float
        Level of :func:`beats_noise` for an order consistent with the noise (0: that
        test off, the rule before it).
    peaks : int
        Resonance peaks of the data (:func:`resonance_count`): the search does not stop for
        want of improvement below that many sections (0: the rule before it).

    Returns
    -------
    (int, str) or None
        The index into ``steps`` of the chosen order and the reason, or None: try the next
        order.
    """
    if end is None:
        if len(steps) < 2:
            return None
        prev, cur = steps[-2], steps[-1]
        better = (significant(prev.rms, cur.rms, n_points, share(prev))
                  or _consistent(prev) and beats_noise(prev, cur, n_points, alpha))
        exact = cur.rms <= EXACT_RMS and prev.rms <= EXACT_RMS
        if _consistent(prev) and (not better or exact) and _modes_stable(
                poles[-2], poles[-1], omega) <= MODE_TOLERANCE:
            return len(steps) - 2, _explained(prev)
        if cur.n_sections >= peaks and _stale(steps, n_points, share) >= PATIENCE:
            return _best(steps, n_points, share), "no-improvement"
        return None
    if steps and _consistent(steps[-1]):
        return len(steps) - 1, _explained(steps[-1])
    return _best(steps, n_points, share), end


def _explained(step):
    return "free-zeros" if step.free else "consistent"


def choose_order(fit_one, *, max_sections=MAX_SECTIONS, min_sections=1):
    """Fit orders ``min_sections, ...`` with ``fit_one`` and choose one (module docstring;
    the rule is :func:`decide`). The warnings a fit issues concern its model: those of the
    order kept are issued again, the others' not at all.

    Parameters
    ----------
    fit_one : callable
        ``n_sections -> FitResult`` (its ``data.omega`` gives the band of the mode check).
    max_sections, min_sections : int

    Returns
    -------
    OrderChoice

    Raises
    ------
    OptionError
        Bad ``max_sections`` / ``min_sections``.
    StructureError
        ``min_sections`` already needs more parameters than the data have points.
    """
    for name, v in (("max_sections", max_sections), ("min_sections", min_sections)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise OptionError(f"{name} must be an integer >= 1, got {v!r}; e.g. "
                              f"max_sections={MAX_SECTIONS}")
    if min_sections > max_sections:
        raise OptionError(f"min_sections={min_sections} > max_sections={max_sections}: "
                          "raise max_sections")
    results, steps, poles, caught = [], [], [], []
    verdict, end = None, "max-sections"
    for n in range(int(min_sections), int(max_sections) + 1):
        try:
            with warnings.catch_warnings(record=True) as issued:
                warnings.simplefilter("always")
                res = fit_one(n)
        except (StructureError, DataError):     # more parameters than the data have points
            if not results:
                raise
            end = "data-limit"
            break
        caught.append(issued)
        if not results:
            data = res.data
            peaks = resonance_count(data.omega, data.response, data.weights)
        results.append(res)
        step, p = _step(res)
        steps.append(step)
        poles.append(p)
        verdict = decide(steps, poles, data.omega, data.omega.size, peaks=peaks)
        if verdict is not None:
            break
    if verdict is None:
        verdict = decide(steps, poles, data.omega, data.omega.size, end=end)
    for w in caught[verdict[0]]:     # an order's warnings concern its model: the kept one's
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return _choice(results, steps, poles, *verdict, data.omega, peaks)


#: The order rule's test, named where it fails: it is stricter than the fit's status check
#: (twice the local noise), so a fit whose status is "ok" may still fail it.
_NONE = ("no residual passes the order rule's noise test (RMS at most "
         f"{WHITE_RATIO:g} times its point-to-point roughness and {CONSISTENT_RATIO:g} times "
         "the local noise)")
_WHY = {
    "consistent": "the residual is consistent with the noise",
    "free-zeros": "the minimum-phase model's residual is not consistent with the noise, the "
                  "residual of its model with free zeros is (the data need right-half-plane "
                  "zeros: use FitResult.alternatives['zeros=free'], or pass zeros='free')",
    "no-improvement": _NONE + ", and more sections stopped lowering it (the model class, "
                      "not the order, limits this fit: see the other diagnostics)",
    "max-sections": _NONE + " up to max_sections (raise max_sections, or see the other "
                    "diagnostics)",
    "data-limit": _NONE + ", and more sections need more data points than there are",
}


def _choice(results, steps, poles, k, reason, omega, peaks=0):
    step = steps[k]
    weighted = getattr(getattr(results[0], "data", None), "weights", None) is not None
    rms = "weighted RMS" if weighted else "RMS"
    tried = ", ".join(f"{s.n_sections}: {rms} {s.rms:.3g}{'*' if s.free else ''} "
                      f"(x{s.ratio:.2g})" for s in steps)
    nxt, moved = "", None
    if k + 1 < len(steps):
        drop = 1 - steps[k + 1].rms / step.rms if step.rms > 0 else 0.0
        moved = _modes_stable(poles[k], poles[k + 1], omega)
        change = (f"lower the RMS by {100 * drop:.2g} %" if drop >= 0 else
                  f"do not lower the RMS (RMS {steps[k + 1].rms:.3g})")
        nxt = (f"; {steps[k + 1].n_sections} sections {change} "
               f"and move its in-band poles by at most {100 * moved:.2g} %")
    plural = "s" if step.n_sections != 1 else ""
    own = f"{rms} {step.rms:.3g}, {step.ratio:.3g} times its point-to-point roughness"
    if step.ratio <= WHITE_RATIO and not _consistent(step):
        own += (f", but {step.local_ratio:.3g} times the local noise level (the fit's "
                "status check)")
    if step.free:
        own = (f"with free zeros {own}; minimum phase RMS "
               f"{results[k].rms_rel_error:.3g}")
    why = _WHY[reason]
    if reason == "no-improvement" and _consistent(step):
        # (a BFU520 transistor's S21: "moves ... by more than 5 %" beside "by at most 0 %")
        why = ("the residual is consistent with the noise" + (
            f", but the next order moves its in-band poles by more than "
            f"{100 * MODE_TOLERANCE:.2g} %" if moved is not None and moved > MODE_TOLERANCE
            else "") + ", and more sections stopped lowering the RMS")
    elif reason == "no-improvement" and k + 1 < len(steps) and \
            steps[k + 1].rms > 1.02 * step.rms:
        # a larger model cannot end worse at its optimum: the next fit stopped short (a
        # published line's S21: 10 sections at RMS 0.081 after 9 at 0.057)
        why = (_NONE + f", and more sections stopped lowering it (but the fit at "
               f"{steps[k + 1].n_sections} sections ended above this one's RMS, which a "
               "larger model cannot do at its optimum: that fit stopped short, so the order "
               f"is not ruled out: fit n_sections={steps[k + 1].n_sections} on its own, "
               "with start='best')")
    message = (f"n_sections='auto' chose {step.n_sections} section{plural}: {why} "
               f"({own}){nxt}; "
               f"orders tried ({rms}, x roughness; * with free zeros) {tried}")
    top = steps[-1].n_sections
    if peaks > top and reason == "max-sections":
        message += (f"; the data show {peaks} resonance peaks, more than the {top} sections "
                    f"tried: pass n_sections=range(1, {peaks + 1}) (command line "
                    f"--max-sections {peaks}), or fit a narrower band")
    elif peaks > 1:
        message += (f"; the data show {peaks} resonance peaks (the search does not stop for "
                    "want of improvement before that many sections)")
    return OrderChoice(result=results[k], n_sections=step.n_sections, reason=reason,
                       steps=tuple(steps), message=message, peaks=int(peaks))


def with_order_record(choice):
    """``choice.result`` with an ``order-chosen`` diagnostic (severity "info") appended:
    the reason and every order's RMS and roughness ratio in its values (``free_zeros``:
    which of them are the order's ``zeros="free"`` alternative's).

    Parameters
    ----------
    choice : OrderChoice

    Returns
    -------
    FitResult
    """
    d = Diagnostic("order-chosen", choice.message, "info", {
        "n_sections": choice.n_sections, "reason": choice.reason,
        "orders": [s.n_sections for s in choice.steps],
        "rms": [s.rms for s in choice.steps], "ratio": [s.ratio for s in choice.steps],
        "local_ratio": [s.local_ratio for s in choice.steps],
        "free_zeros": [s.free for s in choice.steps], "resonance_peaks": choice.peaks})
    try:
        diagnostics, message = _not_the_order(choice)
        return dataclasses.replace(choice.result, diagnostics=diagnostics + (d,),
                                   message=message)
    except (TypeError, FreqidError):        # a result type without diagnostics
        return choice.result


def _not_the_order(choice):
    """The chosen fit's diagnostics and message, its ``poor-fit`` record's cause restated
    when that cause is the order but the search fitted more sections without a
    significant fall of the RMS (``pass n_sections=N+1`` would repeat it)."""
    res = choice.result
    diagnostics, message = tuple(res.diagnostics), res.message
    higher = [s for s in choice.steps if s.n_sections > choice.n_sections]
    poor = next((g for g in diagnostics if g.code == "poor-fit"
                 and g.values.get("cause") == "order"), None)
    if poor is None or not higher:
        return diagnostics, message
    best = min(higher, key=lambda s: s.rms)
    unit = getattr(res.data, "unit", "rad/s")
    weighted = getattr(res.data, "weights", None) is not None
    rms = "weighted RMS" if weighted else "RMS"
    noise = ("the data's weights may not follow it" if weighted else
             "the fit weighs every point alike; weights=, each point's inverse relative "
             "variance, weigh them by their noise")
    cause = (f"not the order: n_sections='auto' fitted up to "
             f"{higher[-1].n_sections} sections, which did not lower the {rms} significantly "
             f"({rms} {best.rms:.3g} at {best.n_sections}); "
             f"the residual is largest near omega = {poor.values['worst_omega']:.4g} {unit}, "
             f"a feature the model class does not fit, or noise whose level varies over the "
             f"band ({noise})")
    restated = with_cause(poor, "not-the-order", cause)
    diagnostics = tuple(restated if g is poor else g for g in diagnostics)
    return diagnostics, message.replace(poor.message, restated.message)


def with_free_zeros(choice, fit_free, *, max_sections, min_sections=1):
    """``with_order_record(choice)``, and when the minimum-phase search found no order
    consistent with the noise, the same search with ``zeros="free"`` as the alternative.

    Data that need right-half-plane zeros (a non-collocated accelerance) leave every
    minimum-phase order near the trivial model's RMS, so the search stops at its smallest
    order ("no-improvement"), where the per-fit ``non-minimum-phase`` check (a free-zeros
    fit of that same order) cannot see the modes the low order lacks (measured on pyuff's
    impact accelerances: 1 section chosen at RMS 0.999; at 8 sections the check offers
    zeros="free" at RMS 0.046). The free-zeros search is kept in
    ``alternatives["zeros=free"]``, and named in the message and a ``non-minimum-phase``
    diagnostic, when its RMS is at most :data:`FREE_ZEROS_GAIN` times the chosen one's;
    the result's own model stays minimum phase.

    Parameters
    ----------
    choice : OrderChoice
        The minimum-phase search.
    fit_free : callable
        ``n_sections -> FitResult`` with ``zeros="free"``.
    max_sections, min_sections : int
        The orders the search may try (as :func:`choose_order`).

    Returns
    -------
    FitResult
    """
    result = with_order_record(choice)
    if choice.reason in ("consistent", "free-zeros") \
            or "zeros=free" in getattr(result, "alternatives", {}):
        return result
    try:
        alt = with_order_record(choose_order(fit_free, max_sections=max_sections,
                                             min_sections=min_sections))
    except FreqidError:
        return result
    if not alt.rms_rel_error <= FREE_ZEROS_GAIN * result.rms_rel_error:
        return result
    n_alt = alt.model.n_sections
    text = (f"every minimum-phase order stays near RMS {result.rms_rel_error:.3g}; with free "
            f"zeros n_sections='auto' chose {n_alt} section{'s' if n_alt != 1 else ''} at "
            f"RMS {alt.rms_rel_error:.3g} (max {alt.max_rel_error:.3g}, status "
            f"{alt.status}) — pass zeros='free' (FitResult.alternatives['zeros=free'] holds "
            "that model)")
    diag = Diagnostic("non-minimum-phase", f"the data need right-half-plane zeros: {text}",
                      "warning", {"alternative_n_sections": int(n_alt),
                                  "alternative_rms_rel_error": float(alt.rms_rel_error),
                                  "alternative_max_rel_error": float(alt.max_rel_error),
                                  "rms_rel_error": float(result.rms_rel_error)})
    head = result.message.split(" — ")[0]
    message = (f"{head}; the data need right-half-plane zeros: zeros='free' reaches RMS "
               f"{alt.rms_rel_error:.3g} at {n_alt} section{'s' if n_alt != 1 else ''} — "
               "pass zeros='free' (FitResult.alternatives['zeros=free'])")
    try:
        return dataclasses.replace(
            result, message=message, diagnostics=tuple(result.diagnostics) + (diag,),
            alternatives=dict(result.alternatives, **{"zeros=free": alt}))
    except (TypeError, FreqidError):
        return result
