"""One stage NLP solved by IPOPT through CasADi (layer L3; the only ``nlpsol`` user).

The stage problem (:class:`~freqid_casadi.solvers.common.StageProblem`) is
``min_z  sum(r(z)^2)  s.t.  lb <= z <= ub`` with the bounds passed to IPOPT as simple
bounds (``lbx``/``ubx``), never as penalties (SPEC §3, first variant):
:func:`solve_stage`. :func:`solve_pnorm` is the p-norm stage of the minimax polish, and
:func:`run_nlpsol` the one wrapper of ``nlpsol`` (status, projection onto the bounds,
evaluation errors) that every IPOPT solve of the package goes through.
"""

import dataclasses
import time

import numpy as np

from .. import _interrupt
from ..errors import OptionError
from ..options import HESSIANS
from ._callbacks import _Cost, _GradF, _Hess
from .common import (StageProblem, StageResult, Status, TERMINATION_MESSAGES, check_start,
                     find_active_constraints, is_success)
from .termination import StageMonitor, Termination, iteration_callback

__all__ = ["HESSIANS", "solve_stage", "solve_least_squares", "solve_pnorm", "ipopt_status",
           "run_nlpsol", "base_options", "PROJECTION_RTOL",
           "STEP_FAILURES", "MAX_HESSIAN_PERTURBATION"]

_IPOPT_STATUS = {
    "Solve_Succeeded": Status.CONVERGED,
    "Solved_To_Acceptable_Level": Status.ACCEPTABLE,
    "Maximum_Iterations_Exceeded": Status.MAX_ITER,
    "Maximum_CpuTime_Exceeded": Status.MAX_ITER,
    "Maximum_WallTime_Exceeded": Status.MAX_ITER,
    "Search_Direction_Becomes_Too_Small": Status.SMALL_STEP,
    "Feasible_Point_Found": Status.ACCEPTABLE,
    "Invalid_Number_Detected": Status.ERROR,
    "NonIpopt_Exception_Thrown": Status.ERROR,
    "User_Requested_Stop": Status.STALLED,       # our iteration callback stopped it
}


def ipopt_status(return_status):
    """Map IPOPT's ``return_status`` string to a :class:`Status`.

    Parameters
    ----------
    return_status : str
        IPOPT's status word (e.g. ``"Solve_Succeeded"``); unknown words give FAILED.

    Returns
    -------
    Status
    """
    return _IPOPT_STATUS.get(return_status, Status.FAILED)


def solve_least_squares(funcs, x0, lb, ub, *, constraints=None, **options):
    """:func:`solve_stage` of the problem of an
    :class:`~freqid_casadi.core.objective.StageFunctions` with bounds ``lb``, ``ub``.

    Parameters
    ----------
    funcs : objective.StageFunctions
    x0 : ndarray of float, shape (n,)
        Start, within the bounds.
    lb, ub : ndarray of float, shape (n,)
    constraints : callable, optional
        ``g(z) >= 0`` on a CasADi vector.
    **options
        Keyword arguments of :func:`solve_stage`.

    Returns
    -------
    StageResult
    """
    problem = StageProblem.from_stage_functions(funcs, lb, ub, constraints)
    return solve_stage(problem, x0, **options)


