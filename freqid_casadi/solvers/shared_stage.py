"""IPOPT on one stage of the shared-pole fit (layer L3).

:func:`solve_stage` minimises :class:`~freqid_casadi.modal._nlp.SharedProblem`'s cost with
true bounds and its exact sparse (block-arrowhead) Hessian, and ends the solve at a
relatively stationary point
(:class:`~freqid_casadi.solvers.shared_termination.SharedMonitor`, checked
after every IPOPT iteration). IPOPT's objective is scaled by the start cost, and its barrier
parameter is absolute in those units: once the cost has fallen by :data:`RESCALE` the
barrier holds variables whose optimum is on a bound far off it (measured on the beam's
5 + 1 polish: an own section's numerator damping held at 5e-3 for 270 iterations while the
cost stayed 5.6e-5 above its optimum), so the solve is restarted there, warm, rescaled.

A warm restart pushes the variables on a bound into the interior by
:func:`warm_push`, a distance that moves the residual by at most :data:`PUSH_FRACTION` of its
norm: IPOPT's usual 1e-9 undid a fit at the rounding level (measured on sdypy-EMA's exact
5-mode chain: each restart lifted the cost from ~1e-20 to ~1e-13, the last one ended at the
iteration limit at max rel. error 3.1e-10 on one kernel and converged at 5e-11 on another;
with the scaled push every kernel converges at the data's rounding, 1.7e-13, in 97
iterations). A restart never returns a point worse than its start.
"""

import time

import numpy as np

from .. import _interrupt
from .shared_termination import SHARED_TERMINATION, SharedMonitor, gradient_and_norms, verdict
from .ipopt import run_nlpsol
from .termination import iteration_callback

__all__ = ["solve_stage", "warm_push", "RESCALE", "MAX_RESTARTS", "PUSH_FRACTION"]
_EXTRA = {}
#: A solve is restarted (objective rescaled) once its cost fell by this factor.
RESCALE = 1e-2
#: Most rescaled restarts of one solve (each needs another RESCALE-fold cost decrease).
MAX_RESTARTS = 20
#: Largest part of the residual's norm a warm start's push off the bounds may change.
PUSH_FRACTION = 1e-3
#: IPOPT's push of a cold start (and the most of a warm one), absolute.
BOUND_PUSH = 1e-9
#: The least warm push: on a bound of magnitude 1 (a delay's upper bound) it still leaves
#: a representable slack (> eps / 2).
MIN_PUSH = 1e-15


def warm_push(problem, x, n_points=None):
    """IPOPT's ``warm_start_bound_push`` at ``x``: the distance off a bound that changes
    the stacked residual by at most :data:`PUSH_FRACTION` of its norm through any one
    variable, ``PUSH_FRACTION * ||r|| / max_j ||J_j||``, within [:data:`MIN_PUSH`,
    :data:`BOUND_PUSH`].

    Parameters
    ----------
    problem : SharedProblem
    x : ndarray of float, shape (n_vars,)
    n_points : int, optional
        The stage's window (default all frequencies).

    Returns
    -------
    float
        Absolute distance (the variables are in the dc gauge, of order one).
    """
    cost, _, cn = gradient_and_norms(problem, x, n_points)
    big = float(np.max(cn)) if cn.size else 0.0
    if not (np.isfinite(cost) and np.isfinite(big) and big > 0.0):
        return BOUND_PUSH
    return float(np.clip(PUSH_FRACTION * np.sqrt(max(cost, 0.0)) / big, MIN_PUSH, BOUND_PUSH))


