"""A safeguard against sections the data cannot resolve (layer L5).

:func:`~freqid_casadi.core.resolution.check_resolution` flags near-cancelling pole/zero pairs
narrower than the data spacing (definitions in :mod:`freqid_casadi.core.resolution`): features
between the samples that lower the error *at* the samples and are wrong *between* them.
This module

- removes them and refits the remaining parameters on the data (:func:`prune_sections`,
  the refit is :func:`~freqid_casadi.fitting.stages.polish`),
- and combines the check and the pruning with :func:`~freqid_casadi.fitting.fit.fit`
  (:func:`fit_validated`),

so the package never returns such a model silently: the flags are in the result and a
``logging`` warning names them. ``check_resolution`` and its types are re-exported here.
"""

import logging
from dataclasses import dataclass

import numpy as np

from ..core.data import FrequencyData, dense_grid
from ..errors import DataError, OptionError
from .fit import FitResult, fit
from ..core.metrics import relative_error
from ..core.model import RationalDelayModel
from ..options import IpoptOptions, ipopt_limits, warn_renamed
from ..core.resolution import (PairFlag, Quadratic, ResolutionCheck, model_of, check_resolution,
                         default_delay_max)
from .stages import polish

__all__ = ["PRUNE_METHOD", "Quadratic", "PairFlag", "ResolutionCheck", "PruneResult",
           "ValidatedFit",
           "check_resolution", "prune_sections", "fit_validated", "dense_grid"]
# Quadratic, PairFlag, ResolutionCheck, check_resolution: defined in freqid_casadi.core.resolution
# (below fit), dense_grid in freqid_casadi.core.data; re-exported here for callers of this module.

_log = logging.getLogger(__name__)


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


# ----------------------------------------------------------------------------- check


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


#: The IPOPT options of :func:`prune_sections`' refits by default (each refit is a final
#: all-data stage, :func:`~freqid_casadi.fitting.stages.polish`).
PRUNE_METHOD = IpoptOptions(final_max_iter=500)


def _refit(model, data, weights, delay_max, solver):
    """Refit all parameters of ``model`` on all of ``data`` from ``model`` (IPOPT, dc
    gauge, as fit()'s final stage: :func:`~freqid_casadi.fitting.stages.polish`). Returns
    (model, success)."""
    if weights is not None:
        data = data.with_weights(weights)
    pol = polish(model, data, method=solver, delay_max=delay_max)
    return pol.model, bool(pol.result.success)


def prune_sections(result_or_model, data=None, *, reference=None, factor=1.0, refit=True,
                   max_rounds=3, dense_factor=10, weights=None, method=None, max_iter=None):
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
    method : IpoptOptions, optional
        The refits' IPOPT options (each refit is a final all-data stage, so
        ``final_max_iter`` is its iteration limit); default :data:`PRUNE_METHOD`,
        ``IpoptOptions(final_max_iter=500)``.
    max_iter : int, optional
        Deprecated (FutureWarning): ``max_iter=k`` is
        ``method=IpoptOptions(final_max_iter=k)``.

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
        original = model_of(result_or_model)
    if not isinstance(data, FrequencyData):
        raise DataError("data must be the FrequencyData the model was fitted to")
    original = model_of(original)
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, int) or max_rounds < 1:
        raise OptionError(f"max_rounds must be an integer >= 1, got {max_rounds!r}; pass "
                          "e.g. max_rounds=3")
    solver = _prune_method(method, max_iter)
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
            model, success = _refit(model, data, w, delay_max, solver)
        check = check_resolution(model, omega, factor=factor)
    if not check.ok:
        _log.warning("after pruning: %s", check.message())

    before, after = relative_error(original, data), relative_error(model, data)
    dense_vals = [None] * 4
    if reference is not None:
        ref = reference(dense)
        ref = ref.response if isinstance(ref, FrequencyData) else np.asarray(ref, complex)
        b, a = relative_error(original, dense, ref), relative_error(model, dense, ref)
        dense_vals = [b.max, b.rms, a.max, a.rms]
    change = relative_error(original, dense, model.frequency_response(dense)).max
    return PruneResult(model=model, original=original, removed=tuple(removed),
                       flags=first.flags, check=check, n_rounds=rounds,
                       refit_success=success, max_rel_error_before=before.max,
                       rms_rel_error_before=before.rms, max_rel_error_after=after.max,
                       rms_rel_error_after=after.rms, max_dense_error_before=dense_vals[0],
                       rms_dense_error_before=dense_vals[1],
                       max_dense_error_after=dense_vals[2],
                       rms_dense_error_after=dense_vals[3], max_dense_change=change,
                       n_dense=int(dense.size))


def _prune_method(method, max_iter):
    """The refits' IpoptOptions from ``method`` or the old ``max_iter`` keyword."""
    if max_iter is None:
        return ipopt_limits("prune_sections", method, PRUNE_METHOD,
                            ("final_max_iter", "hessian", "ipopt", "ftol"))
    if method is not None:
        raise OptionError("max_iter and method both give the refits' iteration limit; drop "
                          "max_iter and pass method=IpoptOptions(final_max_iter=...) only")
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise OptionError(f"max_iter must be an integer >= 1, got {max_iter!r}; pass "
                          "method=IpoptOptions(final_max_iter=500) instead")
    warn_renamed("prune_sections", f"max_iter={max_iter!r}",
                 f"method=IpoptOptions(final_max_iter={max_iter})", 3)
    return IpoptOptions(final_max_iter=max_iter)


def fit_validated(data, *, n_sections, reference=None, factor=1.0, refit=True,
                  dense_factor=10, **fit_options):
    """:func:`~freqid_casadi.fitting.fit.fit`, then :func:`check_resolution` and, if a section is
    flagged, :func:`prune_sections`.

    Parameters
    ----------
    data : FrequencyData
    n_sections : int
    reference, factor, refit, dense_factor
        As in :func:`prune_sections`.
    **fit_options
        Passed to :func:`~freqid_casadi.fitting.fit.fit` (``integrator``, ``delay``,
        ``weights``...).

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
