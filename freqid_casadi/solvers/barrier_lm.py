"""The thesis's stage solver: a log-barrier outer loop (SUMT) around Levenberg–Marquardt.

Layer L3, numpy/scipy only (STYLE §1.3: solvers are CasADi-free). The interface is scipy-like:
``barrier_lm(fun, jac, x0, lb=...)`` takes numpy callables for the real residual vector and
its Jacobian and returns a frozen :class:`~freqid_casadi.solvers.common.StageResult`.

The algorithm is SPEC §3 "Barrier-LM variant" (thesis §3.1.1–3.1.2 and Appendix A,
``cost_and_coeffs.m``):

* outer loop (SUMT, thesis §3.1.2): for ``t = 1/mu = t0, t0*t_factor, ...`` while
  ``t <= t_max`` (the MATLAB code: ``t_ = 1``, ``t_ = t_*mu1`` with ``mu1 = 20``, loop while
  ``1/t_ > 1e-12``), minimise the barrier objective

  .. math:: \\phi_t(x) = t\\,\\varepsilon(x) - \\sum_i \\log(x_i - lb_i),
            \\qquad \\varepsilon(x) = r(x)^T r(x),

  starting each solve at the previous solution;
* inner loop (thesis §3.1.1, after Lourakis/Nielsen): Levenberg–Marquardt on ``phi_t`` with
  the damping update ``sigma <- sigma*max(1/3, 1-(2 rho-1)^3), nu <- 2`` on success and
  ``sigma <- sigma*nu, nu <- 2 nu`` on failure.

The small kernels :func:`predicted_decrease`, :func:`gain_ratio` and :func:`update_damping`
are exported so the tests can check them on their own, as scipy ``_lsq/common.py`` does.
"""

import dataclasses
import math
import time

import numpy as np
from scipy import linalg

from .. import _interrupt
from ..errors import DataError, OptionError
from ..options import DAMPING_MODES, BarrierLMOptions
from .common import (Status, TERMINATION_MESSAGES, StageResult, check_start,
                     find_active_constraints, is_success)
from .lm_kernels import _ratio, gain_ratio, model_decrease, predicted_decrease, update_damping

__all__ = ["barrier_lm", "solve_stage_lm", "gain_ratio", "predicted_decrease",
           "model_decrease", "update_damping", "DAMPING_MODES"]

# DAMPING_MODES (from freqid_casadi.options): ``"thesis"`` is ``sigma*I`` with
# ``sigma0 = tau*max(diag(A))`` (thesis eq. 3.2, Step 5); ``"marquardt"`` is
# ``sigma*diag(A)`` with ``sigma0 = tau``.

# Inner-loop stop reasons (kept in ``extra["inner_stop"]``).
_GTOL, _XTOL, _FTOL, _MAXITER = "gtol", "xtol", "ftol", "max_iter"
_ERROR_JAC, _ERROR_FUN = "nonfinite_jacobian", "nonfinite_residuals"
_ERROR_MODEL = "nonfinite_model"      # A or g overflowed (x - lb underflowing, huge t*J^T J)
_ERRORS = (_ERROR_JAC, _ERROR_FUN, _ERROR_MODEL)


# --------------------------------------------------------------------------------------
# Validation (STYLE §7: at the entry point, before any work)
# --------------------------------------------------------------------------------------
def _check_options(fun, jac, callback, **options):
    """The options as a validated :class:`~freqid_casadi.options.BarrierLMOptions`."""
    for name, f in (("fun", fun), ("jac", jac)):
        if not callable(f):
            raise OptionError(f"{name} must be callable, got {type(f).__name__}")
    if callback is not None and not callable(callback):
        raise OptionError(f"callback must be callable or None, got {type(callback).__name__}")
    return BarrierLMOptions(**options)


