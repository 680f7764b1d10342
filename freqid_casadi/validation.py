"""Checks that a fitted model is resolved by its data, and a safeguard (layer L4).

A least-squares fit of noisy data can spend sections on near-cancelling pole/zero pairs
whose half-power bandwidth is far narrower than the spacing of the data (damping ratios
``zeta ~ 1e-7`` were measured on example A with 2 % noise). Such a pair bends the response
by up to a factor ``zeta_num / zeta_den`` in a band that falls between two samples: it
lowers the error *at* the samples and is wrong *between* them. This module

- flags such sections (:func:`check_resolution`),
- removes them and refits the remaining parameters on the data (:func:`prune_sections`),
- and combines both with :func:`~freqid_casadi.fit.fit` (:func:`fit_validated`),

so the package never returns such a model silently: the flags are in the result and a
``logging`` warning names them.

Definitions (SPEC §1 sections ``(a s^2 + 2 zn wn s + wn^2) / (b s^2 + 2 zd wd s + wd^2)``):
a quadratic ``a s^2 + 2 zeta w s + w^2`` has the natural frequency ``w0 = w / sqrt(a)``,
the damping ratio ``zeta0 = zeta / sqrt(a)`` and the half-power bandwidth ``2 zeta0 w0 =
2 zeta w / a`` (rad/s). It is *resolved* by a grid ``omega`` if that bandwidth is at least
the local spacing ``delta omega`` of the grid at ``w0`` (the width of the grid interval that
contains ``w0``). A zero and a pole (of any sections) are *near-cancelling* when
``|w0_num - w0_den|`` is below the local spacing (or the smaller of the two
bandwidths). Features outside the data band are not flagged (the data says nothing there).
"""

import logging
import math
from dataclasses import dataclass

import numpy as np

from .data import FrequencyData
from .errors import DataError, OptionError
from .fit import FitResult, default_delay_max, fit
from .model import RationalDelayModel
from .objective import Parametrization, rel_error_stats, stage_functions
from .solvers.ipopt import solve_least_squares

__all__ = ["Quadratic", "PairFlag", "ResolutionCheck", "PruneResult", "ValidatedFit",
           "check_resolution", "prune_sections", "fit_validated", "dense_grid"]

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Quadratic:
    """One quadratic factor ``c2 s^2 + 2 zeta w s + w^2`` of a model (a pole or zero pair).

    Attributes
    ----------
    kind : {"zero", "pole"}
    section : int
        Zero-based index of its section (row of ``model.sections()``).
    omega : float
        Natural frequency ``w0 = w / sqrt(c2)``, rad/s.
    zeta : float
        Damping ratio ``zeta0 = zeta / sqrt(c2)``.
    bandwidth : float
        Half-power bandwidth ``2 zeta0 w0``, rad/s.
    spacing : float
        Local spacing of the data grid at ``omega``, rad/s (nan outside the data band).
    """

    kind: str
    section: int
    omega: float
    zeta: float
    bandwidth: float
    spacing: float

    def as_dict(self):
        return dict(self.__dict__)


@dataclass(frozen=True)
class PairFlag:
    """A near-cancelling zero/pole pair the data cannot resolve.

    Attributes
    ----------
    zero, pole : Quadratic
        The two factors (possibly of different sections); at least one is narrower than
        the spacing, and their natural frequencies differ by less than the larger of the
        two bandwidths and the spacing.
    """

    zero: Quadratic
    pole: Quadratic

    @property
    def sections(self):
        """Sections involved, sorted tuple of int."""
        return tuple(sorted({self.zero.section, self.pole.section}))

    def as_dict(self):
        return {"zero": self.zero.as_dict(), "pole": self.pole.as_dict()}

    def text(self):
        return (f"zero {self.zero.omega:.4g} rad/s zeta {self.zero.zeta:.2g} (section "
                f"{self.zero.section}) / pole {self.pole.omega:.4g} rad/s zeta "
                f"{self.pole.zeta:.2g} (section {self.pole.section}), spacing "
                f"{self.pole.spacing:.3g} rad/s")


