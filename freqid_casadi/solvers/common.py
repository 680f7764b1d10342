"""Result type and small kernels shared by the stage solvers (layer L3).

Solvers return a frozen :class:`StageResult` whose field names follow scipy's
``OptimizeResult``; ``status`` is a :class:`Status` and :data:`TERMINATION_MESSAGES` maps it
to text, as scipy's ``least_squares`` does.
"""

import enum
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Status", "TERMINATION_MESSAGES", "StageResult", "find_active_constraints",
           "Termination", "relative_stationarity", "free_variables", "projected_fraction"]


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
    Status.STALLED: "stopped: the cost decreased by less than its relative tolerance over "
                    "the last iterations, but the point is not stationary",
}

SUCCESS_STATUSES = frozenset({Status.CONVERGED, Status.ACCEPTABLE, Status.SMALL_STEP,
                              Status.COST_TOL})


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
        ``status`` is one of CONVERGED, ACCEPTABLE, SMALL_STEP, COST_TOL.
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


EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class Termination:
    """Scale-free termination test of a least-squares stage (the relative residuals ``r``
    are dimensionless; the test is invariant to the scale of each variable).

    A point is *stationary* when the Gauss-Newton model cannot lower the cost by more than
    the fraction ``ftol``: ``||P r||^2 / ||r||^2 <= ftol``, ``P`` the projection onto the
    range of the Jacobian's columns of the free variables (those not held at a bound by the
    gradient). A cheap necessary condition is checked first at every iteration:
    ``max_j cos_j <= sqrt(ftol)``, with ``cos_j = |J_j^T r| / (||J_j|| ||r||)`` (MINPACK's
    ``gtol`` measure). Both thresholds are raised by ``noise / rms(r)``, the rounding level
    of a relative residual (``noise_factor * eps * n_factors``): an exact fit at machine
    precision is stationary.

    The stage is *stalled* when the cost fell by less than ``stall_ftol`` (relative) over
    the last ``stall_window`` iterations without being stationary (0: no stall test).

    Attributes
    ----------
    ftol : float
    noise_factor : float
    stall_window : int
    stall_ftol : float
    rcond : float
        Relative singular-value cutoff of the column-scaled Jacobian in ``P``.
    """

    ftol: float = 1e-8
    noise_factor: float = 10.0
    stall_window: int = 0
    stall_ftol: float = 0.0
    rcond: float = 1e-10


def free_variables(grad, x, lb, ub, col_norms, norm_r, tol=1e-4):
    """Mask of the variables not held at a bound: a variable is held when the gradient
    ``grad`` points out of the box at its bound and moving it onto the bound would change
    the residual by at most ``tol * norm_r`` (``col_norms * distance``, to first order)."""
    big = tol * norm_r
    at_lb = (col_norms * (x - lb) <= big) & (grad > 0)
    at_ub = (col_norms * (ub - x) <= big) & (grad < 0)
    return ~(at_lb | at_ub) & (lb < ub)


def relative_stationarity(grad, col_norms, cost, free, n_points, n_factors):
    """``(max cos_j, noise / rms)`` over the ``free`` variables (see :class:`Termination`).

    Parameters
    ----------
    grad : ndarray (n,)
        ``2 J^T r``.
    col_norms : ndarray (n,)
        ``||J_j||``.
    cost : float
        ``||r||^2`` (2M real residuals for M points).
    free : ndarray of bool (n,)
    n_points : int
    n_factors : int
        Number of factors multiplied to form a residual (rounding model).
    """
    grad = np.asarray(grad, float)
    use = free & (col_norms > 0)
    norm_r = np.sqrt(max(cost, 0.0))
    if not np.any(use) or norm_r == 0.0:
        return 0.0, np.inf
    cos = np.abs(grad[use]) / (2.0 * col_norms[use] * norm_r)
    rms = norm_r / np.sqrt(max(n_points, 1))
    return float(np.max(cos)), float(EPS * n_factors / rms)


def projected_fraction(r, jac, free, rcond=1e-10):
    """``||P r|| / ||r||``: the part of the residual the linearised model can remove, ``P``
    the projection onto the span of the free columns of ``jac`` (columns scaled to unit
    norm; singular values below ``rcond`` times the largest dropped)."""
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
