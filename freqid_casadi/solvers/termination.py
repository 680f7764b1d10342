"""Scale-free termination of a least-squares stage (layer L3).

IPOPT's tolerances are absolute on its scaled NLP, whose objective scale is fixed at the
stage's start (the cost there). On exact data the cost falls by 10..20 orders within a
stage; the scaled gradient is then dominated by rounding noise, IPOPT's ``tol`` cannot be
met and every such stage ran to its iteration limit.
:class:`StageMonitor` checks a test that is invariant to the scale of the residuals and of
the variables after every IPOPT iteration (a CasADi ``iteration_callback``) and once more
at the returned point, where a point that fails it gets a short Levenberg-Marquardt polish
(:func:`~freqid_casadi.solvers.lm_polish.lm_polish`).
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .. import _interrupt
from .common import Status, TERMINATION_MESSAGES

__all__ = ["Termination", "NoiseStall", "noise_stall_text", "StageMonitor", "free_variables",
           "relative_stationarity", "projected_fraction", "moved_onto_bounds",
           "rounding_level", "hold_tol"]

EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Termination:
    """The stage's termination test.

    A point is *stationary* when the Gauss-Newton model cannot lower the cost by more than
    the fraction ``ftol``: ``||P r||^2 / ||r||^2 <= ftol``, ``P`` the projection onto the
    span of the Jacobian's columns of the free variables (those not held at a bound by the
    gradient, within the tolerance of :func:`hold_tol`). A cheap necessary condition is
    checked first at every iteration: ``max_j cos_j <= sqrt(ftol)``,
    ``cos_j = |J_j^T r| / (||J_j|| ||r||)`` (MINPACK's ``gtol`` measure). Both thresholds
    are raised by ``noise / rms(r)``, the rounding level of a relative residual
    (``noise_factor * eps * n``, n variables): an exact fit at machine precision is
    stationary. A stage with constraints ``g(z) >= 0`` (the damping floor) is tested in
    the KKT form: the active constraints' normals, times nonnegative multipliers, are
    taken off the gradient, and ``P`` projects along the directions that keep the binding
    ones active.

    The stage is *stalled* when the cost fell by less than ``stall_ftol`` (relative) over
    the last ``stall_window`` iterations without being stationary (0: no stall test).

    Parameters
    ----------
    ftol : float
        Largest relative cost decrease the linearised model may still promise.
    noise_factor : float
        Multiplier of the rounding-noise model.
    stall_window : int
        Iterations over which the stall test measures the decrease (0: off).
    stall_ftol : float
        Relative decrease over ``stall_window`` iterations below which the stage stops.
    rcond : float
        Relative singular-value cutoff of the column-scaled Jacobian in ``P``.
    polish_steps : int
        Largest number of LM steps tried at a point that fails the test (0: none).
    onto_bounds : bool
        At a returned point that fails the test, try it with the variables held just
        inside a bound put onto it (:meth:`StageMonitor.decide`); used by
        :func:`~freqid_casadi.fitting.stages.polish`, whose optimum may lie on the root floor.
    newton : bool
        At a returned point that passes the gradient test but not the projection, try
        Newton steps with the exact Hessian (:func:`~.lm_polish.newton_polish`), kept only
        if they reach the test; set for a fit's final stages.
    abandon : (int, float) or None
        ``(k, rms)``: stop at iteration ``k`` when the RMS residual ``sqrt(cost / M)`` is
        still above ``rms`` (a candidate that cannot catch up: its stage returns unsolved,
        ``extra["abandoned"]`` True, without the polish of a stopped stage). None: off.
    noise_stall : NoiseStall or None
        At the end of a stage that fails the test: is it converged to the noise
        (:class:`NoiseStall`)? None: not asked.
    """

    ftol: float = 1e-12
    noise_factor: float = 10.0
    stall_window: int = 0
    stall_ftol: float = 0.0
    rcond: float = 1e-10
    polish_steps: int = 10
    onto_bounds: bool = False
    newton: bool = False
    abandon: tuple = None
    noise_stall: object = None


@dataclass(frozen=True)
class NoiseStall:
    """The test that calls a stage converged to the data's noise.

    On noisy data a fit reaches its optimum only to within the noise: along a valley the
    cost may still fall by a few parts in a million per iteration, a move by a tiny
    fraction of the model's standard errors, and the strict test of :class:`Termination`
    (a Gauss-Newton model that promises at most ``ftol`` = 1e-12 of the cost) then runs the
    stage to its iteration limit, or IPOPT stops at its step tolerance first. Such a stage,
    at its end, is *converged to the noise* when its last ``window`` iterations lowered the
    cost by at most ``chi2`` noise variances, ``(c_old - c) / s^2 <= chi2`` with
    ``s^2 = c / (M ratio^2)`` the noise variance per point that ``ratio`` (the residual's
    RMS over the noise its point-to-point differences show) gives, and its residual is at
    the noise (``ratio <= max_ratio``). A fall of 0.01 noise variances is that of a move by
    a tenth of a standard error along the best-determined direction. Exact data are left to
    the strict test: the test applies only when the RMS residual ``sqrt(c / M)`` is above
    ``rms_floor``. The stage's result stays unconverged (``success`` False, so a fit's
    choice among its candidates is unchanged) and carries the numbers in
    ``extra["noise_stall"]``; the fit's verdict reads them for its final stage.

    Parameters
    ----------
    window : int
        Iterations over which the fall is measured, >= 1.
    chi2 : float
        Largest fall, in noise variances, > 0.
    rms_floor : float
        RMS residual (the stage's units) at or below which the test does not apply.
    noise_ratio : callable
        ``noise_ratio(e) -> float`` for the complex residual ``e`` (M,) in frequency order:
        its RMS over its noise level (NaN when it cannot be estimated).
    max_ratio : float
        Largest ``ratio`` of a residual at the noise.
    """

    window: int
    chi2: float
    rms_floor: float
    noise_ratio: object
    max_ratio: float = 2.0


def _reach(col_norms, distance):
    """First-order residual change ``||J_j|| * distance`` of a move onto a bound; inf for an
    infinite bound (also where ``||J_j|| = 0``: no "invalid value" from ``0 * inf``)."""
    finite = np.isfinite(distance)
    return np.where(finite, col_norms * np.where(finite, distance, 0.0), np.inf)


def moved_onto_bounds(x, grad, col_norms, lb, ub, reach):
    """``x`` with every variable that lies within ``reach / ||J_j||`` of a bound the
    gradient pushes it against put onto that bound, or None when there is none.

    An interior-point method stops ``mu / multiplier`` away from an active bound; moved
    onto it, the variable changes the residual by at most ``reach`` (to first order).

    Parameters
    ----------
    x, grad, col_norms : ndarray of float, shape (n,)
        The point, the cost's gradient and the Jacobian's column norms ``||J_j||``.
    lb, ub : ndarray of float, shape (n,)
        The bounds.
    reach : float
        Largest first-order change of the residual (its units) a move may make.

    Returns
    -------
    ndarray of float, shape (n,), or None
    """
    low = (grad > 0) & (x > lb) & (_reach(col_norms, x - lb) <= reach)
    high = (grad < 0) & (x < ub) & (_reach(col_norms, ub - x) <= reach)
    if not (np.any(low) or np.any(high)):
        return None
    return np.where(low, lb, np.where(high, ub, x))


def free_variables(grad, x, lb, ub, col_norms, norm_r, tol=1e-4):
    """Mask of the variables not held at a bound.

    A variable is held when the gradient points out of the box at its bound and moving
    it onto the bound would change the residual by at most ``tol * norm_r`` (to first
    order, ``col_norms * distance``).

    Parameters
    ----------
    grad, x, lb, ub, col_norms : ndarray of float, shape (n,)
    norm_r : float
        ``||r||``.
    tol : float

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    big = tol * norm_r
    at_lb = (_reach(col_norms, x - lb) <= big) & (grad > 0)
    at_ub = (_reach(col_norms, ub - x) <= big) & (grad < 0)
    return ~(at_lb | at_ub) & (lb < ub)


def _free_one(g, x, lo, hi, cn, big):
    """:func:`free_variables`' rule for one variable (floats; ``big = tol * ||r||``): the
    termination test's fast path asks it of one variable per iteration, where the array
    version's numpy calls cost as much as for all of them."""
    if not lo < hi:
        return False
    at_lb = g > 0 and math.isfinite(x - lo) and cn * (x - lo) <= big
    at_ub = g < 0 and math.isfinite(hi - x) and cn * (hi - x) <= big
    return not (at_lb or at_ub)


def relative_stationarity(grad, col_norms, cost, free, n_points, n_factors):
    """``(max cos_j, noise / rms)`` over the ``free`` variables (see :class:`Termination`).

    Parameters
    ----------
    grad : ndarray (n,)
        ``2 J^T r``.
    col_norms : ndarray (n,)
        ``||J_j||``.
    cost : float
        ``||r||^2``.
    free : ndarray of bool (n,)
    n_points : int
        Number of (complex) residuals.
    n_factors : int
        Size of the rounding model (rounding level ``eps * n_factors``).

    Returns
    -------
    (float, float)
    """
    grad = np.asarray(grad, float)
    use = free & (col_norms > 0)
    norm_r = np.sqrt(max(cost, 0.0))
    if not np.any(use) or norm_r == 0.0:
        return 0.0, np.inf
    cos = np.abs(grad[use]) / (2.0 * col_norms[use] * norm_r)
    return float(np.max(cos)), rounding_level(cost, n_points, n_factors)


def hold_tol(term, noise):
    """Tolerance of :func:`free_variables` in the termination test: a variable is held at
    a bound when putting it there changes the residual by at most ``ftol / 2`` of its norm
    (the cost by at most ``ftol``) or by less than the residual's own rounding error
    (``noise`` of its norm): such a variable is on the bound to working precision.

    Measured at example C's endpoint: four zeros' dampings 4e-17 off their bound 0, put
    onto it, change the residual by 2e-5 of its norm, 1e3 times less than its rounding
    error (3e-2 of its norm there); counted free, their cosines (0.13) failed the test.

    Parameters
    ----------
    term : Termination
    noise : float
        ``noise_factor * rounding_level`` at the point (relative to ``||r||``).

    Returns
    -------
    float
    """
    return max(0.5 * term.ftol, min(noise, 1.0))


def rounding_level(cost, n_points, n_factors):
    """``eps * n_factors / rms(r)``: the relative rounding level of a residual whose
    entries carry errors of about ``eps * n_factors`` each (inf at a zero residual).

    Parameters
    ----------
    cost : float
        ``||r||^2``.
    n_points : int
        Number of (complex) residuals.
    n_factors : int
        Size of the rounding model.

    Returns
    -------
    float
    """
    if cost <= 0.0:
        return np.inf
    return float(EPS * n_factors / np.sqrt(cost / max(n_points, 1)))


def projected_fraction(r, jac, free, rcond=1e-10):
    """``||P r|| / ||r||``: the part of the residual the linearised model can remove.

    Parameters
    ----------
    r : ndarray (m,)
    jac : ndarray (m, n)
    free : ndarray of bool (n,)
    rcond : float
        Singular values of the unit-column Jacobian below ``rcond`` times the largest are
        dropped.

    Returns
    -------
    float
    """
    r = np.asarray(r, float)
    nr = float(np.linalg.norm(r))
    if nr == 0.0 or not np.any(free):
        return 0.0
    a = jac[:, free]
    cn = np.linalg.norm(a, axis=0)
    a = a[:, cn > 0] / cn[cn > 0]
    if a.shape[1] == 0:
        return 0.0
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    u = u[:, sv > rcond * sv[0]]
    return float(np.linalg.norm(u.T @ r)) / nr


class StageMonitor:
    """The :class:`Termination` test of one stage problem.

    Parameters
    ----------
    problem : StageProblem
    term : Termination
    """

    def __init__(self, problem, term):
        self.problem, self.term = problem, term
        self.history = []
        self.reason = None
        self.n_points = None         # complex residuals, from the first residual evaluated
        self.cos = self.allowed = self.proj = self.proj_allowed = float("nan")
        self._sqrt_ftol = np.sqrt(term.ftol)      # the cosine's allowed value's first term
        self._gfun = None            # the constraints' values and Jacobian (CasADi)

    def test_text(self, explain=True):
        """The termination test's numbers for messages (the projection is computed only
        when the cosine test passes); ``explain``: say what a failed projection means (not
        in the message of a stage IPOPT's own tolerance calls converged)."""
        if not np.isfinite(self.proj):
            proj = "||P r||/||r|| not computed (the cosine test fails first)"
        else:
            proj = f"||P r||/||r|| {self.proj:.2g} (allowed {self.proj_allowed:.2g})"
            if explain and self.proj > self.proj_allowed:
                proj += (": the gradient is small, but the Gauss-Newton step promises a "
                         f"{100 * min(self.proj, 1.0) ** 2:.3g} % lower cost")
        return f"max cos(r, J_j) {self.cos:.2g} (allowed {self.allowed:.2g}), {proj}"

    def test_numbers(self):
        """The termination test's numbers at the last point tested (for ``details``):
        ``max_cos`` and ``max_cos_allowed``, ``projection`` and ``projection_allowed``
        (``||P r|| / ||r||``; NaN when the cosine test failed first), ``ftol``, and the
        RMS error's relative fall per iteration over the last ten iterations
        (``rms_fall_per_iteration``, NaN with fewer)."""
        hist = [c for c in self.history if np.isfinite(c) and c > 0]
        fall = float("nan")
        if len(hist) > 10:
            fall = float(1.0 - (hist[-1] / hist[-11]) ** (1.0 / 20.0))   # RMS: sqrt(cost)
        return {"max_cos": float(self.cos), "max_cos_allowed": float(self.allowed),
                "projection": float(self.proj), "projection_allowed": float(self.proj_allowed),
                "ftol": float(self.term.ftol), "rms_fall_per_iteration": fall}

    def _plain(self, ok, ipopt_ok):
        """One plain clause: how the test ended (the numbers go to ``details``)."""
        if ok:
            return "converged (relative stationarity: no step can lower the cost further)"
        if ipopt_ok:
            return "converged (IPOPT's tolerance)"
        if not np.isfinite(self.proj):
            return "not stationary: the gradient is not yet small"
        return ("not stationary: the gradient is small, but a Gauss-Newton step still "
                f"promises a {100 * min(self.proj, 1.0) ** 2:.3g} % lower cost")

    def _noise(self, x, cost):
        """The residual's rounding level times ``noise_factor`` at ``x`` of this cost (the
        first call counts the stage's residuals)."""
        pb = self.problem
        if self.n_points is None:
            self.n_points = max(np.asarray(pb.residual(x), float).size // 2, 1)
        return self.term.noise_factor * rounding_level(cost, self.n_points, pb.n)

    def _free_mask(self, x, cost, grad, cn, noise):
        pb = self.problem
        return free_variables(grad, x, pb.lb, pb.ub, cn, float(np.sqrt(max(cost, 0.0))),
                              hold_tol(self.term, noise))

    def free_mask(self, x, cost, grad, cn):
        """Mask of the variables the test counts as free at ``x`` (its cost, gradient and
        column norms given), shape (n,)."""
        return self._free_mask(x, cost, grad, cn, self._noise(x, cost))

    def stationary(self, x, kkt=False):
        """(stationary?, cost) at ``x``: the cheap cosine test, then the projection; with
        ``kkt``, in the KKT form of a stage with constraints (:meth:`_stationary_kkt`)."""
        pb = self.problem
        # np.clip's numbers in a third of its time (the test runs after every iteration)
        x = np.minimum(np.maximum(np.asarray(x, float), pb.lb), pb.ub)
        cost, grad = pb.eval_gradient(x)
        if not np.isfinite(cost):
            return False, cost
        cn = pb.eval_column_norms(x)
        noise = self._noise(x, cost)
        self.allowed, self.proj = self._sqrt_ftol + noise, float("nan")
        if kkt and pb.constraints is not None:
            return self._stationary_kkt(x, cost, grad, cn, noise), cost
        if self._fails_fast(x, cost, grad, cn, noise):
            return False, cost
        free = self._free_mask(x, cost, grad, cn, noise)
        self.cos, _ = relative_stationarity(grad, cn, cost, free, self.n_points, pb.n)
        if self.cos > self.allowed:
            return False, cost
        if pb.projected_fraction is not None:
            self.proj = float(pb.projected_fraction(x, free, self.term.rcond))
        else:
            r = np.asarray(pb.residual(x), float)
            jac = np.asarray(pb.jacobian(x), float)
            self.proj = projected_fraction(r, jac, free, self.term.rcond)
        self.proj_allowed = float(np.sqrt(self.term.ftol + noise))
        return self.proj <= self.proj_allowed, cost

    def _constraint_values(self, x):
        """(values (m,), Jacobian (m, n)) of the problem's constraints ``g(z) >= 0`` at
        ``x`` (their CasADi function built at the first call)."""
        if self._gfun is None:
            import casadi as ca

            z = ca.SX.sym("z", self.problem.n)
            g = self.problem.constraints(z)
            self._gfun = ca.Function("g", [z], [g, ca.jacobian(g, z)])
        g, jac = self._gfun(x)
        return np.asarray(g.full(), float).reshape(-1), np.asarray(jac.full(), float)

    def _stationary_kkt(self, x, cost, grad, cn, noise):
        """The test at ``x`` of a stage with constraints ``g(z) >= 0`` (the damping floor):
        the KKT form of the bounds' test. A constraint is active when moving onto its
        surface changes the residual by at most ``sqrt(ftol)`` of its norm (to first order,
        as the bounds' :func:`moved_onto_bounds`; an interior point stops just inside it);
        the gradient less the active normals times their nonnegative least-squares
        multipliers takes the gradient's place in the cosine test, and the projection is
        onto the Jacobian's span along the directions that keep the binding constraints
        (positive multipliers) on their surface."""
        from scipy.linalg import null_space
        from scipy.optimize import nnls

        pb = self.problem
        free = self._free_mask(x, cost, grad, cn, noise)
        g, jac_g = self._constraint_values(x)
        norm_r = math.sqrt(max(cost, 0.0))
        an = np.linalg.norm(jac_g, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            # each normal's residual norm (bounded by the columns'), its surface's distance
            dist = np.where(an > 0, np.maximum(g, 0.0) / an, np.inf)
            norms = np.abs(np.where(an[:, None] > 0, jac_g / an[:, None], 0.0)) @ cn
        act = _reach(norms, dist) <= self._sqrt_ftol * norm_r
        a = jac_g[act][:, free]
        lam = nnls(a.T, grad[free])[0] if a.size else np.zeros(0)
        reduced = grad - jac_g[act].T @ lam
        self.cos, _ = relative_stationarity(reduced, cn, cost, free, self.n_points, pb.n)
        if self.cos > self.allowed:
            return False
        r = np.asarray(pb.residual(x), float)
        jac = np.asarray(pb.jacobian(x), float)[:, free]
        binding = a[lam > 0]
        if binding.size:
            jac = jac @ null_space(binding)
        self.proj = projected_fraction(r, jac, np.ones(jac.shape[1], bool), self.term.rcond)
        self.proj_allowed = float(np.sqrt(self.term.ftol + noise))
        return self.proj <= self.proj_allowed

    def _fails_fast(self, x, cost, grad, cn, noise):
        """True when the cosine test fails on the variable of the largest cosine of all
        and that variable is free (:func:`_free_one`): then it is also the largest over the
        free variables (the same number as the full test's, its decision the same) and the
        free mask of every variable is not needed; sets ``cos``. Anything else (a held or
        fixed variable, a zero column, a passing cosine) goes to the full test."""
        # (the ufunc's reduce and the array's own argmax: np.min's and np.argmax's numbers
        # without their Python wrappers, which cost as much as the work on n values)
        if not (cost > 0.0 and np.minimum.reduce(cn) > 0.0):
            return False
        norm_r = math.sqrt(cost)
        cos = np.abs(grad) / (2.0 * cn * norm_r)
        j = int(cos.argmax())
        pb = self.problem
        if not (cos[j] > self.allowed and _free_one(
                float(grad[j]), float(x[j]), float(pb.lb[j]), float(pb.ub[j]),
                float(cn[j]), hold_tol(self.term, noise) * norm_r)):
            return False
        self.cos = float(cos[j])
        return True

    def check(self, x):
        """After an iteration at ``x``: True to stop (stationary, stalled or abandoned)."""
        ok, cost = self.stationary(x)
        if ok:
            self.reason = "stationary"
            return True
        self.history.append(cost)
        # (the first call is IPOPT's iteration 0, the start)
        if self.term.abandon is not None and len(self.history) == self.term.abandon[0] + 1 \
                and np.sqrt(max(cost, 0.0) / (self.n_points or 1)) > self.term.abandon[1]:
            self.reason = "abandoned"
            return True
        w = self.term.stall_window
        if w and len(self.history) > w:
            old = self.history[-w - 1]
            if old - self.history[-1] <= self.term.stall_ftol * old:
                self.reason = "stalled"
                return True
        return False

    def at_noise(self, x):
        """The :class:`NoiseStall` test at the end of a stage that failed the strict test,
        at its returned point ``x``: the numbers (``window``, ``chi2``, ``chi2_allowed``,
        ``noise_ratio``) when it passes, else None."""
        ns, hist = self.term.noise_stall, [c for c in self.history if np.isfinite(c)]
        if ns is None or len(hist) <= ns.window:
            return None
        pb = self.problem
        x = np.clip(np.asarray(x, float), pb.lb, pb.ub)
        r = np.asarray(pb.residual(x), float)
        half = r.size // 2
        cost, m = float(r @ r), max(half, 1)
        if not (np.isfinite(cost) and cost / m > ns.rms_floor ** 2):
            return None                       # exact data: the strict test decides
        ratio = float(ns.noise_ratio(r[:half] + 1j * r[half:]))
        fall = max(hist[-ns.window - 1] - min(hist[-1], cost), 0.0)
        chi2 = fall * m * ratio ** 2 / cost
        if not (np.isfinite(ratio) and ratio <= ns.max_ratio and chi2 <= ns.chi2):
            return None
        return {"window": int(ns.window), "chi2": float(chi2),
                "chi2_allowed": float(ns.chi2), "noise_ratio": ratio}

    def at_start(self, x0, lam_x0, t0):
        """The result of a stage whose start ``x0`` passes the test (no solve).

        Parameters
        ----------
        x0 : ndarray (n,)
        lam_x0 : ndarray (n,) or None
            Bound multipliers of the start (kept).
        t0 : float
            ``time.perf_counter()`` at the start of the stage.

        Returns
        -------
        StageResult
        """
        import time

        from .common import StageResult, find_active_constraints

        pb = self.problem
        x = np.clip(np.asarray(x0, float), pb.lb, pb.ub)
        lam = np.zeros_like(x) if lam_x0 is None else np.asarray(lam_x0, float).copy()
        return StageResult(x=x, cost=pb.eval_cost(x), status=Status.CONVERGED,
                           message="converged: the start is already stationary",
                           extra={"termination": self.test_numbers(), "polish_steps": 0},
                           success=True, nit=0, nfev=1, wall_time=time.perf_counter() - t0,
                           active_mask=find_active_constraints(x, pb.lb, pb.ub, rtol=1e-8),
                           lam_x=lam, solver_status="start stationary")

    def _onto_bounds(self, res):
        """``res`` with the variables that sit just inside a bound the gradient pushes
        them against put onto it, if that does not raise the cost.

        An interior-point method stops ``mu / multiplier`` away from an active bound; the
        test of :func:`free_variables` holds a variable only within ``ftol`` (relative
        cost) of its bound, which that distance may exceed: the optimum on a bound
        (e.g. a root at ``root_floor``) would then never be stationary. A variable is
        moved when the move changes the residual by at most ``sqrt(ftol)`` of its norm
        (to first order, ``||J_j|| * distance``: the test of :func:`free_variables` with a
        looser tolerance); the moved point is kept only if its cost is not higher beyond
        the cost's rounding level (and, in :meth:`decide`, only if it passes the test).
        """
        pb = self.problem
        x = np.clip(np.asarray(res.x, float), pb.lb, pb.ub)
        cost, grad = pb.eval_gradient(x)
        if not np.isfinite(cost) or cost <= 0:
            return res
        y = moved_onto_bounds(x, grad, pb.eval_column_norms(x), pb.lb, pb.ub,
                              np.sqrt(self.term.ftol * cost))
        if y is None:
            return res
        c_y = pb.eval_cost(y)
        # the cost is known to twice the residual's rounding level (relative)
        slack = 2.0 * self.term.noise_factor * rounding_level(cost, self.n_points or 1, pb.n)
        if not (np.isfinite(c_y) and c_y <= cost * (1.0 + slack)):
            return res
        from .common import find_active_constraints

        return dataclasses.replace(res, x=y, cost=c_y, active_mask=find_active_constraints(
            y, pb.lb, pb.ub, rtol=1e-8))

    def decide(self, res):
        """``res`` with the status, success and message of the test at its point, after an
        LM polish (:func:`~.lm_polish.lm_polish`) if the point fails the test.

        Parameters
        ----------
        res : StageResult

        Returns
        -------
        StageResult
        """
        if res.status == Status.ERROR:
            return res
        if self.reason == "abandoned":
            return dataclasses.replace(
                res, status=Status.STALLED, success=False,
                message=f"abandoned after {int(res.nit)} iterations: still above the "
                        "candidate it had to beat", extra=dict(res.extra or {}, abandoned=True))
        nit0 = int(res.nit)              # the solver's own iterations (the rest: polish)
        ok, _ = self.stationary(res.x)
        if not ok and self.problem.constraints is not None:
            # the KKT form decides at the returned point only: after every iteration the
            # plain test runs, so IPOPT's path within the stage is as before
            ok, _ = self.stationary(res.x, kkt=True)
        if not ok and self.term.onto_bounds:
            snapped = self._onto_bounds(res)
            if snapped is not res and self.stationary(snapped.x)[0]:
                res, ok = snapped, True
        # (the polish keeps only the bounds: not with constraints such as a damping floor)
        if not ok and self.term.polish_steps and self.problem.constraints is None:
            from .lm_polish import lm_polish

            x, steps = lm_polish(self.problem, res.x, lambda v: self.stationary(v)[0],
                                 max_steps=self.term.polish_steps)
            if steps:
                res = dataclasses.replace(res, x=x, cost=self.problem.eval_cost(x),
                                          nit=res.nit + steps)
                ok, _ = self.stationary(x)
            if not ok and self.term.newton and self.cos <= self.allowed:
                res, ok = self._newton(res)
        ipopt_ok = res.status in (Status.CONVERGED, Status.ACCEPTABLE)
        extra = dict(res.extra or {}, termination=self.test_numbers(),
                     polish_steps=int(res.nit - nit0), ipopt_iterations=int(nit0))
        if ok or ipopt_ok:
            status = res.status if ipopt_ok else Status.CONVERGED
            return dataclasses.replace(res, status=status, success=True,
                                       message=self._plain(ok, ipopt_ok), extra=extra)
        status = Status.STALLED if self.reason == "stalled" else res.status
        if status in (Status.CONVERGED, Status.ACCEPTABLE, Status.COST_TOL):
            status = Status.SMALL_STEP
        steps = extra["polish_steps"]
        its = (f"{nit0} iteration{'s' * (nit0 != 1)}"
               + (f" and {steps} polish step{'s' * (steps != 1)}" if steps else ""))
        msg = f"{TERMINATION_MESSAGES[status]} after {its}; {self._plain(False, False)}"
        noise = self.at_noise(res.x)
        if noise is not None:
            # (the stage stays unconverged for the fit's choices among its candidates; the
            # fit's verdict reads this: see freqid_casadi.fitting._checks.success_of)
            extra["noise_stall"] = noise
            msg = f"{msg}; {noise_stall_text(noise)}"
        return dataclasses.replace(res, status=status, success=False, message=msg,
                                   extra=extra)

    def _newton(self, res):
        """``(res, ok)`` after Newton steps (:func:`~.lm_polish.newton_polish`) from a point
        that passes the gradient test but not the projection; the steps are kept only if
        they end at a point that passes the test."""
        from .lm_polish import newton_polish

        x, steps = newton_polish(self.problem, res.x, lambda v: self.stationary(v)[0],
                                 self.term.polish_steps, self.free_mask)
        if steps and self.stationary(x)[0]:
            return dataclasses.replace(res, x=x, cost=self.problem.eval_cost(x),
                                       nit=res.nit + steps), True
        self.stationary(res.x)                  # (the message's numbers at res.x)
        return res, False


def noise_stall_text(numbers):
    """The plain clause of a stage converged to the noise (:class:`NoiseStall`).

    Parameters
    ----------
    numbers : dict
        The stage's ``extra["noise_stall"]``: ``window``, ``chi2``, ``chi2_allowed``,
        ``noise_ratio``.

    Returns
    -------
    str
    """
    return (f"converged to the noise (the last {numbers['window']} iterations lowered the "
            f"cost by {numbers['chi2']:.2g} noise variances, at most "
            f"{numbers['chi2_allowed']:.2g}: a move far below the fit's standard errors; "
            f"the residual at the noise, RMS {numbers['noise_ratio']:.3g} times it)")


def iteration_callback(monitor, n, ng):
    """A CasADi ``iteration_callback`` running ``monitor.check`` after every IPOPT
    iteration (a nonzero return stops IPOPT with ``User_Requested_Stop``); a signal
    (Ctrl-C, SIGTERM) stops it too (:func:`freqid_casadi._interrupt.stop_callback`).

    Parameters
    ----------
    monitor : StageMonitor
    n, ng : int
        Numbers of variables and constraints of the NLP.

    Returns
    -------
    casadi.Callback
    """
    return _interrupt.stop_callback(n, ng, monitor.check)