@dataclass(frozen=True)
class ResolutionCheck:
    """Result of :func:`check_resolution`.

    Attributes
    ----------
    ok : bool
        True when no section is flagged.
    flags : tuple of PairFlag
        Near-cancelling zero/pole pairs of which the pole or the zero is narrower than the
        spacing: features between the samples that the data does not support.
    narrow : tuple of Quadratic
        Other poles or zeros narrower than the spacing, with no zero/pole nearby (a lightly
        damped true resonance or antiresonance, fixed by the samples on its skirts).
        Reported, not flagged unless also in ``unresolved``.
    n_sections : int
        Sections of the checked model.
    factor : float
        A quadratic counts as resolved when its bandwidth is >= ``factor`` x spacing.
    unresolved : tuple of Quadratic
        The members of ``narrow`` whose bandwidth is below ``severe`` x spacing (default
        1 %): their damping is not determined by the data at all (e.g. zeta ~ 1e-11, an
        undamped peak between two samples). They make ``ok`` False; pruning cannot remove
        them (they do not cancel), so refit with fewer sections or other weights.
    """

    ok: bool
    flags: tuple
    narrow: tuple
    n_sections: int
    factor: float
    unresolved: tuple = ()

    @property
    def flagged(self):
        """Sections holding a flagged pole or zero, sorted tuple of int."""
        return tuple(sorted({k for f in self.flags for k in f.sections}))

    def message(self):
        if self.ok:
            return f"the {self.n_sections} sections are resolved by the data"
        parts = []
        if self.flags:
            parts.append(f"{len(self.flags)} near-cancelling zero/pole pair(s) narrower than "
                         "the data spacing: " + "; ".join(f.text() for f in self.flags))
        if self.unresolved:
            parts.append(f"{len(self.unresolved)} pole(s)/zero(s) over 100x narrower than the "
                         "spacing: " + "; ".join(
                             f"{q.kind} {q.omega:.4g} rad/s zeta {q.zeta:.2g} (section "
                             f"{q.section})" for q in self.unresolved))
        return "; ".join(parts)


@dataclass(frozen=True, eq=False)
class PruneResult:
    """Result of :func:`prune_sections`.

    Attributes
    ----------
    model : RationalDelayModel
        The model after removing the flagged sections (and refitting, if ``refit``).
    original : RationalDelayModel
        The model before.
    removed : tuple of PairFlag
        The removed zero/pole pairs, over all rounds (sections indexed in the model of
        their round).
    flags : tuple of PairFlag
        The flags of ``original`` (what was found).
    check : ResolutionCheck
        The check of the returned ``model``.
    n_rounds : int
        Remove-and-refit rounds done (a refit may narrow another section, which is then
        removed in the next round).
    refit_success : bool or None
        Whether the last refit converged (None without refit or when nothing was removed).
    max_rel_error_before, rms_rel_error_before : float
        Relative error against the data at the samples, before.
    max_rel_error_after, rms_rel_error_after : float
        The same, after.
    max_dense_error_before, rms_dense_error_before : float or None
        Relative error against ``reference`` on the dense grid, before (None without
        ``reference``).
    max_dense_error_after, rms_dense_error_after : float or None
        The same, after.
    max_dense_change : float
        ``max |G_after / G_before - 1|`` on the dense grid: how much the safeguard changed
        the model between the samples.
    n_dense : int
        Points of the dense grid.
    """

    model: RationalDelayModel
    original: RationalDelayModel
    removed: tuple
    flags: tuple
    check: ResolutionCheck
    n_rounds: int
    refit_success: object
    max_rel_error_before: float
    rms_rel_error_before: float
    max_rel_error_after: float
    rms_rel_error_after: float
    max_dense_error_before: object
    rms_dense_error_before: object
    max_dense_error_after: object
    rms_dense_error_after: object
    max_dense_change: float
    n_dense: int

    def as_dict(self):
        """JSON-ready dict of every number (models as ``to_dict``)."""
        d = {k: v for k, v in self.__dict__.items()
             if k not in ("model", "original", "flags", "check")}
        d["removed"] = [f.as_dict() for f in self.removed]
        d["flags"] = [f.as_dict() for f in self.flags]
        d["flags_after"] = [f.as_dict() for f in self.check.flags]
        d["unresolved_after"] = [q.as_dict() for q in self.check.unresolved]
        d["resolved_after"] = self.check.ok
        d["n_sections_before"] = self.original.n_sections
        d["n_sections_after"] = self.model.n_sections
        return d


@dataclass(frozen=True, eq=False)
class ValidatedFit:
    """Result of :func:`fit_validated`.

    Attributes
    ----------
    model : RationalDelayModel
        The model to use: ``fit.model`` if it passed the check, else ``pruning.model``.
    fit : FitResult
        The plain fit.
    check : ResolutionCheck
        The check of ``fit.model``.
    pruning : PruneResult or None
        What the safeguard did (None when the plain fit passed).
    """

    model: RationalDelayModel
    fit: FitResult
    check: ResolutionCheck
    pruning: object

    @property
    def pruned(self):
        return self.pruning is not None and bool(self.pruning.removed)


