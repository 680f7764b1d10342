"""The stage-solver contract and small kernels shared by the stage solvers (layer L3).

Both stage solvers (:func:`~freqid_casadi.solvers.ipopt.solve_stage`, IPOPT with true
bounds, and :func:`~freqid_casadi.solvers.barrier_lm.solve_stage_lm`, the thesis's
barrier + LM) take a frozen :class:`StageProblem` of numpy callables and a start, reject an
infeasible start with :class:`InfeasibleStartError` (:func:`check_start`), and return a
frozen :class:`StageResult` whose field names follow scipy's ``OptimizeResult``; ``status``
is a :class:`Status`, :data:`TERMINATION_MESSAGES` maps it to text, as scipy's
``least_squares`` does, and :func:`is_success` is the one success rule.
"""

import enum
from dataclasses import dataclass, field

import numpy as np

from ..errors import DataError, SolverError

__all__ = ["Status", "TERMINATION_MESSAGES", "SUCCESS_STATUSES", "StageResult",
           "StageProblem", "InfeasibleStartError", "check_start", "is_success",
           "find_active_constraints"]


class Status(enum.IntEnum):
    """Why a stage solver stopped. Values >= 0 mean a usable point was returned."""

    ERROR = -2                #: evaluation error (NaN/inf) or the solver raised
    FAILED = -1               #: the solver reported failure (restoration failed, ...)
    CONVERGED = 0             #: converged to the requested tolerance
    ACCEPTABLE = 1            #: converged to the relaxed ("acceptable") tolerance
    MAX_ITER = 2              #: iteration or evaluation limit reached
    SMALL_STEP = 3            #: steps became too small to make progress
    COST_TOL = 4              #: the cost fell below its tolerance
    STALLED = 5               #: the cost stopped decreasing (relative), not stationary


TERMINATION_MESSAGES = {
    Status.ERROR: "evaluation error: the residuals or their derivatives were not finite",
    Status.FAILED: "the solver failed (see solver_status)",
    Status.CONVERGED: "converged: optimality tolerance satisfied",
    Status.ACCEPTABLE: "converged to the acceptable (relaxed) tolerance",
    Status.MAX_ITER: "iteration limit reached",
    Status.SMALL_STEP: "stopped: step smaller than the step tolerance",
    Status.COST_TOL: "converged: cost below its tolerance",
    Status.STALLED: "stopped: the cost fell by less than its relative tolerance over the "
                    "last iterations, at a point that is not stationary",
}

#: The statuses that count as success (:func:`is_success`), for every stage solver.
SUCCESS_STATUSES = frozenset({Status.CONVERGED, Status.ACCEPTABLE, Status.SMALL_STEP,
                              Status.COST_TOL})


def is_success(status):
    """The one success rule of the stage solvers: ``status`` in :data:`SUCCESS_STATUSES`.

    Parameters
    ----------
    status : Status

    Returns
    -------
    bool
    """
    return Status(status) in SUCCESS_STATUSES


class InfeasibleStartError(SolverError, DataError):
    """A stage solver was started outside its bounds (or, for the barrier method, on a
    bound). Also a DataError: the start is bad input to the solver."""