def _eval_fun(fun, x, m=None):
    r = np.asarray(fun(x))
    if np.iscomplexobj(r):
        raise DataError("fun(x) returned complex values; stack the complex residuals as "
                        "real [Re; Im] (shape (2L,))")
    r = np.asarray(r, dtype=float)
    if r.ndim != 1 or (m is not None and r.shape != (m,)):
        want = "(m,)" if m is None else f"({m},)"
        raise DataError(f"fun(x) must return a 1-D residual vector of shape {want}, got "
                        f"shape {r.shape}")
    return r


def _eval_jac(jac, x, m, n):
    J = np.asarray(jac(x))
    if np.iscomplexobj(J):
        raise DataError("jac(x) returned complex values; stack the real and imaginary "
                        "parts as rows [Re J; Im J] (shape (2L, n))")
    J = np.asarray(J, dtype=float)
    if J.shape != (m, n):
        raise DataError(f"jac(x) must return shape (m, n) = ({m}, {n}) to match fun(x) "
                        f"and x0, got {J.shape}")
    return J


# --------------------------------------------------------------------------------------
# Inner loop
# --------------------------------------------------------------------------------------
def _model(J, r, x, lb, fin, t):
    """Gradient and Hessian approximation of phi_t (see Notes of :func:`barrier_lm`)."""
    d = x[fin] - lb[fin]
    idx = np.flatnonzero(fin)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        A = (2.0 * t) * (J.T @ J)
        g = (2.0 * t) * (J.T @ r)
        A[idx, idx] += 1.0 / d**2
        g[idx] -= 1.0 / d
    return A, g


def _finite_model(A, g):
    return bool(np.all(np.isfinite(A)) and np.all(np.isfinite(g)))


def _solve(A, D_diag, g):
    """Solve (A + diag(D)) delta = -g; Cholesky, falling back to lstsq (thesis: pinv)."""
    M = A.copy()
    M[np.diag_indices_from(M)] += D_diag
    try:
        c = linalg.cho_factor(M, check_finite=False)
        delta = linalg.cho_solve(c, -g, check_finite=False)
    except linalg.LinAlgError:
        delta = linalg.lstsq(M, -g, check_finite=False)[0]
    return delta


def _stalled(n_finite_trials, n_nonfinite_trials):
    """Reason for a vanishing step: residuals non-finite at every trial point, or xtol."""
    if n_nonfinite_trials > 0 and n_finite_trials == 0:
        return _ERROR_FUN
    return _XTOL