# ----------------------------------------------------------------------------- helpers


def dense_grid(omega, factor=10):
    """A log-spaced grid with ``factor`` x as many points over the range of ``omega``.

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        rad/s, > 0, increasing.
    factor : int
        >= 1.

    Returns
    -------
    ndarray of float, shape (factor * M,)
    """
    omega = _omega(omega)
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
        raise OptionError(f"factor must be an integer >= 1, got {factor!r}")
    return np.logspace(math.log10(omega[0]), math.log10(omega[-1]), int(factor) * omega.size)


def _omega(omega):
    if isinstance(omega, FrequencyData):
        return omega.omega
    w = np.asarray(omega, float).reshape(-1)
    if w.size < 2 or not np.all(np.isfinite(w)) or np.any(w <= 0) or np.any(np.diff(w) <= 0):
        raise DataError("omega must hold >= 2 finite frequencies > 0 (rad/s), strictly "
                        "increasing; use FrequencyData.sorted()")
    return w


def _quadratic(c2, zeta, w):
    """(w0, zeta0, bandwidth) of ``c2 s^2 + 2 zeta w s + w^2``; a first-order or constant
    factor (c2 = 0) has no resonance: (inf, inf, inf)."""
    if c2 <= 0 or w <= 0:
        return math.inf, math.inf, math.inf
    sa = math.sqrt(c2)
    return w / sa, zeta / sa, 2.0 * zeta * w / c2


def _local_spacing(omega, w0):
    """Width of the grid interval holding w0 (nan outside the data band)."""
    if not (omega[0] <= w0 <= omega[-1]):
        return math.nan
    i = int(np.clip(np.searchsorted(omega, w0) - 1, 0, omega.size - 2))
    return float(omega[i + 1] - omega[i])


# ----------------------------------------------------------------------------- check


def check_resolution(model, omega, *, factor=1.0, severe=1e-2):
    """Flag sections whose poles or zeros are narrower than the data spacing.

    Parameters
    ----------
    model : RationalDelayModel or FitResult
    omega : array_like of float, shape (M,) or FrequencyData
        The data frequencies (rad/s) the model was fitted to.
    factor : float
        A quadratic is resolved when its half-power bandwidth ``2 zeta0 w0`` is at least
        ``factor`` times the local spacing (default 1).
    severe : float
        A pole or zero (not in a flagged pair) narrower than ``severe`` x spacing is
        ``unresolved`` and fails the check (default 0.01).

    Returns
    -------
    ResolutionCheck

    Raises
    ------
    DataError
        Bad ``omega``.
    OptionError
        Bad ``factor`` or a model that is not a second-order-basis RationalDelayModel.

    Notes
    -----
    See the module docstring. A zero and a pole (of any sections, both inside the data
    band) are flagged as a pair if one of them has a bandwidth below ``factor`` x spacing
    and their natural frequencies differ by less than the larger of ``factor`` x spacing
    and the smaller of the two bandwidths; pairs are matched greedily, closest first, each
    factor used once. A narrow pole or zero that is not part of such a pair goes to ``narrow``: a
    lightly damped true resonance can be narrower than a coarse grid (example A on the
    thesis's grid: zeta 0.008 at 15 rad/s, bandwidth 0.24 rad/s, spacing 0.52 rad/s) and is
    still fixed by the samples around it.
    """
    model = _model_of(model)
    omega = _omega(omega)
    if isinstance(factor, bool) or not isinstance(factor, (int, float)) \
            or not math.isfinite(factor) or factor <= 0:
        raise OptionError(f"factor must be a finite number > 0, got {factor!r}")
    quads = []
    for k, (a, zn, wn, b, zd, wd) in enumerate(model.sections()):
        for kind, c2, zeta, w in (("zero", a, zn, wn), ("pole", b, zd, wd)):
            w0, z0, bw = _quadratic(c2, zeta, w)
            quads.append(Quadratic(kind, k, w0, z0, bw, _local_spacing(omega, w0)))
    inband = [q for q in quads if math.isfinite(q.spacing)]
    narrow = {id(q) for q in inband if q.bandwidth < factor * q.spacing}
    candidates = []
    for z in (q for q in inband if q.kind == "zero"):
        for p in (q for q in inband if q.kind == "pole"):
            if id(z) not in narrow and id(p) not in narrow:
                continue
            dist = abs(z.omega - p.omega)
            if dist < max(min(z.bandwidth, p.bandwidth), factor * max(z.spacing, p.spacing)):
                candidates.append((dist / max(z.spacing, p.spacing), z, p))
    flags, used = [], set()
    for _, z, p in sorted(candidates, key=lambda c: c[0]):
        if id(z) in used or id(p) in used:
            continue
        used |= {id(z), id(p)}
        flags.append(PairFlag(z, p))
    flags.sort(key=lambda f: f.pole.omega)
    narrow = [q for q in inband if id(q) in narrow and id(q) not in used]
    unresolved = tuple(q for q in narrow if q.bandwidth < severe * q.spacing)
    return ResolutionCheck(not flags and not unresolved, tuple(flags), tuple(narrow),
                           model.n_sections, float(factor), unresolved)