def solve_stage(problem, x0, *, lam_x0=None, hessian="exact", max_iter=3000, tol=1e-12,
                warm_start=True, ipopt_options=None, verbose=False, termination=None):
    """Minimise ``||r(z)||^2`` subject to ``lb <= z <= ub`` (and ``g(z) >= 0``) with IPOPT.

    Parameters
    ----------
    problem : StageProblem
        Residual, derivatives, bounds and optional constraints. IPOPT gets the cost (a
        callback of ``problem.nlp_cost`` when given, else the MX expression of
        ``problem.casadi_residual``, else a callback of ``problem.cost``), and
        the gradient and Hessian from the problem's numpy callables as ``grad_f`` /
        ``hess_lag`` Functions (:class:`casadi.Callback`): the dense products are done
        by BLAS, the one operation the CasADi VM is slow at.
    x0 : ndarray of float, shape (n,)
        Start, within ``[lb, ub]`` (else :class:`InfeasibleStartError`).
    lam_x0 : ndarray of float, shape (n,), optional
        Bound multipliers to warm-start with (CasADi convention).
    hessian : {"exact", "gauss-newton", "limited-memory"}
        "exact" is ``problem.hessian`` (for a stage: the true Hessian assembled from the
        model's product structure); "gauss-newton" drops the second-order residual term
        (undamped, it jumps to phase-wrapped delays); "limited-memory" is IPOPT's
        quasi-Newton update.
    max_iter : int
    tol : float
        IPOPT's ``tol`` (scaled NLP error).
    warm_start : bool
        Use IPOPT's warm-start initialisation with tiny bound pushes, so that lightly damped
        parameters (zeta ~ 1e-4) near their bound are not pushed away at every stage.
    ipopt_options : dict, optional
        Extra IPOPT options (without the ``ipopt.`` prefix); they override the defaults.
    verbose : bool
        Let IPOPT print its iteration log.
    termination : Termination, optional
        The scale-free test (:mod:`~freqid_casadi.solvers.termination`) checked after
        every IPOPT iteration and at the returned point; default ``Termination()``.
        ``max_iter`` is then a safety net: IPOPT's own ``tol`` applies to the objective
        scaled by its start value, which the gradient's rounding noise exceeds once the
        cost has fallen by many orders.

    Returns
    -------
    StageResult
        ``x`` is projected onto the bounds exactly (IPOPT's bound relaxation can leave
        e.g. a damping at -1e-9, a right-half-plane root), and ``cost`` is evaluated there.
        ``success`` is True when IPOPT converged or the point passes the termination test
        (after a short LM polish if needed); ``message`` says which.

    Raises
    ------
    OptionError
        Unknown ``hessian``.
    InfeasibleStartError
        ``x0`` outside the bounds.
    DataError
        ``x0`` not finite or of the wrong shape.
    """
    import casadi as ca

    if hessian not in HESSIANS:
        raise OptionError(f"unknown hessian {hessian!r}; choose one of {', '.join(HESSIANS)}")
    t0 = time.perf_counter()
    x0, lb, ub = check_start(x0, problem.lb, problem.ub)
    n = problem.n
    z = ca.MX.sym("z", n)
    keep = [_GradF(n, problem.eval_gradient)]     # the callbacks must outlive the solver
    if problem.nlp_cost is not None:
        keep.append(_Cost(n, problem.nlp_cost, keep[0]))
        f = keep[-1](z)
    elif problem.casadi_residual is not None:
        f = ca.sumsqr(problem.casadi_residual(z))
    else:
        keep.append(_Cost(n, problem.eval_cost, keep[0]))
        f = keep[-1](z)
    nlp = {"x": z, "f": f}
    hess_g = _add_constraints(nlp, z, problem.constraints)
    opts = base_options(max_iter, tol, verbose)
    opts["ipopt"].update({"acceptable_tol": 1e-8, "acceptable_iter": 30})
    opts["grad_f"] = keep[0]
    monitor = StageMonitor(problem, termination or Termination())
    if monitor.stationary(x0)[0]:
        # already at a (relative) optimum: IPOPT's pushes off the bounds would only move it
        return monitor.at_start(x0, lam_x0, t0)
    keep.append(iteration_callback(monitor, n, 0 if "g" not in nlp else int(nlp["g"].numel())))
    opts["iteration_callback"] = keep[-1]
    if hessian == "limited-memory":
        opts["ipopt"]["hessian_approximation"] = "limited-memory"
    else:
        keep.append(_Hess(n, problem.eval_hessian, hessian, hess_g))
        opts["hess_lag"] = keep[-1]
    use_warm = warm_start and lam_x0 is not None
    if use_warm:
        opts["ipopt"].update({
            "warm_start_init_point": "yes",
            "warm_start_bound_push": 1e-9,
            "warm_start_bound_frac": 1e-9,
            "warm_start_slack_bound_push": 1e-9,
            "warm_start_slack_bound_frac": 1e-9,
            "warm_start_mult_bound_push": 1e-9,
            "mu_init": 1e-6,
        })
    # scale the objective to about 1 at the start: IPOPT's tolerances and its Hessian
    # regularisation (inertia correction) are absolute, and the cost of a good fit is tiny
    cost0 = problem.eval_cost(x0)
    if np.isfinite(cost0) and cost0 > 0:
        opts["ipopt"]["obj_scaling_factor"] = 1.0 / cost0
        opts["ipopt"]["nlp_scaling_method"] = "none"
    if ipopt_options:
        opts["ipopt"].update(ipopt_options)
    res, stats, t_build, t_solve = run_nlpsol(
        "stage", nlp, opts, x0, lb, ub, constrained=problem.constraints is not None,
        lam_x0=lam_x0 if use_warm else None, cost_of=problem.eval_cost, keep=keep, t0=t0)
    res = monitor.decide(res)
    return dataclasses.replace(res, extra={
        **(res.extra or {}), "max_iter": int(max_iter), "ipopt_status": res.solver_status,
        "t_build": t_build, "t_solve": t_solve,
        **{f"t_{k}": float(stats.get(f"t_wall_nlp_{k}", 0.0) or 0.0)
           for k in ("f", "grad_f", "hess_l")}})


