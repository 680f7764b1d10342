"""One stage NLP solved by IPOPT through CasADi (layer L3; the only ``nlpsol`` user).

The stage problem is ``min_z  sum(r(z)^2)  s.t.  lb <= z <= ub`` with the bounds passed to
IPOPT as simple bounds (``lbx``/``ubx``), never as penalties (SPEC §3, first variant).
"""

import dataclasses
import time

import numpy as np

from ..errors import OptionError
from .common import (StageResult, Status, SUCCESS_STATUSES, TERMINATION_MESSAGES,
                     Termination, find_active_constraints, free_variables,
                     projected_fraction, relative_stationarity)

__all__ = ["HESSIANS", "solve_least_squares", "solve_pnorm", "ipopt_status"]

HESSIANS = ("exact", "exact-clip", "gauss-newton", "limited-memory")

_IPOPT_STATUS = {
    "Solve_Succeeded": Status.CONVERGED,
    "Solved_To_Acceptable_Level": Status.ACCEPTABLE,
    "Maximum_Iterations_Exceeded": Status.MAX_ITER,
    "Maximum_CpuTime_Exceeded": Status.MAX_ITER,
    "Maximum_WallTime_Exceeded": Status.MAX_ITER,
    "Search_Direction_Becomes_Too_Small": Status.SMALL_STEP,
    "Feasible_Point_Found": Status.ACCEPTABLE,
    "User_Requested_Stop": Status.STALLED,
    "Invalid_Number_Detected": Status.ERROR,
    "NonIpopt_Exception_Thrown": Status.ERROR,
}


def ipopt_status(return_status):
    """Map IPOPT's ``return_status`` string to a :class:`Status`."""
    return _IPOPT_STATUS.get(return_status, Status.FAILED)