def _model_of(obj):
    if isinstance(obj, FitResult) or (hasattr(obj, "model") and hasattr(obj, "data")):
        obj = obj.model
    if not isinstance(obj, RationalDelayModel):
        raise OptionError(f"expected a RationalDelayModel or FitResult, got {type(obj).__name__}")
    if obj.structure.basis != "second-order":
        raise OptionError("check_resolution needs the second-order basis (first-order "
                          "sections have real roots, which are never narrow)")
    return obj


# ----------------------------------------------------------------------------- prune


def _remove(model, pairs):
    """The model without the zero and pole factors of ``pairs`` (PairFlag). The product
    of the remaining factors does not depend on how they are grouped into sections, so the
    remaining zeros and poles are regrouped in their order; the gain absorbs the removed
    factors' DC value (wn/wd)^2, keeping the static gain."""
    secs = model.sections()
    nums = [tuple(r[:3]) for r in secs]
    dens = [tuple(r[3:]) for r in secs]
    drop_n = {f.zero.section for f in pairs}
    drop_d = {f.pole.section for f in pairs}
    gain = model.gain
    for k in drop_n:
        gain *= nums[k][2] ** 2
    for k in drop_d:
        gain /= dens[k][2] ** 2
    nums = [q for k, q in enumerate(nums) if k not in drop_n]
    dens = [q for k, q in enumerate(dens) if k not in drop_d]
    rows = [list(n) + list(d) for n, d in zip(nums, dens)]
    beta = np.concatenate([[model.delay, gain], np.array(rows, float).reshape(-1)])
    return RationalDelayModel(model.structure.with_sections(len(rows)), beta)


def _refit(model, data, weights, delay_max, max_iter):
    """Refit all parameters of ``model`` on all of ``data`` from ``model`` (IPOPT, dc
    gauge, as fit()'s final stage). Returns (model, success)."""
    secs = model.sections()
    refs = tuple(float(wd / math.sqrt(b)) if b > 0 else float(wd) for *_, b, _, wd in secs)
    param = Parametrization(model.structure, "dc", refs, model.gain, delay_max, True)
    z0 = param.from_beta(model.beta)
    lb, ub = param.bounds()
    z0 = np.clip(z0, lb, ub)
    funcs = stage_functions(param, data.omega, data.response, weights)
    res = solve_least_squares(funcs, z0, lb, ub, max_iter=max_iter)
    new = param.to_model(res.x)
    before = np.sum(_w(weights) * model.relative_error(data) ** 2)
    after = np.sum(_w(weights) * new.relative_error(data) ** 2)
    if not np.isfinite(after) or after > before:
        return model, bool(res.success)
    return new, bool(res.success)


def _w(weights):
    return 1.0 if weights is None else weights


def _stats(model, omega, response):
    return rel_error_stats(np.abs(response / model.frequency_response(omega) - 1.0))