def base_options(max_iter, tol, verbose):
    """nlpsol options shared by the stage solvers: true bounds (no relaxation, IPOPT's
    pushes off the bounds tiny, so lightly damped parameters stay near 0).

    Parameters
    ----------
    max_iter : int
    tol : float
    verbose : bool

    Returns
    -------
    dict
        ``nlpsol`` options with an ``"ipopt"`` sub-dict.
    """
    # a trial point where the residual is not finite is IPOPT's to cut back (the stage's
    # status says ERROR only if the solve ends there): CasADi's own line per such
    # evaluation ("nlp_grad_f failed: NaN detected") reached the user's terminal
    return {"print_time": False, "error_on_fail": False, "show_eval_warnings": bool(verbose),
            "ipopt": {"print_level": 5 if verbose else 0, "sb": "yes",
                      "max_iter": int(max_iter), "tol": float(tol),
                      "bound_relax_factor": 0.0, "honor_original_bounds": "yes",
                      "bound_push": 1e-9, "bound_frac": 1e-9}}


#: A returned point outside the bounds whose projection onto them raises ``cost_of`` by
#: more than this fraction is solved again (:func:`run_nlpsol`).
PROJECTION_RTOL = 1e-2
#: IPOPT's ``max_soc`` for an NLP without constraints (bounds only; a user's value wins).
#: There a second-order correction solves the rejected first trial step's own system again
#: (no constraint violation to correct; only the iterative refinement is skipped) and tests
#: that point; IPOPT's default 4 repeats the identical attempt three more times, an
#: objective evaluation and a back-solve each, since its loop test (violation 0 <= 0.99 *
#: 0) never ends it. One attempt keeps IPOPT's path exactly.
BOUNDS_ONLY_MAX_SOC = 1
#: IPOPT statuses after which :func:`run_nlpsol` solves again with the Hessian's
#: regularisation allowed up to :data:`MAX_HESSIAN_PERTURBATION`.
STEP_FAILURES = frozenset({"Error_In_Step_Computation", "Restoration_Failed"})
#: IPOPT's ``max_hessian_perturbation`` of that repeat (IPOPT's default 1e20).
MAX_HESSIAN_PERTURBATION = 1e40