def check_start(x0, lb, ub, *, strict=False):
    """Check a start against its bounds.

    Parameters
    ----------
    x0 : array_like of float, shape (n,)
    lb, ub : float or array_like of float, shape (n,)
        Bounds (``-inf``/``inf`` for none).
    strict : bool
        Require ``lb < x0`` where ``lb < ub`` (a barrier method's interior start).

    Returns
    -------
    x0, lb, ub : ndarray of float, shape (n,)

    Raises
    ------
    DataError
        ``x0`` empty, not 1-D or not finite; bounds of another shape or NaN.
    InfeasibleStartError
        A component outside ``[lb, ub]`` (or on a lower bound with ``strict``).
    """
    try:
        x = np.array(x0, dtype=float).reshape(-1) if np.ndim(x0) <= 1 else None
    except (TypeError, ValueError):
        x = None
    if x is None or x.size == 0:
        raise DataError(f"x0 must be a non-empty real 1-D array, got {x0!r}")
    if not np.all(np.isfinite(x)):
        i = int(np.flatnonzero(~np.isfinite(x))[0])
        raise DataError(f"x0 must be finite: x0[{i}]={x[i]}; give a finite starting point")
    try:
        lbv = np.array(np.broadcast_to(np.asarray(lb, float), x.shape))
        ubv = np.array(np.broadcast_to(np.asarray(ub, float), x.shape))
    except (TypeError, ValueError):
        raise DataError(f"lb and ub must be scalars or arrays of shape {x.shape}, got "
                        f"{np.shape(lb)} and {np.shape(ub)}") from None
    bad = np.flatnonzero(np.isnan(lbv) | np.isnan(ubv) | (lbv > ubv) | (lbv == np.inf)
                         | (ubv == -np.inf))
    if bad.size:
        i = int(bad[0])
        raise DataError(f"bounds lb[{i}]={lbv[i]}, ub[{i}]={ubv[i]} are not valid: they must "
                        "not be NaN and lb <= ub, lb < inf, ub > -inf; use -inf/inf for no "
                        "bound")
    low = (x <= lbv) & (lbv < ubv) if strict else x < lbv
    bad = np.flatnonzero(low | (x > ubv))
    if bad.size:
        i = int(bad[0])
        raise InfeasibleStartError(
            f"the start is infeasible: x0[{i}]={x[i]:g} with bounds [{lbv[i]:g}, {ubv[i]:g}]"
            + ("; the barrier method needs a start strictly above lb" if strict else "")
            + f"; move x0[{i}] inside (e.g. np.clip(x0, lb, ub)"
            + (" plus a small margin above lb)" if strict else ")"))
    return x, lbv, ubv


#: From this many points on, IPOPT evaluates a stage's objective through a callback of
#: ``StageFunctions.nlp_cost`` (the same value bit for bit) instead of an MX expression in
#: the NLP: building the solver around the MX expression costs O(M) per stage (measured,
#: CPU: 36 -> 20 ms per stage at 5000 points, 0.24 s -> 2 ms at 200 000), while below
#: ~1000 points the callback's Python call per evaluation costs more than it saves.
CALLBACK_COST_POINTS = 1000
#: From this many points on, the termination test takes ``||P r|| / ||r||`` from the stage
#: functions' blockwise QR (``StageFunctions.projected_fraction``: O(block x n) memory, the
#: same number to rounding) instead of an SVD of the whole Jacobian (at 200 000 points and
#: 14 variables about 125 MiB and 0.4 s per test); below it, the SVD as before, bit for bit.
BLOCKWISE_PROJECTION_POINTS = 8192