def prune_sections(result_or_model, data=None, *, reference=None, factor=1.0, refit=True,
                   max_rounds=3, dense_factor=10, weights=None, max_iter=500):
    """Remove the sections the data cannot resolve and refit the rest.

    Parameters
    ----------
    result_or_model : FitResult or RationalDelayModel
    data : FrequencyData, optional
        The fitted data (default: the FitResult's).
    reference : callable, optional
        ``reference(omega) -> FrequencyData or complex ndarray``: the true system (e.g.
        :func:`freqid_casadi.systems.G_A`), to measure the error on the dense grid.
    factor : float
        Resolution factor of :func:`check_resolution`.
    refit : bool
        After removing, refit all remaining parameters on the data (IPOPT from the pruned
        model). A refit is kept only if it lowers the (weighted) cost.
    max_rounds : int
        Remove-and-refit rounds at most.
    dense_factor : int
        The dense grid has ``dense_factor`` x as many log-spaced points as the data.
    weights : array_like of float, shape (M,), optional
        Weights of the refit (default: ``data.weights``).
    max_iter : int
        IPOPT iteration limit of each refit.

    Returns
    -------
    PruneResult
        With nothing removed when the model passes the check.

    Raises
    ------
    DataError, OptionError
        Bad data or options.

    Notes
    -----
    Removing a near-cancelling narrow pair changes the response only within its bandwidth
    (a few samples at most), so the error at the samples hardly rises, while the error
    between samples (dense grid) falls. The zero and the pole are removed (the remaining
    factors regrouped into sections); the gain absorbs their DC value ``(wn/wd)^2``.
    """
    if isinstance(result_or_model, FitResult):
        original = result_or_model.model
        data = result_or_model.data if data is None else data
    else:
        original = _model_of(result_or_model)
    if not isinstance(data, FrequencyData):
        raise DataError("data must be the FrequencyData the model was fitted to")
    original = _model_of(original)
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, int) or max_rounds < 1:
        raise OptionError(f"max_rounds must be an integer >= 1, got {max_rounds!r}")
    w = data.weights if weights is None else np.asarray(weights, float)
    omega = data.omega
    dense = dense_grid(omega, dense_factor)
    delay_max = max(default_delay_max(omega), original.delay)

    first = check_resolution(original, omega, factor=factor)
    model, removed, rounds, success = original, [], 0, None
    check = first
    while check.flags and rounds < max_rounds and model.n_sections > len(check.flags):
        removed += list(check.flags)
        model = _remove(model, check.flags)
        rounds += 1
        if refit:
            model, success = _refit(model, data, w, delay_max, max_iter)
        check = check_resolution(model, omega, factor=factor)
    if not check.ok:
        _log.warning("after pruning: %s", check.message())

    mb, rb = _stats(original, omega, data.response)
    ma, ra = _stats(model, omega, data.response)
    dense_vals = [None] * 4
    if reference is not None:
        ref = reference(dense)
        ref = ref.response if isinstance(ref, FrequencyData) else np.asarray(ref, complex)
        dense_vals = [*_stats(original, dense, ref), *_stats(model, dense, ref)]
    change = float(np.max(np.abs(model.frequency_response(dense)
                                 / original.frequency_response(dense) - 1.0)))
    return PruneResult(model=model, original=original, removed=tuple(removed),
                       flags=first.flags, check=check, n_rounds=rounds,
                       refit_success=success, max_rel_error_before=mb,
                       rms_rel_error_before=rb, max_rel_error_after=ma,
                       rms_rel_error_after=ra, max_dense_error_before=dense_vals[0],
                       rms_dense_error_before=dense_vals[1],
                       max_dense_error_after=dense_vals[2],
                       rms_dense_error_after=dense_vals[3], max_dense_change=change,
                       n_dense=int(dense.size))


def fit_validated(data, *, n_sections, reference=None, factor=1.0, refit=True,
                  dense_factor=10, **fit_options):
    """:func:`~freqid_casadi.fit.fit`, then :func:`check_resolution` and, if a section is
    flagged, :func:`prune_sections`.

    Parameters
    ----------
    data : FrequencyData
    n_sections : int
    reference, factor, refit, dense_factor
        As in :func:`prune_sections`.
    **fit_options
        Passed to :func:`~freqid_casadi.fit.fit` (``integrator``, ``delay``, ``weights``...).

    Returns
    -------
    ValidatedFit
        Its ``model`` is resolved by the data unless pruning could not achieve it, in which
        case ``pruning.check.ok`` is False and a warning is logged.
    """
    result = fit(data, n_sections=n_sections, **fit_options)
    check = check_resolution(result.model, result.data.omega, factor=factor)
    if check.ok:
        return ValidatedFit(result.model, result, check, None)
    _log.warning("fit: %s; pruning", check.message())
    pruning = prune_sections(result, reference=reference, factor=factor, refit=refit,
                             dense_factor=dense_factor, weights=fit_options.get("weights"))
    return ValidatedFit(pruning.model, result, check, pruning)