def run_nlpsol(name, nlp, opts, x0, lb, ub, *, constrained=False, lam_x0=None,
               cost_of=None, keep=None, t0=None):
    """Build ``nlpsol(name, "ipopt", nlp, opts)`` and run it from ``x0``.

    IPOPT moves a bound by up to ``slack_move * max(1, |bound|)`` (default ``eps^(3/4)``)
    when a slack falls below machine precision, so a variable whose optimum is on its bound
    can end just outside it; the point is then projected onto the bounds. Where that
    projection raises ``cost_of`` by more than :data:`PROJECTION_RTOL` (a relative cost
    far below the rest's rounding level can rest on it: measured on sdypy-EMA's 5-channel
    system under ``OPENBLAS_CORETYPE=Prescott``, a numerator coefficient at -3.2e-14
    against its bound 0, projected, raised the cost from 3.7e-26 to 2.0e-21 and a
    channel's max rel. error from 4e-14 to 1.3e-12, a point the stage's termination test
    rightly rejected for its last 200 iterations), the solve is repeated once from the
    projected point with the bounds held exactly (``slack_move = 0``), and the better
    projected point is returned. Whether a slack gets that small depends on the last bits
    of the linear algebra (the BLAS kernel); solves that return a point within the bounds,
    or whose projection costs less, are not affected.

    A solve that ends in a failed step computation (:data:`STEP_FAILURES`) is repeated
    once, from the better of ``x0`` and its projected point, with IPOPT's
    ``max_hessian_perturbation`` raised to :data:`MAX_HESSIAN_PERTURBATION`: the stages
    scale the objective by 1 / (start cost), so near a zero residual the Hessian and the
    regularisation its inertia correction needs grow past IPOPT's default limit 1e20
    (measured on the same system under ``OPENBLAS_CORETYPE=Nehalem``: a restart at cost
    1.2e-22 failed at its first iteration and returned the pushed start, cost 2.6e-11;
    Prescott's run needed 1e20 exactly). If the solve still fails and ends above the
    start's cost, the start is returned.

    Parameters
    ----------
    name : str
    nlp : dict
        CasADi NLP (``x``, ``f``, optional ``g``).
    opts : dict
        nlpsol options (e.g. :func:`base_options`).
    x0, lb, ub : ndarray of float, shape (n,)
    constrained : bool
        ``nlp`` has ``g >= 0`` constraints.
    lam_x0 : ndarray of float, shape (n,), optional
        Bound multipliers to start from.
    cost_of : callable, optional
        ``cost_of(x)`` gives the result's ``cost``; a non-finite cost makes the status
        ERROR. Without it ``cost`` is nan (and no solve is repeated).
    keep : list, optional
        Callbacks that must outlive the solver; released after the solve.
    t0 : float, optional
        ``time.perf_counter()`` at the start of the caller's work (for ``wall_time``).

    Returns
    -------
    result : StageResult
        ``x`` projected onto the bounds; an evaluation error inside CasADi or a
        non-finite point gives ``Status.ERROR`` at ``x0``. After a repeated solve
        ``nit``/``nfev`` count both solves and ``message`` says so.
    stats : dict
        IPOPT's statistics (empty after an exception; of the solve returned, with
        ``iter_count`` summed over both and ``"step_retry"`` or ``"bound_retry"`` True
        after a repeat).
    t_build, t_solve : float
        Seconds building the solver(s) (from ``t0``) and solving.
    """
    t0 = time.perf_counter() if t0 is None else t0
    first = _solve(name, nlp, opts, x0, lb, ub, constrained, lam_x0, cost_of)
    t_build, t_solve = first["t_build"] - t0, first["t_solve"]
    out, note = first, ""
    plan = _retry_plan(first, x0, lam_x0, cost_of)
    if plan is not None:
        update, start, lam, why, key = plan
        again = _solve(name, nlp, {**opts, "ipopt": {**opts.get("ipopt", {}), **update}},
                       start, lb, ub, constrained, lam, cost_of)
        t_build += again["t_build"] - again["t_start"]
        t_solve += again["t_solve"]
        better = _better(again, first, cost_of)
        out = again if better else first
        out["stats"] = {**out["stats"], key: True, "iter_count": sum(
            int(d["stats"].get("iter_count", 0)) for d in (first, again))}
        for k in ("nit", "nfev"):
            out[k] = first[k] + again[k]
        note = f"; {why} ({again['return_status']}, {'kept' if better else 'not better'})"
        if (cost_of is not None and not is_success(out["status"])
                and not out["cost"] <= cost_of(x0)):
            out.update(x=x0, cost=cost_of(x0), lam_x=np.zeros(x0.size))
            note += "; the start kept (the failed solves ended higher)"
    if keep is not None:
        del keep[:]
    status = out["status"]
    res = StageResult(
        x=out["x"], cost=out["cost"], status=status,
        message=f"{TERMINATION_MESSAGES[status]} (IPOPT: {out['return_status']}){note}",
        success=is_success(status), nit=out["nit"], nfev=out["nfev"],
        wall_time=time.perf_counter() - t0,
        active_mask=find_active_constraints(out["x"], lb, ub, rtol=1e-8),
        lam_x=out["lam_x"], solver_status=out["return_status"])
    return res, out["stats"], t_build, t_solve