@dataclass(frozen=True, eq=False)
class StageProblem:
    """A stage's least-squares problem ``min ||r(z)||^2, lb <= z <= ub [, g(z) >= 0]``
    as numpy callables: what both stage solvers accept.

    Attributes
    ----------
    residual : callable ``residual(z) -> ndarray of float, shape (m,)``
        Real residual ``r`` (complex residuals stacked as ``[Re; Im]``).
    jacobian : callable ``jacobian(z) -> ndarray of float, shape (m, n)``
        ``dr/dz``.
    lb, ub : ndarray of float, shape (n,)
        Bounds (``-inf``/``inf`` for none; ``lb == ub`` fixes a variable).
    gradient : callable ``gradient(z) -> (cost, ndarray shape (n,))``, optional
        Cost ``r.r`` and its gradient ``2 J^T r``; default from ``residual``/``jacobian``.
    hessian : callable ``hessian(z, exact=True) -> ndarray shape (n, n)``, optional
        Hessian of the cost (``exact=False``: Gauss-Newton ``2 J^T J``); default
        Gauss-Newton from ``jacobian``.
    cost : callable ``cost(z) -> float``, optional
        ``r.r``; default from ``residual``.
    constraints : callable, optional
        ``g(z) >= 0`` on a CasADi vector (IPOPT only; e.g. the damping floor).
    casadi_residual : casadi.Function, optional
        ``r`` as a CasADi Function: IPOPT then builds its objective from it; else the
        objective is a callback of ``cost``.
    projected_fraction : callable ``projected_fraction(z, free, rcond) -> float``, optional
        ``||P r|| / ||r||`` of the termination test (:func:`~.termination.
        projected_fraction`) without the caller forming the Jacobian; default from
        ``residual`` and ``jacobian``.
    column_norms : callable ``column_norms(z) -> ndarray shape (n,)``, optional
        ``||J_j||`` (cheap to give: the termination test asks for it after every
        iteration); default from ``jacobian``.
    nlp_cost : callable ``nlp_cost(z) -> float``, optional
        IPOPT's objective, ``sumsqr(casadi_residual(z))`` evaluated numerically (IPOPT
        then calls it through a callback instead of an MX expression of
        ``casadi_residual``, whose solver is slow to build at many points).
    """

    residual: object
    jacobian: object
    lb: np.ndarray
    ub: np.ndarray
    gradient: object = None
    hessian: object = None
    cost: object = None
    constraints: object = None
    casadi_residual: object = None
    column_norms: object = None
    nlp_cost: object = None
    projected_fraction: object = None

    def __post_init__(self):
        for name in ("residual", "jacobian"):
            if not callable(getattr(self, name)):
                raise DataError(f"StageProblem.{name} must be callable, got "
                                f"{type(getattr(self, name)).__name__}")
        lb = np.array(self.lb, float).reshape(-1)
        ub = np.array(np.broadcast_to(np.asarray(self.ub, float), lb.shape))
        object.__setattr__(self, "lb", lb)
        object.__setattr__(self, "ub", ub)
        # the last (z, cost, gradient): IPOPT's grad_f and the termination test after the
        # iteration ask for the same point (one gradient product per iteration, not two)
        object.__setattr__(self, "_last_gradient", (None, None, None))

    @property
    def n(self):
        """Number of variables."""
        return self.lb.size

    def eval_cost(self, z):
        """``r(z).r(z)``."""
        if self.cost is not None:
            return float(self.cost(z))
        r = np.asarray(self.residual(z), float)
        return float(r @ r)

    def eval_gradient(self, z):
        """``(cost, gradient)`` at ``z`` (the gradient a new array the caller may keep;
        the last point's values are reused: the same numbers)."""
        key = np.asarray(z, float).tobytes()
        last, cost, grad = self._last_gradient
        if key != last:
            if self.gradient is not None:
                cost, grad = self.gradient(z)
            else:
                r = np.asarray(self.residual(z), float)
                cost, grad = float(r @ r), 2.0 * np.asarray(self.jacobian(z), float).T @ r
            object.__setattr__(self, "_last_gradient", (key, cost, grad))
        return cost, np.array(grad, float)

    def eval_column_norms(self, z):
        """``||J_j||`` at ``z``, ndarray (n,)."""
        if self.column_norms is not None:
            return np.asarray(self.column_norms(z), float)
        return np.linalg.norm(np.asarray(self.jacobian(z), float), axis=0)

    def eval_hessian(self, z, exact=True):
        """Hessian of the cost at ``z`` (Gauss-Newton when no ``hessian`` was given)."""
        if self.hessian is not None:
            return self.hessian(z, exact=exact)
        J = np.asarray(self.jacobian(z), float)
        return 2.0 * J.T @ J

    @classmethod
    def from_stage_functions(cls, funcs, lb, ub, constraints=None):
        """The problem of an :class:`~freqid_casadi.core.objective.StageFunctions` (its exact
        structured derivatives and its CasADi residual)."""
        nlp_cost = (getattr(funcs, "nlp_cost", None)
                    if getattr(funcs, "n_points", 0) >= CALLBACK_COST_POINTS else None)
        return cls(residual=funcs.residual,
                   jacobian=lambda z: funcs.residual_jacobian(z)[1],
                   lb=lb, ub=ub, gradient=funcs.gradient,
                   hessian=lambda z, exact=True: funcs.hessian(z, exact=exact),
                   cost=funcs.cost, constraints=constraints,
                   # the MX residual only where IPOPT's objective is built from it (asking
                   # for it builds it)
                   casadi_residual=(getattr(funcs, "r_fun", None) if nlp_cost is None
                                    else None),
                   column_norms=getattr(funcs, "column_norms", None),
                   nlp_cost=nlp_cost,
                   projected_fraction=(getattr(funcs, "projected_fraction", None)
                                       if getattr(funcs, "n_points", 0)
                                       >= BLOCKWISE_PROJECTION_POINTS else None))