def _inner_lm(fun, jac, x, r, J, lb, fin, t, opts, counts):
    """LM on phi_t from the strictly feasible x (thesis §3.1.1 Steps 2–7).

    Returns (x, r, J, k, reason). ``counts`` (dict) accumulates nfev and njev.
    """
    tau, eps1, eps2, eps3, max_inner, marquardt = opts
    m = r.size
    n = x.size
    k = 0
    nu = 2.0
    A, g = _model(J, r, x, lb, fin, t)                        # Step 3
    if not _finite_model(A, g):
        return x, r, J, k, _ERROR_MODEL
    cost = float(r @ r)
    if np.max(np.abs(g)) / t <= eps1:                         # Step 4 (scaled, see Notes)
        return x, r, J, k, _GTOL
    if cost <= eps3:
        return x, r, J, k, _FTOL
    diag_a = np.diag(A).copy()
    if marquardt:
        sigma = tau
    else:
        sigma = tau * float(np.max(diag_a))                   # Step 5
    n_finite_trials = 0      # trial points with finite residuals since the last acceptance
    n_nonfinite_trials = 0
    while True:                                               # Step 6
        _interrupt.check()                                    # Ctrl-C / SIGTERM
        if k >= max_inner:                                    # Step xi
            return x, r, J, k, _MAXITER
        k += 1                                                # Step i
        if marquardt:
            scale = np.maximum(diag_a, np.finfo(float).eps * max(float(np.max(diag_a)), 1.0))
            D = sigma * scale
        else:
            D = sigma
        with np.errstate(over="ignore", invalid="ignore"):
            delta = _solve(A, np.broadcast_to(D, (n,)), g)   # Step ii
        step_norm = float(np.linalg.norm(delta)) if np.all(np.isfinite(delta)) else math.nan
        if step_norm <= eps2 * (float(np.linalg.norm(x)) + eps2):   # Step iii
            return x, r, J, k, _stalled(n_finite_trials, n_nonfinite_trials)
        rho = -math.inf
        if math.isfinite(step_norm):
            x_new = x + delta                                 # Step iv
            step = x_new - x                                  # the step after rounding
            d_old = x[fin] - lb[fin]
            if np.all(x_new[fin] > lb[fin]):                  # strictly feasible only
                counts["nfev"] += 1
                r_new = _eval_fun(fun, x_new, m)
                if not np.all(np.isfinite(r_new)):
                    n_nonfinite_trials += 1
                else:
                    n_finite_trials += 1
                    # phi(x) - phi(x_new), written to avoid cancellation at large t:
                    # t (r - r_new).(r + r_new) + sum log((x_new - lb)/(x - lb))
                    with np.errstate(over="ignore", invalid="ignore"):
                        actual = (t * float((r - r_new) @ (r + r_new))
                                  + float(np.sum(np.log1p(step[fin] / d_old))))
                    rho = _ratio(actual, model_decrease(step, g, A))        # Step v
        sigma, nu = update_damping(sigma, nu, rho)            # Step vi / ix
        if rho > 0.0:                                         # Step vii–viii
            x, r = x_new, r_new
            n_finite_trials = n_nonfinite_trials = 0
            counts["njev"] += 1
            J = _eval_jac(jac, x, m, n)
            if not np.all(np.isfinite(J)):
                return x, r, J, k, _ERROR_JAC
            A, g = _model(J, r, x, lb, fin, t)
            if not _finite_model(A, g):
                return x, r, J, k, _ERROR_MODEL
            diag_a = np.diag(A).copy()
            cost = float(r @ r)
            if np.max(np.abs(g)) / t <= eps1:                 # Step x
                return x, r, J, k, _GTOL
            if cost <= eps3:
                return x, r, J, k, _FTOL
        if not math.isfinite(sigma):
            # sigma overflowed: every trial point was rejected (non-finite residuals or
            # no decrease down to a vanishing step). The step test above normally fires first.
            return x, r, J, k, _stalled(n_finite_trials, n_nonfinite_trials)