def _retry_plan(run, x0, lam_x0, cost_of):
    """``(ipopt option update, start, lam_x0, why, stats key)`` of the one repeated solve
    of :func:`run_nlpsol`, or None: after a step computation that failed
    (:data:`STEP_FAILURES`) from the better of the start and the projected point with
    ``max_hessian_perturbation`` raised; after a costly projection from the projected
    point with the bounds held exactly."""
    if run["return_status"] in STEP_FAILURES:
        start, lam = x0, lam_x0
        if cost_of is not None and run["cost"] < cost_of(x0):
            start, lam = run["x"], run["lam_x"]
        return ({"max_hessian_perturbation": MAX_HESSIAN_PERTURBATION}, start, lam,
                f"IPOPT's step computation failed ({run['return_status']}): solved again "
                f"with max_hessian_perturbation {MAX_HESSIAN_PERTURBATION:g}", "step_retry")
    if _projection_costs(run, cost_of):
        return ({"slack_move": 0.0}, run["x"], run["lam_x"],
                f"IPOPT's point was outside the bounds, projected cost {run['cost']:.3g} > "
                f"{run['cost_raw']:.3g}: solved again with the bounds held exactly",
                "bound_retry")
    return None


def _better(again, first, cost_of):
    """The repeated solve's result is kept: a lower finite cost (without ``cost_of``: it
    succeeded where the first did not)."""
    if again["status"] == Status.ERROR:
        return False
    if cost_of is None:
        return is_success(again["status"]) and not is_success(first["status"])
    return bool(again["cost"] < first["cost"])


def _projection_costs(run, cost_of):
    """True when ``run``'s IPOPT point was outside the bounds and projecting it raised the
    cost by more than :data:`PROJECTION_RTOL` (relative)."""
    raw = run["cost_raw"]
    return (cost_of is not None and run["outside"] and run["status"] != Status.ERROR
            and np.isfinite(raw) and run["cost"] > raw * (1.0 + PROJECTION_RTOL))


def _solve(name, nlp, opts, x0, lb, ub, constrained, lam_x0, cost_of):
    """One ``nlpsol`` build and solve (see :func:`run_nlpsol`); a dict of the projected
    point ``x``, its ``cost`` and ``status``, ``cost_raw`` (at IPOPT's own point),
    ``outside`` (that point left the bounds), ``lam_x``, ``return_status``, ``stats``,
    ``nit``, ``nfev`` and the times ``t_start``, ``t_build`` (perf_counter after the
    build) and ``t_solve`` (s)."""
    import casadi as ca

    t_start = time.perf_counter()
    if not constrained:
        opts = {**opts, "ipopt": {"max_soc": BOUNDS_ONLY_MAX_SOC, **opts.get("ipopt", {})}}
    # one iteration callback: a stage's termination monitor (which also stops on Ctrl-C /
    # SIGTERM), else the interrupt hook alone
    with _interrupt.guard():        # (CasADi calls the Python callbacks while it builds)
        solver = ca.nlpsol(name, "ipopt", nlp, {**_interrupt.ipopt_callback(nlp), **opts})
    t_build = time.perf_counter()
    args = {"x0": x0, "lbx": lb, "ubx": ub}
    if constrained:
        args.update(lbg=0.0, ubg=np.inf)
    if lam_x0 is not None:
        args["lam_x0"] = np.asarray(lam_x0, float)
    try:
        with _interrupt.guard():        # Ctrl-C/SIGTERM: IPOPT stops, then Interrupted
            sol = solver(**args)
        stats = solver.stats()
        return_status = str(stats.get("return_status", "unknown"))
        raw = np.array(sol["x"], float).reshape(-1)
        lam_x = np.array(sol["lam_x"], float).reshape(-1)
    except RuntimeError as exc:  # evaluation errors raised inside CasADi
        stats, return_status, raw, lam_x = {}, f"exception: {exc}", x0, np.zeros(x0.size)
    t_solve = time.perf_counter() - t_build
    x = np.clip(raw, lb, ub)
    outside = bool(np.any(x != raw))
    cost = cost_of(x) if cost_of is not None else float("nan")
    status = (ipopt_status(return_status) if cost_of is None or np.isfinite(cost)
              else Status.ERROR)
    if not np.all(np.isfinite(x)):
        status, x = Status.ERROR, x0
    cost_raw = cost
    if outside and cost_of is not None and status != Status.ERROR and np.all(np.isfinite(raw)):
        with np.errstate(all="ignore"):     # (outside the bounds by a rounding-size move)
            cost_raw = cost_of(raw)
    return {"x": x, "cost": cost, "status": status, "cost_raw": cost_raw,
            "outside": outside, "lam_x": lam_x, "return_status": return_status,
            "stats": stats, "nit": int(stats.get("iter_count", 0)),
            "nfev": int(stats.get("n_call_nlp_f", 0) or 0), "t_start": t_start,
            "t_build": t_build, "t_solve": t_solve}