@dataclass(frozen=True)
class StageResult:
    """Outcome of one stage solve (one NLP).

    Attributes
    ----------
    x : ndarray of float, shape (n,)
        Solution in the solver's own variables (feasible: within the bounds exactly).
    cost : float
        Objective at ``x``: the (weighted) sum of squared relative residuals.
    status : Status
    message : str
    success : bool
        :func:`is_success` of ``status`` (CONVERGED, ACCEPTABLE, SMALL_STEP, COST_TOL).
    nit : int
        Iterations (IPOPT iterations, or LM inner iterations summed over outer steps).
    nfev : int
        Objective/residual evaluations.
    wall_time : float
        Seconds spent in the solver, including building it.
    active_mask : ndarray of int, shape (n,)
        -1 where ``x`` is at (or within a relative tolerance of) its lower bound,
        +1 at its upper bound, 0 otherwise (scipy's ``find_active_constraints``).
    lam_x : ndarray of float, shape (n,)
        Bound multipliers (negative for an active lower bound, CasADi's convention); zeros
        where the solver has none.
    solver_status : str
        The solver's own return status (e.g. IPOPT's ``Solve_Succeeded``).
    extra : dict
        Solver-specific numbers (IPOPT: timings; barrier-LM: its outer-loop history).
    """

    x: np.ndarray
    cost: float
    status: Status
    message: str
    success: bool
    nit: int
    nfev: int
    wall_time: float
    active_mask: np.ndarray
    lam_x: np.ndarray
    solver_status: str = ""
    extra: dict = field(default_factory=dict)


def find_active_constraints(x, lb, ub, rtol=1e-10):
    """Which bounds are active: -1 at the lower, +1 at the upper bound, 0 otherwise.

    A bound counts as active when ``x`` is within ``rtol * max(1, |bound|)`` of it, as in
    scipy ``optimize/_lsq/common.py``.

    Parameters
    ----------
    x : array_like of float, shape (n,)
    lb, ub : float or array_like of float, shape (n,)
    rtol : float
        Relative tolerance (0: exactly on the bound).

    Returns
    -------
    ndarray of int, shape (n,)
    """
    x = np.asarray(x, float)
    lb = np.broadcast_to(np.asarray(lb, float), x.shape)
    ub = np.broadcast_to(np.asarray(ub, float), x.shape)
    active = np.zeros(x.shape, dtype=int)
    if rtol == 0:
        active[x <= lb] = -1
        active[x >= ub] = 1
        return active
    lower_dist = x - lb
    upper_dist = ub - x
    lower_thr = rtol * np.maximum(1, np.abs(lb))
    upper_thr = rtol * np.maximum(1, np.abs(ub))
    lower_active = np.isfinite(lb) & (lower_dist <= np.minimum(upper_dist, lower_thr))
    active[lower_active] = -1
    upper_active = np.isfinite(ub) & (upper_dist <= np.minimum(lower_dist, upper_thr))
    active[upper_active] = 1
    return active