def _callbacks():
    import casadi as ca

    class _Fn(ca.Callback):
        """A numpy function as a CasADi Function writing into CasADi's buffers."""

        def __init__(self, name, fn, names_in, sp_in, names_out, sp_out, jac=None):
            ca.Callback.__init__(self)
            self.fn, self.names_in, self.sp_in = fn, names_in, sp_in
            self.names_out, self.sp_out = names_out, sp_out
            self.jac = jac                  # (x -> [gradient]) for CasADi's own AD of f
            self._jac_fn = None
            _interrupt.construct(self, name)

        def has_jacobian(self):
            return self.jac is not None

        def get_jacobian(self, name, inames, onames, opts):
            n = self.sp_in[0].size1()
            self._jac_fn = _Fn(name, lambda x, out: self.jac(x), inames,
                               [self.sp_in[0], self.sp_out[0]], onames,
                               [ca.Sparsity.dense(1, n)])
            return self._jac_fn

        def get_n_in(self):
            return len(self.sp_in)

        def get_n_out(self):
            return len(self.sp_out)

        def get_name_in(self, i):
            return self.names_in[i]

        def get_name_out(self, i):
            return self.names_out[i]

        def get_sparsity_in(self, i):
            return self.sp_in[i]

        def get_sparsity_out(self, i):
            return self.sp_out[i]

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            args = [None if a is None else np.frombuffer(a, dtype=np.float64).copy()
                    for a in arg]
            for buf, val in zip(res, self.fn(*args)):
                if buf is not None:
                    np.frombuffer(buf, dtype=np.float64)[:] = val
            return 0

    return _Fn


def solve_stage(problem, x0, n_points=None, *, lam_x0=None, max_iter=200, tol=1e-10,
                termination=SHARED_TERMINATION):
    """Minimise the stage cost with IPOPT (through :func:`~.ipopt.run_nlpsol`, the one
    ``nlpsol`` path), true bounds, exact sparse Hessian; stop at a relatively stationary
    point (:class:`~freqid_casadi.solvers.shared_termination.SharedMonitor`).

    Parameters
    ----------
    problem : SharedProblem
    x0 : ndarray of float, shape (n_vars,)
    n_points : int, optional
        Fit the first ``n_points`` frequencies (the window); default all.
    lam_x0 : ndarray, optional
        Bound multipliers for IPOPT's warm start.
    max_iter : int
        A safety net: the test stops the solve at a relatively stationary point.
    tol : float
        IPOPT's ``tol`` on the objective scaled by 1 / (start cost).
    termination : Termination or None
        The scale-free test checked after every iteration and at the returned point
        (:mod:`~freqid_casadi.solvers.termination`); None: IPOPT's own status only.

    Returns
    -------
    dict
        ``x`` (projected on the bounds), ``lam_x``, ``cost``, ``nit``, ``status`` (IPOPT's
        return_status, "start-stationary" when the start passed the test), ``success``
        (IPOPT converged or the point passes the test), ``stationary`` (the test passed),
        ``message`` (why, with the test's numbers), ``t_solve`` (s, wall), ``c_solve`` (s,
        CPU time of this process: robust to other jobs on the machine), ``t_build`` (s).
    """
    import casadi as ca

    t0 = time.perf_counter()
    n = problem.n_vars
    lb, ub = problem.bounds()
    x0 = np.clip(np.asarray(x0, float), lb, ub)
    monitor = None if termination is None else SharedMonitor(problem, termination, n_points)
    if monitor is not None and monitor.stationary(x0)[0]:
        x0 = monitor.point
        return {"x": x0, "lam_x": np.zeros(n) if lam_x0 is None else np.asarray(lam_x0, float),
                "cost": problem.cost(x0, n_points), "nit": 0, "status": "start-stationary",
                "success": True, "stationary": True, "t_solve": 0.0, "c_solve": 0.0,
                "t_build": time.perf_counter() - t0,
                "message": f"converged: the start is stationary ({monitor.test_text()})"}
    out, rescaled = None, 0
    while True:
        left = int(max_iter) - (out["nit"] if out else 0)
        res = _solve_once(problem, x0, n_points, lam_x0, left, tol, monitor)
        if out is not None:
            res.update(nit=out["nit"] + res["nit"], t_solve=out["t_solve"] + res["t_solve"],
                       c_solve=out["c_solve"] + res["c_solve"],
                       t_build=out["t_build"] + res["t_build"])
            if not res["cost"] <= out["cost"]:
                # the restart lost ground: its start (the previous solve's point) stands
                res.update(x=out["x"], lam_x=out["lam_x"], cost=out["cost"])
        out = res
        if monitor is None or monitor.reason != "rescale" or out["nit"] >= max_iter or \
                rescaled >= MAX_RESTARTS:
            break
        # the cost fell RESCALE-fold: IPOPT's barrier parameter (absolute, on the objective
        # scaled by the start cost) now holds variables far off their bounds; restart there
        x0, lam_x0, rescaled = out["x"], out["lam_x"], rescaled + 1
    out["t_build"] += time.perf_counter() - t0 - out["t_build"] - out["t_solve"]
    out.update(verdict(monitor, out["x"], out["status"]))
    out["cost"] = problem.cost(out["x"], n_points)
    if rescaled:
        note = f" (after {rescaled} rescaled restarts)"
        out.update(status=out["status"] + note, message=out["message"][:-1] + note + ")")
    return out