def _add_constraints(nlp, z, constraints):
    """Put ``g = constraints(z)`` (>= 0) into ``nlp``; return the Function
    ``(z, lam_g) -> Hessian of lam_g . g`` (CasADi AD) for the Lagrangian's Hessian, or None
    without constraints."""
    if constraints is None:
        return None
    import casadi as ca

    g = constraints(z)
    nlp["g"] = g
    lam_g = ca.MX.sym("lam_g", g.numel())
    return ca.Function("hess_g", [z, lam_g], [ca.densify(ca.hessian(ca.dot(lam_g, g), z)[0])])


def solve_pnorm(funcs, x0, lb, ub, p, *, max_iter=300, tol=1e-10, constraints=None,
                verbose=False):
    """Minimise a smooth stand-in for the largest relative error: the p-norm of the
    squared residuals, ``(1/p) log sum_i (|r_i|^2 / s)^(p/2)``, ``s`` the largest ``|r_i|^2``
    at ``x0`` (so the terms are O(1) and the objective is smooth for any p).

    As p grows it tends to ``log max_i |r_i|`` (minus ``log sqrt(s)``); a continuation in p,
    each stage started from the last, walks down to the minimax point while every stage
    stays a smooth NLP with true bounds. The objective is the log-sum-exp of the vectorised
    MX residual; its exact gradient and Hessian come from the stage's structured
    derivatives (:class:`~freqid_casadi.core.objective.PNormFunctions`) through the same
    callbacks as :func:`solve_least_squares`.

    Parameters
    ----------
    funcs : objective.StageFunctions
    x0, lb, ub : ndarray of float, shape (n,)
        Start (within the bounds, else :class:`InfeasibleStartError`) and bounds.
    p : float >= 2
    max_iter : int
    tol : float
    constraints : callable, optional
        ``g(z) >= 0`` as in :func:`solve_least_squares`.
    verbose : bool

    Returns
    -------
    StageResult
        ``cost`` is the largest ``|r_i|^2`` at the returned (projected) ``x``.
    """
    import casadi as ca

    t_start = time.perf_counter()
    n, m = funcs.param.n_vars, funcs.n_points
    x0, lb, ub = check_start(x0, lb, ub)
    r0 = funcs.residual(x0)
    s = float(np.max(r0[:m] ** 2 + r0[m:] ** 2))
    if not (np.isfinite(s) and s > 0):
        s = 1.0
    from ..core.objective import PNormFunctions

    z = ca.MX.sym("z", n)
    r = funcs.r_fun(z)
    e2 = (r[:m] ** 2 + r[m:] ** 2) / s
    # log-sum-exp of (p/2) log e2: no overflow at trial points far from x0 (p up to 1e3)
    nlp = {"x": z, "f": ca.logsumexp(0.5 * float(p) * ca.log(e2 + 1e-300)) / float(p)}
    hess_g = _add_constraints(nlp, z, constraints)
    pn = PNormFunctions(funcs, p, s)
    keep = [_GradF(n, pn.gradient), _Hess(n, pn.hessian, "exact", hess_g)]  # outlive solver
    opts = base_options(max_iter, tol, verbose)
    opts.update({"show_eval_warnings": False, "grad_f": keep[0], "hess_lag": keep[1]})
    opts["ipopt"]["mu_init"] = 1e-6

    def max_abs2(x):
        rr = funcs.residual(x)
        return float(np.max(rr[:m] ** 2 + rr[m:] ** 2))

    res = run_nlpsol("pnorm", nlp, opts, x0, lb, ub, constrained=constraints is not None,
                     cost_of=max_abs2, keep=keep, t0=t_start)[0]
    return dataclasses.replace(res, extra={"p": float(p)})