# --------------------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------------------
def barrier_lm(fun, jac, x0, *, lb=0.0, t0=1.0, t_factor=20.0, t_max=1e12, tau=1.0,
               eps1=1e-10, eps2=1e-16, eps3=0.0, max_inner=500, damping="thesis",
               callback=None):
    """Minimise ``r(x).r(x)`` subject to ``x > lb`` by the thesis's barrier + LM method.

    Parameters
    ----------
    fun : callable ``fun(x) -> ndarray of float, shape (m,)``
        Real residual vector ``r``; complex residuals stacked as ``[Re; Im]``, so the data
        cost is ``eps(x) = r.r`` (SPEC §3, thesis eq. 3.9–3.10).
    jac : callable ``jac(x) -> ndarray of float, shape (m, n)``
        Jacobian ``dr/dx``.
    x0 : array_like of float, shape (n,)
        Start, strictly inside the bounds (``x0 > lb``).
    lb : float or array_like of float, shape (n,), optional
        Lower bounds (default 0: beta >= 0). ``-inf`` marks an unbounded variable, which
        gets no barrier term. There are no upper bounds.
    t0 : float, optional
        First barrier parameter ``t = 1/mu`` (thesis code: 1).
    t_factor : float, optional
        Growth of ``t`` per outer step, ``> 1`` (thesis ``alpha``; code ``mu1 = 20``).
    t_max : float, optional
        Outer steps are run for ``t = t0*t_factor**j <= t_max`` (code: stop when
        ``1/t < 1e-12``). With the defaults: 10 outer steps, the last at ``t = 5.12e11``.
    tau : float, optional
        Initial damping: ``sigma0 = tau*max(diag(A))`` (``"thesis"``) or ``sigma0 = tau``
        (``"marquardt"``).
    eps1 : float, optional
        Inner stop when ``||g||_inf / t <= eps1``: ``g/t`` is the gradient of the thesis's
        form ``eps(x) - mu*sum(log(x - lb))`` (eq. 2.22), which does not grow with ``t``.
    eps2 : float, optional
        Inner stop when ``||delta|| <= eps2*(||x|| + eps2)`` (thesis Step iii; the
        ``+ eps2`` of Nielsen keeps the test meaningful at ``x = 0``). The default 1e-16
        is below one ulp of ``x``: the test fires once the step is lost in rounding, which
        is needed to resolve ``x - lb ~ 1/t`` and hence ``lam_x`` (the thesis code uses
        1e-20; 1e-14 stops early and leaves ``lam_x`` a few % off).
    eps3 : float, optional
        Inner stop when the data cost ``eps(x) <= eps3`` (default 0: off).
    max_inner : int, optional
        ``k_max``: trial steps (accepted or not) per inner solve.
    damping : {"thesis", "marquardt"}, optional
        ``"thesis"``: ``(A + sigma I) delta = -g``, faithful to thesis eq. 3.2. It stalls
        when a variable nears its bound: the barrier curvature ``1/(x - lb)^2`` makes
        ``max(diag(A))`` and hence ``sigma`` huge, and the other variables crawl.
        ``"marquardt"``: ``(A + sigma diag(A)) delta = -g``, which damps each variable in
        its own curvature scale (an affine-scaling trust region).
    callback : callable ``callback(x, t, cost)``, optional
        Called after each outer step with a copy of ``x``, the ``t`` just solved and the
        data cost ``eps(x)``; its return value is ignored.

    Returns
    -------
    StageResult
        ``x`` (strictly feasible), ``cost = eps(x)`` (data cost, no barrier), ``status``
        (CONVERGED; MAX_ITER if the last inner solve hit ``max_inner``; ERROR if the
        Jacobian or the model became non-finite, or the residuals were non-finite at every
        trial point until the step vanished; the last good iterate is returned), ``nit``
        (inner trial steps summed), ``nfev`` (``fun`` calls, including the one at
        ``x0``), ``active_mask`` (relative tolerance 1e-6: the barrier leaves
        ``x - lb ~ 1/(t*lambda)``), ``lam_x`` (see Notes),
        ``solver_status`` (``"outer_done"``, ``"inner_max_iter"``,
        ``"nonfinite_jacobian"``, ``"nonfinite_residuals"`` or ``"nonfinite_model"``) and
        ``extra`` = ``{"n_outer", "t_final", "history" (list of (t, cost, inner_iters)
        per outer step), "inner_stop" (list of stop reasons), "njev", "damping"}``.

    Raises
    ------
    OptionError
        Invalid option (``t_factor <= 1``, ``tau <= 0``, unknown ``damping``, ...).
    DataError
        ``x0`` not finite or not strictly inside the bounds, ``fun(x0)`` or ``jac(x0)``
        not finite, or shapes that do not agree.

    Notes
    -----
    **Barrier formulation.** The inner loop minimises
    ``phi_t(x) = t*r.r - sum_{lb_i > -inf} log(x_i - lb_i)`` with the gradient and
    Hessian approximation

    ``g = 2 t J^T r - 1/(x - lb)``,  ``A = 2 t J^T J + diag(1/(x - lb)^2)``,

    i.e. Gauss–Newton curvature for the data term and the exact (Newton) curvature of the
    barrier, which is convex and separable. ``g`` is the exact gradient of ``phi_t`` and
    ``A`` is positive semi-definite, so the gain ratio is measured against a consistent
    model and an exact quadratic gives ``rho = 1``. The thesis instead subtracts
    ``sum(log beta)`` from every residual (eq. 2.26; ``eps_p = t_*(H - f)./f -
    sum(log(beta))`` in ``cost_and_coeffs.m``) and adds ``-1/beta_j`` to each Jacobian
    column (eq. 2.27); the sum of squares of those residuals is not ``phi_t`` (it mixes
    ``t^2 eps``, ``-2 t log * sum(r)`` and ``m log^2``), and its gradient is not that of
    the barrier problem, so we do not copy it.

    **Gain ratio.** ``rho = (phi(x) - phi(x + delta)) / (L(0) - L(delta))``. The thesis's
    denominator ``delta.(D delta - g)/2`` (:func:`predicted_decrease`, ``D = sigma`` or
    ``sigma*diag(A)``) equals the model decrease ``-(g.delta + delta.A.delta/2)``
    (:func:`model_decrease`) for the computed step; the solver evaluates the latter at the
    step actually taken after rounding, ``(x + delta) - x``. The actual decrease is
    evaluated as ``t (r - r_new).(r + r_new) + sum log1p(delta/(x - lb))``. Both avoid the
    cancellation that otherwise turns ``rho`` into noise once ``x - lb`` is a few hundred
    ulps of ``x`` (late outer steps), where the damping would then drift upward and stall.

    **Feasibility.** A trial step that leaves ``x > lb`` is not evaluated and counts as
    ``rho <= 0`` (as do non-finite residuals), so every point at which ``fun`` is called,
    and every accepted iterate, is strictly feasible. The thesis code instead clips one
    parameter to 0 (``if beta(1) < 0, beta(1) = 0``), where the barrier is infinite.

    **Multipliers.** At a minimiser of ``phi_t``, ``t grad eps = 1/(x - lb)``: the central
    path estimate of the KKT multiplier of ``min eps(x)`` s.t. ``x >= lb`` is
    ``1/(t (x - lb))``, with duality gap ``n_bounded/t``. In CasADi's sign convention
    (``grad eps + lam_x = 0``, negative at an active lower bound) we return
    ``lam_x = -1/(t (x - lb))`` for the last ``t`` solved, 0 where ``lb = -inf``. The
    multipliers are those of the data cost ``eps = r.r`` (not ``r.r/2``).

    References: thesis §3.1.1–3.1.2 and Appendix A; SPEC §3; H. B. Nielsen, "Damping
    parameter in Marquardt's method" (IMM-REP-1999-05); Boyd & Vandenberghe §11.3.
    """
    start = time.perf_counter()
    o = _check_options(fun, jac, callback, t0=t0, t_factor=t_factor, t_max=t_max, tau=tau,
                       eps1=eps1, eps2=eps2, eps3=eps3, max_inner=max_inner, damping=damping)
    t0, t_factor, t_max = float(o.t0), float(o.t_factor), float(o.t_max)
    x, lbv, _ = check_start(x0, lb, np.inf, strict=True)
    n = x.size
    fin = np.isfinite(lbv)

    r = _eval_fun(fun, x.copy())
    m = r.size
    bad = np.flatnonzero(~np.isfinite(r))
    if bad.size:
        i = bad[0]
        raise DataError(f"fun(x0) is not finite: r[{i}]={r[i]} ({bad.size} of {m} "
                        f"entries); choose an x0 where the model can be evaluated")
    J = _eval_jac(jac, x.copy(), m, n)
    bad = np.argwhere(~np.isfinite(J))
    if bad.size:
        i, j = bad[0]
        raise DataError(f"jac(x0) is not finite: J[{i}, {j}]={J[i, j]}; choose an x0 where "
                        f"the model can be differentiated")

    counts = {"nfev": 1, "njev": 1}
    opts = (float(o.tau), float(o.eps1), float(o.eps2), float(o.eps3), int(o.max_inner),
            damping == "marquardt")
    history = []
    inner_stop = []
    nit = 0
    t = t0
    t_last = t0
    reason = _GTOL
    while t <= t_max:                                         # thesis §3.1.2, Step 5
        x, r, J, k, reason = _inner_lm(fun, jac, x, r, J, lbv, fin, t, opts, counts)
        nit += k
        t_last = t
        cost = float(r @ r)
        history.append((t, cost, k))
        inner_stop.append(reason)
        if callback is not None:
            callback(x.copy(), t, cost)
        if reason in _ERRORS:
            break
        t *= t_factor                                         # Step 6: mu <- mu/alpha

    if reason in _ERRORS:
        status, solver_status = Status.ERROR, reason
    elif reason == _MAXITER:
        status, solver_status = Status.MAX_ITER, "inner_max_iter"
    elif counts["njev"] == 1 and _GTOL not in inner_stop and _FTOL not in inner_stop:
        # not one step accepted, and no inner solve stopped on its gradient or cost test:
        # the steps vanished from the start (e.g. a damping tau = 1e300), not an optimum
        status, solver_status = Status.STALLED, "no_step_accepted"
    else:
        status, solver_status = Status.CONVERGED, "outer_done"

    lam_x = np.zeros(n)
    lam_x[fin] = -1.0 / (t_last * (x[fin] - lbv[fin]))
    active = find_active_constraints(x, lbv, np.inf, rtol=1e-6)
    return StageResult(
        x=x.copy(),
        cost=float(r @ r),
        status=status,
        message=TERMINATION_MESSAGES[status],
        success=is_success(status),
        nit=int(nit),
        nfev=int(counts["nfev"]),
        wall_time=time.perf_counter() - start,
        active_mask=active,
        lam_x=lam_x,
        solver_status=solver_status,
        extra={"n_outer": len(history), "t_final": float(t_last), "history": history,
               "inner_stop": inner_stop, "njev": int(counts["njev"]), "damping": damping},
    )