def solve_least_squares(funcs, x0, lb, ub, *, lam_x0=None, hessian="exact",
                        max_iter=3000, tol=1e-12, warm_start=True, ipopt_options=None,
                        verbose=False, constraints=None, termination=None):
    """Minimise ``||r(z)||^2`` subject to ``lb <= z <= ub`` with IPOPT.

    Parameters
    ----------
    funcs : objective.StageFunctions
        The stage's residual ``r_fun`` (CasADi; the NLP objective is
        ``sumsqr(r_fun(z))``) and the numpy assembly of its gradient ``2 J^T r`` and
        Hessian, passed to IPOPT as ``grad_f``/``hess_lag`` Functions
        (:class:`casadi.Callback`): the dense products are done by BLAS, the one
        operation the CasADi VM is slow at.
    x0 : ndarray of float, shape (n,)
        Start; clipped into ``[lb, ub]``.
    lb, ub : ndarray of float, shape (n,)
        Simple bounds (``ub`` may be inf).
    lam_x0 : ndarray of float, shape (n,), optional
        Bound multipliers to warm-start with (CasADi convention).
    hessian : {"exact", "gauss-newton", "limited-memory"}
        "exact" is the true Hessian assembled from the model's product structure
        (:class:`~freqid_casadi.objective.StageFunctions`); "gauss-newton" drops the
        second-order residual term (undamped, it jumps to phase-wrapped delays).
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
    constraints : callable, optional
        ``g(z) >= 0``: maps a CasADi (n,) vector to the constraint vector (e.g.
        :meth:`~freqid_casadi.objective.Parametrization.damping_constraints`). Its Jacobian
        and its part of the Lagrangian's Hessian come from CasADi's AD; ``x0`` should be
        feasible (IPOPT then keeps it so).
    termination : Termination, optional
        The scale-free test checked after every IPOPT iteration (relative stationarity, or
        a stall of the relative cost decrease); default ``Termination()``. IPOPT's own
        ``tol`` applies to the objective scaled by its start value and cannot be met once
        the cost has fallen by many orders (the gradient's rounding noise); this test can.

    Returns
    -------
    StageResult
        ``success`` is True when IPOPT converged or the point passes the relative
        stationarity test; ``x`` is projected onto the bounds exactly (IPOPT's bound relaxation can leave
        e.g. a damping at -1e-9, a right-half-plane root), and ``cost`` is evaluated there.
    """
    import casadi as ca

    if hessian not in HESSIANS:
        raise OptionError(f"unknown hessian {hessian!r}; choose one of {', '.join(HESSIANS)}")
    t0 = time.perf_counter()
    n = funcs.param.n_vars
    lb = np.asarray(lb, float)
    ub = np.asarray(ub, float)
    x0 = np.clip(np.asarray(x0, float), lb, ub)
    z = ca.MX.sym("z", n)
    f = ca.sumsqr(funcs.r_fun(z))
    nlp = {"x": z, "f": f}
    hess_g = _add_constraints(nlp, z, constraints)
    opts = _base_options(max_iter, tol, verbose)
    opts["ipopt"].update({"acceptable_tol": 1e-8, "acceptable_iter": 30})
    keep = [_GradF(funcs)]          # the callbacks must outlive the solver
    opts["grad_f"] = keep[0]
    monitor = _Monitor(funcs, lb, ub, termination or Termination())
    keep.append(_IterCB(monitor, n, 0 if constraints is None else int(nlp["g"].numel())))
    opts["iteration_callback"] = keep[-1]
    if hessian == "limited-memory":
        opts["ipopt"]["hessian_approximation"] = "limited-memory"
    else:
        keep.append(_Hess(funcs, hessian, hess_g))
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
    cost0 = funcs.cost(x0)
    if np.isfinite(cost0) and cost0 > 0:
        opts["ipopt"]["obj_scaling_factor"] = 1.0 / cost0
        opts["ipopt"]["nlp_scaling_method"] = "none"
    if ipopt_options:
        opts["ipopt"].update(ipopt_options)
    solver = ca.nlpsol("stage", "ipopt", nlp, opts)
    t_build = time.perf_counter() - t0
    res, stats, t_solve = _solve(solver, keep, x0, lb, ub, constraints is not None,
                                 lam_x0 if use_warm else None, funcs.cost, t0)
    res = monitor.decide(res)
    return dataclasses.replace(res, extra={
        "t_build": t_build, "t_solve": t_solve,
        **{f"t_{k}": float(stats.get(f"t_wall_nlp_{k}", 0.0) or 0.0)
           for k in ("f", "grad_f", "hess_l")}})


def _base_options(max_iter, tol, verbose):
    """nlpsol options shared by the stage solvers: true bounds (no relaxation, IPOPT's
    pushes off the bounds tiny, so lightly damped parameters stay near 0)."""
    return {"print_time": False, "error_on_fail": False,
            "ipopt": {"print_level": 5 if verbose else 0, "sb": "yes",
                      "max_iter": int(max_iter), "tol": float(tol),
                      "bound_relax_factor": 0.0, "honor_original_bounds": "yes",
                      "bound_push": 1e-9, "bound_frac": 1e-9}}