def _solve_once(problem, x0, n_points, lam_x0, max_iter, tol, monitor):
    """One IPOPT solve from ``x0`` with the objective scaled by 1 / cost(x0) (see
    :func:`solve_stage`; ``monitor`` may stop it, and is armed to stop it once the cost
    has fallen :data:`RESCALE`-fold)."""
    import casadi as ca

    t0 = time.perf_counter()
    n = problem.n_vars
    lb, ub = problem.bounds()
    rows, cols, order = problem.hessian_pattern()
    sp_h = ca.Sparsity.triplet(n, n, rows[order].tolist(), cols[order].tolist())
    Fn = _callbacks()
    dense = ca.Sparsity.dense
    keep = [
        Fn("f", lambda x: [problem.cost(x, n_points)], ["x"], [dense(n, 1)], ["f"],
           [dense(1, 1)], jac=lambda x: [problem.gradient(x, n_points)[1]]),
        Fn("nlp_grad_f", lambda x, p: problem.gradient(x, n_points), ["x", "p"],
           [dense(n, 1), dense(0, 1)], ["f", "grad_f"], [dense(1, 1), dense(n, 1)]),
        Fn("nlp_hess_l", lambda x, p, lf, lg: [lf[0] * problem.hessian_values(x, n_points)
                                               [order]],
           ["x", "p", "lam_f", "lam_g"], [dense(n, 1), dense(0, 1), dense(1, 1),
                                          dense(0, 1)], ["hess_gamma_x_x"], [sp_h])]
    z = ca.MX.sym("z", n)
    ipopt = {"print_level": 0, "sb": "yes", "max_iter": int(max_iter), "tol": float(tol),
             "acceptable_tol": 1e-8, "acceptable_iter": 30, "bound_relax_factor": 0.0,
             "honor_original_bounds": "yes", "bound_push": BOUND_PUSH, "bound_frac": BOUND_PUSH,
             "nlp_scaling_method": "none", **_EXTRA}
    cost0 = problem.cost(x0, n_points)
    if np.isfinite(cost0) and cost0 > 0:
        ipopt["obj_scaling_factor"] = 1.0 / cost0
    if lam_x0 is not None:
        push = warm_push(problem, x0, n_points)
        ipopt.update({"warm_start_init_point": "yes", "warm_start_bound_push": push,
                      "warm_start_bound_frac": push, "warm_start_mult_bound_push": 1e-9,
                      "mu_init": 1e-6})
    opts = {"print_time": False, "error_on_fail": False, "show_eval_warnings": False,
            "grad_f": keep[1],
            "hess_lag": keep[2], "ipopt": ipopt}
    if monitor is not None:
        monitor.arm(RESCALE * cost0)
        keep.append(iteration_callback(monitor, n, 0))
        opts["iteration_callback"] = keep[-1]
    c1 = time.process_time()
    res, stats, t_build, t_solve = run_nlpsol(
        "shared_stage", {"x": z, "f": keep[0](z)}, opts, x0, lb, ub,
        lam_x0=lam_x0, cost_of=lambda x: problem.cost(x, n_points), keep=keep,
        t0=t0)
    c_solve = time.process_time() - c1
    x, lam, cost, status = res.x, res.lam_x, res.cost, res.solver_status
    if not (np.isfinite(cost) and np.all(np.isfinite(x))):
        x, cost, status = x0, cost0, "Invalid_Number_Detected"
    return {"x": x, "lam_x": lam, "cost": cost, "nit": int(stats.get("iter_count", 0)),
            "status": status, "t_solve": t_solve, "c_solve": c_solve, "t_build": t_build}