def solve_stage_lm(problem, x0, **options):
    """:func:`barrier_lm` on a :class:`~freqid_casadi.solvers.common.StageProblem`.

    Fixed variables (``lb == ub``) are removed; the barrier method has no upper bounds, so
    ``problem.ub`` is neither imposed nor checked (the fit's delay bound is an IPOPT
    feature; it only marks ``active_mask``) and ``problem.constraints`` are not supported.

    Parameters
    ----------
    problem : StageProblem
    x0 : ndarray of float, shape (n,)
        Start, strictly above ``lb`` in every free variable (else
        :class:`~freqid_casadi.solvers.common.InfeasibleStartError`).
    **options
        Keyword arguments of :func:`barrier_lm` (``damping``, ``t0``, ..., ``max_inner``).

    Returns
    -------
    StageResult
        In all ``n`` variables (``lam_x`` 0 for the fixed ones; active set with relative
        tolerance 1e-6).

    Raises
    ------
    OptionError
        Bad options, or a problem with constraints.
    DataError, InfeasibleStartError
        As :func:`barrier_lm`.
    """
    if problem.constraints is not None:
        raise OptionError("the barrier-LM stage solver takes no constraints; use IPOPT "
                          "(method='ipopt') for a damping floor")
    lb, ub = problem.lb, problem.ub
    free = lb < ub
    x0 = check_start(x0, lb, np.where(free, np.inf, ub), strict=True)[0]
    xf = x0.copy()

    def full(v):
        xf[free] = v
        return xf

    res = barrier_lm(lambda v: problem.residual(full(v)),
                     lambda v: problem.jacobian(full(v))[:, free], x0[free], lb=lb[free],
                     **options)
    x = x0.copy()
    x[free] = res.x
    lam = np.zeros_like(x)
    lam[free] = res.lam_x
    return dataclasses.replace(res, x=x, lam_x=lam,
                               active_mask=find_active_constraints(x, lb, ub, rtol=1e-6))