def _solve(solver, keep, x0, lb, ub, constrained, lam_x0, cost_of, t0):
    """Run ``solver`` from ``x0``; return ``(StageResult, stats, t_solve)``.

    ``x`` is projected onto the bounds; ``cost_of(x)`` gives the result's cost; an
    evaluation error inside CasADi or a non-finite point gives ``Status.ERROR`` at ``x0``.
    ``keep`` (the callbacks) is released after the solve.
    """
    args = {"x0": x0, "lbx": lb, "ubx": ub}
    if constrained:
        args.update(lbg=0.0, ubg=np.inf)
    if lam_x0 is not None:
        args["lam_x0"] = np.asarray(lam_x0, float)
    t_solve = time.perf_counter()
    try:
        sol = solver(**args)
        stats = solver.stats()
        return_status = str(stats.get("return_status", "unknown"))
        x = np.clip(np.array(sol["x"], float).reshape(-1), lb, ub)
        lam_x = np.array(sol["lam_x"], float).reshape(-1)
    except RuntimeError as exc:  # evaluation errors raised inside CasADi
        stats, return_status, x, lam_x = {}, f"exception: {exc}", x0, np.zeros(x0.size)
    t_solve = time.perf_counter() - t_solve
    del keep[:]
    cost = cost_of(x)
    status = ipopt_status(return_status) if np.isfinite(cost) else Status.ERROR
    if not np.all(np.isfinite(x)):
        status, x = Status.ERROR, x0
    res = StageResult(
        x=x, cost=cost, status=status,
        message=f"{TERMINATION_MESSAGES[status]} (IPOPT: {return_status})",
        success=status in SUCCESS_STATUSES, nit=int(stats.get("iter_count", 0)),
        nfev=int(stats.get("n_call_nlp_f", 0) or 0), wall_time=time.perf_counter() - t0,
        active_mask=find_active_constraints(x, lb, ub, rtol=1e-8),
        lam_x=lam_x, solver_status=return_status)
    return res, stats, t_solve


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


