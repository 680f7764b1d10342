"""Residual bootstrap of a fit's physical parameters, for comparison with the delta method
(layer L6: its global refit calls :func:`freqid_casadi.fit`, above :mod:`.covariance`).
"""

import numpy as np

from ..core import physical as _physical
from .._progress import channel, check_progress
from .._workers import local_map
from ..uncertainty.covariance import (covariance_inputs, covariance_record,
                                      parameter_uncertainty, residual_jacobian)
from ..core.data import FrequencyData
from ..errors import OptionError

__all__ = ["bootstrap"]


def _refit_fit(data, structure):
    """Default global refit: freqid_casadi.fit with the same structure, rational start,
    the least-squares delay itself (no hold of an undetermined delay at a lower order's:
    the bootstrap measures the spread of the estimate, and the hold would refit at
    ``n_sections - 1`` in every replicate), without the non-minimum-phase check (a
    diagnostic: the model is the same)."""
    from .fit import fit   # lazy: fit is imported by the package facade anyway
    from ._checks import without_phase_check
    from ..options import LoopOptions

    with without_phase_check():         # the model is kept, not the diagnostics
        return fit(data, n_sections=structure.n_sections, integrator=structure.integrator,
                   delay=structure.delay, basis=structure.basis, start="rational",
                   loop=LoopOptions(hold_delay=False)).model


def _replicate(b, seed, par, data, w, u, refit):
    """One bootstrap replicate: resampled residuals, refit; theta (P,) or NaN."""
    rng = np.random.default_rng([int(seed), int(b)])
    log_g, _ = _physical.log_response(par, par.theta, data.omega)
    g = np.exp(log_g)
    pos = np.flatnonzero(w > 0)
    r_star = np.zeros(data.n_points, dtype=complex)
    r_star[pos] = u[rng.integers(0, pos.size, pos.size)] / np.sqrt(w[pos])
    phi = g * (1 + r_star)
    if refit is None:
        theta, ok = _physical.polish(par, data.omega, phi, w)
        return theta if ok else np.full(par.n_params, np.nan)
    star = FrequencyData(data.omega, phi, data.name, w)
    try:
        model = refit(star) if callable(refit) else _refit_fit(star, par.structure)
    except Exception:   # noqa: BLE001 -- a failed refit is counted, not fatal
        return np.full(par.n_params, np.nan)
    model = getattr(model, "model", model)
    theta = _physical.align(par, model)
    return np.full(par.n_params, np.nan) if theta is None else theta


def _replicate_line(row):
    """One line of text for a finished replicate (``progress="lines"``)."""
    row = np.asarray(row, dtype=float)
    return ("refit failed" if not np.all(np.isfinite(row)) else
            f"refit done: {row.size} parameters")


def bootstrap(model, data=None, *, n_boot=200, seed=0, n_jobs=1, refit=None, weights=None,
              bound_tol=1e-8, progress=False):
    """Residual bootstrap of a fitted model's physical parameters.

    Each replicate adds the standardised weighted residuals, resampled with replacement,
    to the model's response (``Phi* = G_N (1 + u*_i / sqrt(w_i))``) and refits;
    the record's covariance is the empirical covariance of the refitted parameters.

    Parameters
    ----------
    model : RationalDelayModel or FitResult
    data : FrequencyData or FrfEstimate, optional
        The data of the fit (required with a bare model).
    n_boot : int
        Number of replicates (>= 2).
    seed : int
        Replicate b draws from ``numpy.random.default_rng([seed, b])``: the result does not
        depend on ``n_jobs``.
    n_jobs : int
        Worker processes (1: in this process; -1: all cores; -2: all but one, as joblib
        counts): forked on Linux when no other thread runs, else joblib's loky.
    refit : None, "fit" or callable
        None: a warm-started local refit of the same structure from the model (scipy
        ``least_squares`` in the physical parameters, analytic Jacobian, parameters at a
        bound fixed). "fit": :func:`freqid_casadi.fit` with the same structure and
        ``start="rational"`` (sections matched by frequency). A callable takes a
        FrequencyData and returns a RationalDelayModel or FitResult of the same structure.
    weights : array_like of float, shape (M,), optional
        As in :func:`parameter_uncertainty`.
    bound_tol : float

    progress : bool, "lines" or callable, optional
        True draws a bar on a terminal (elsewhere a line per 30 s of a long run), "lines"
        writes a line per replicate to stderr, a callable receives each replicate's
        parameter vector (ndarray, NaN where the refit failed).

    Returns
    -------
    ParameterUncertainty
        ``method="bootstrap"``, ``noise_source="bootstrap"``, ``samples`` the refitted
        parameters (NaN rows: failed or unmatched refits, left out of the covariance).

    Raises
    ------
    OptionError
        Bad ``n_boot``, ``n_jobs`` or ``refit``; fewer than 2 successful replicates.
    """
    if isinstance(n_boot, bool) or not isinstance(n_boot, (int, np.integer)) or n_boot < 2:
        raise OptionError(f"n_boot must be an integer >= 2, got {n_boot!r}")
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, (int, np.integer)) or n_jobs == 0:
        raise OptionError(f"n_jobs must be a nonzero integer (-1: all cores), got {n_jobs!r}")
    if not (refit is None or refit == "fit" or callable(refit)):
        raise OptionError(f"refit must be None, 'fit' or a callable, got {refit!r}")
    base = parameter_uncertainty(model, data, weights=weights, bound_tol=bound_tol)
    model, data, w, _, _, par = covariance_inputs(model, data, weights, None, bound_tol)
    r, _ = residual_jacobian(par, par.theta, data)
    pos = w > 0
    u = np.sqrt(w[pos]) * r[pos] * np.sqrt((2 * pos.sum()) / base.dof)
    progress = check_progress(progress, "each replicate's parameters")
    jobs = [(b, seed, par, data, w, u, refit) for b in range(n_boot)]
    rows = ((_replicate(*job) for job in jobs) if n_jobs == 1
            else local_map(_replicate, jobs, n_jobs))
    with channel(progress, _replicate_line, total=n_boot, unit="refit") as emit:
        rows = [emit(row) or row for row in rows]
    samples = np.array(rows)
    ok = np.all(np.isfinite(samples[:, ~par.at_bound]), axis=1)
    if ok.sum() < 2:
        raise OptionError(f"only {int(ok.sum())} of {n_boot} bootstrap refits succeeded; "
                          "check the refit or use refit=None")
    free = ~par.at_bound
    cov = np.atleast_2d(np.cov(samples[ok][:, free], rowvar=False))
    samples.setflags(write=False)
    return covariance_record(model, par, cov, free, base.sigma2, base.dof, base.condition_number,
                   "bootstrap", "bootstrap", samples)