def _make_callbacks():
    import casadi as ca

    class GradF(ca.Callback):
        """``nlp_grad_f``: (x, p) -> (f, grad f) with grad f = 2 J^T r."""

        def __init__(self, funcs):
            ca.Callback.__init__(self)
            self.funcs = funcs
            self.n = funcs.param.n_vars
            self.construct("nlp_grad_f", {})

        def get_n_in(self):
            return 2

        def get_n_out(self):
            return 2

        def get_name_in(self, i):
            return ("x", "p")[i]

        def get_name_out(self, i):
            return ("f", "grad_f")[i]

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(self.n, 1) if i == 0 else ca.Sparsity.dense(0, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(1, 1) if i == 0 else ca.Sparsity.dense(self.n, 1)

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            # copy-free: read x from and write (f, grad) into CasADi's own buffers
            x = np.frombuffer(arg[0], dtype=np.float64)
            cost, grad = self.funcs.gradient(x.copy())
            if res[0] is not None:              # an output not asked for is None
                np.frombuffer(res[0], dtype=np.float64)[0] = cost
            if res[1] is not None:
                np.frombuffer(res[1], dtype=np.float64)[:] = grad
            return 0

    class Hess(ca.Callback):
        """``nlp_hess_l``: (x, p, lam_f, lam_g) -> triu(lam_f * Hessian of the cost)."""

        def __init__(self, funcs, kind, hess_g=None):
            ca.Callback.__init__(self)
            self.funcs = funcs
            self.hess_g = hess_g
            self.ng = 0 if hess_g is None else hess_g.numel_in(1)
            self.exact = kind != "gauss-newton"
            self.clip = kind == "exact-clip"
            n = self.n = funcs.param.n_vars
            self.sp = ca.Sparsity.upper(n)
            rows, cols = np.triu_indices(n)
            order = np.lexsort((rows, cols))                 # column-major nonzero order
            self.flat = rows[order] * n + cols[order]        # into the row-major Hessian
            self.construct("nlp_hess_l", {})

        def get_n_in(self):
            return 4

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ("x", "p", "lam_f", "lam_g")[i]

        def get_name_out(self, i):
            return "hess_gamma_x_x"

        def get_sparsity_in(self, i):
            return [ca.Sparsity.dense(self.n, 1), ca.Sparsity.dense(0, 1),
                    ca.Sparsity.dense(1, 1), ca.Sparsity.dense(self.ng, 1)][i]

        def get_sparsity_out(self, i):
            return self.sp

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            x = np.frombuffer(arg[0], dtype=np.float64).copy()
            lam_f = float(np.frombuffer(arg[2], dtype=np.float64)[0])
            if res[0] is None:
                return 0
            h = lam_f * self.funcs.hessian(x, exact=self.exact, clip=self.clip)
            if self.ng:
                lam_g = (np.zeros(self.ng) if arg[3] is None
                         else np.frombuffer(arg[3], dtype=np.float64))
                h = h + self.hess_g(x, lam_g).full()
            np.copyto(np.frombuffer(res[0], dtype=np.float64), h.ravel().take(self.flat))
            return 0


    class IterCB(ca.Callback):
        """``iteration_callback``: runs the :class:`_Monitor`; a nonzero return stops IPOPT
        (``User_Requested_Stop``)."""

        def __init__(self, monitor, n, ng):
            ca.Callback.__init__(self)
            self.monitor, self.n, self.ng = monitor, n, ng
            self.construct("iteration_monitor", {})

        def get_n_in(self):
            return ca.nlpsol_n_out()

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ca.nlpsol_out(i)

        def get_name_out(self, i):
            return "ret"

        def get_sparsity_in(self, i):
            name = ca.nlpsol_out(i)
            if name == "f":
                return ca.Sparsity.scalar()
            if name in ("x", "lam_x"):
                return ca.Sparsity.dense(self.n)
            if name in ("g", "lam_g"):
                return ca.Sparsity.dense(self.ng)
            return ca.Sparsity(0, 0)

        def eval(self, arg):
            return [1 if self.monitor.check(np.array(arg[0].full(), float).reshape(-1))
                    else 0]

    return GradF, Hess, IterCB


class _Monitor:
    """The :class:`~freqid_casadi.solvers.common.Termination` test of one stage, run after
    every IPOPT iteration and once more at the returned point."""

    def __init__(self, funcs, lb, ub, term):
        self.funcs, self.lb, self.ub, self.term = funcs, lb, ub, term
        nsec = funcs.param.structure.n_sections
        self.n_factors = 2 * nsec + 3
        self.history = []
        self.reason = None
        self.cos = self.allowed = self.proj = float("nan")

    def stationary(self, x):
        """(stationary?, cost) at ``x``: the cheap cosine test, then the projection."""
        x = np.clip(x, self.lb, self.ub)
        cost, grad = self.funcs.gradient(x)
        if not np.isfinite(cost):
            return False, cost
        cn = self.funcs.column_norms(x)
        free = free_variables(grad, x, self.lb, self.ub, cn, np.sqrt(max(cost, 0.0)),
                              np.sqrt(self.term.ftol))
        cmax, noise = relative_stationarity(grad, cn, cost, free,
                                            self.funcs.n_points, self.n_factors)
        noise *= self.term.noise_factor
        self.cos, self.allowed = cmax, np.sqrt(self.term.ftol) + noise
        if cmax > self.allowed:
            return False, cost
        r, jac = self.funcs.residual_jacobian(x)
        self.proj = projected_fraction(r, jac, free, self.term.rcond)
        return self.proj ** 2 <= self.term.ftol + noise, cost

    def check(self, x):
        ok, cost = self.stationary(x)
        if ok:
            self.reason = "stationary"
            return True
        self.history.append(cost)
        w = self.term.stall_window
        if w and len(self.history) > w:
            old = self.history[-w - 1]
            if old - self.history[-1] <= self.term.stall_ftol * old:
                self.reason = "stalled"
                return True
        return False

    def decide(self, res):
        """The stage's status and success from the test at the returned point; a point
        that fails it gets a bounded LM polish (:func:`~.polish.lm_polish`) first."""
        if res.status == Status.ERROR:
            return res
        ok, _ = self.stationary(res.x)
        if not ok:
            from .polish import lm_polish

            x, steps = lm_polish(self.funcs, res.x, self.lb, self.ub,
                                 lambda v: self.stationary(v)[0])
            if steps:
                res = dataclasses.replace(res, x=x, cost=self.funcs.cost(x),
                                          nit=res.nit + steps)
                ok, _ = self.stationary(x)
        ipopt_ok = res.status in (Status.CONVERGED, Status.ACCEPTABLE)
        test = (f"max cos(r, J_j) {self.cos:.2g} (allowed {self.allowed:.2g}), "
                f"||P r||/||r|| {self.proj:.2g}")
        if ok or ipopt_ok:
            status = res.status if ipopt_ok else Status.CONVERGED
            how = "relative stationarity" if ok else "IPOPT's tolerance"
            msg = f"converged ({how}: {test}; IPOPT: {res.solver_status})"
            return dataclasses.replace(res, status=status, success=True, message=msg)
        status = Status.STALLED if self.reason == "stalled" else res.status
        if status == Status.SMALL_STEP or status in SUCCESS_STATUSES:
            status = Status.SMALL_STEP
        msg = (f"{TERMINATION_MESSAGES[status]}; not stationary ({test}; IPOPT: "
               f"{res.solver_status})")
        return dataclasses.replace(res, status=status, success=False, message=msg)


_CALLBACKS = []


def _callback_classes():
    if not _CALLBACKS:
        _CALLBACKS.extend(_make_callbacks())
    return _CALLBACKS


def _GradF(funcs):
    return _callback_classes()[0](funcs)


def _Hess(funcs, kind, hess_g=None):
    return _callback_classes()[1](funcs, kind, hess_g)


def _IterCB(monitor, n, ng):
    return _callback_classes()[2](monitor, n, ng)


def solve_pnorm(funcs, x0, lb, ub, p, *, max_iter=300, tol=1e-10, constraints=None,
                verbose=False):
    """Minimise a smooth stand-in for the largest relative error: the p-norm of the
    squared residuals, ``(1/p) log sum_i (|r_i|^2 / s)^(p/2)``, ``s`` the largest ``|r_i|^2``
    at ``x0`` (so the terms are O(1) and the objective is smooth for any p).

    As p grows it tends to ``log max_i |r_i|`` (minus ``log sqrt(s)``); a continuation in p,
    each stage started from the last, walks down to the minimax point while every stage
    stays a smooth NLP with true bounds. The objective is the log-sum-exp of the vectorised
    MX residual; its exact gradient and Hessian come from the stage's structured
    derivatives (:class:`~freqid_casadi.objective.PNormFunctions`) through the same
    callbacks as :func:`solve_least_squares`.

    Parameters
    ----------
    funcs : objective.StageFunctions
    x0, lb, ub : ndarray of float, shape (n,)
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
    lb = np.asarray(lb, float)
    ub = np.asarray(ub, float)
    x0 = np.clip(np.asarray(x0, float), lb, ub)
    r0 = funcs.residual(x0)
    s = float(np.max(r0[:m] ** 2 + r0[m:] ** 2))
    if not (np.isfinite(s) and s > 0):
        s = 1.0
    from ..objective import PNormFunctions

    z = ca.MX.sym("z", n)
    r = funcs.r_fun(z)
    e2 = (r[:m] ** 2 + r[m:] ** 2) / s
    # log-sum-exp of (p/2) log e2: no overflow at trial points far from x0 (p up to 1e3)
    nlp = {"x": z, "f": ca.logsumexp(0.5 * float(p) * ca.log(e2 + 1e-300)) / float(p)}
    hess_g = _add_constraints(nlp, z, constraints)
    pn = PNormFunctions(funcs, p, s)
    keep = [_GradF(pn), _Hess(pn, "exact", hess_g)]     # must outlive the solver
    opts = _base_options(max_iter, tol, verbose)
    opts.update({"show_eval_warnings": False, "grad_f": keep[0], "hess_lag": keep[1]})
    opts["ipopt"]["mu_init"] = 1e-6
    solver = ca.nlpsol("pnorm", "ipopt", nlp, opts)

    def max_abs2(x):
        rr = funcs.residual(x)
        return float(np.max(rr[:m] ** 2 + rr[m:] ** 2))

    res, _, _ = _solve(solver, keep, x0, lb, ub, constraints is not None, None, max_abs2,
                       t_start)
    return dataclasses.replace(res, extra={"p": float(p)})
