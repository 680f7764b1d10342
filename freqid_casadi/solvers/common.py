"""Result type and small kernels shared by the stage solvers (layer L3).

Solvers return a frozen :class:`StageResult` whose field names follow scipy's
``OptimizeResult``; ``status`` is a :class:`Status` and :data:`TERMINATION_MESSAGES` maps it
to text, as scipy's ``least_squares`` does.
"""

import enum
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Status", "TERMINATION_MESSAGES", "StageResult", "find_active_constraints"]


class Status(enum.IntEnum):
    """Why a stage solver stopped. Values >= 0 mean a usable point was returned."""

    ERROR = -2                #: evaluation error (NaN/inf) or the solver raised
    FAILED = -1               #: the solver reported failure (restoration failed, ...)
    CONVERGED = 0             #: converged to the requested tolerance
    ACCEPTABLE = 1            #: converged to the relaxed ("acceptable") tolerance
    MAX_ITER = 2              #: iteration or evaluation limit reached
    SMALL_STEP = 3            #: steps became too small to make progress
    COST_TOL = 4              #: the cost fell below its tolerance


TERMINATION_MESSAGES = {
    Status.ERROR: "evaluation error: the residuals or their derivatives were not finite",
    Status.FAILED: "the solver failed (see solver_status)",
    Status.CONVERGED: "converged: optimality tolerance satisfied",
    Status.ACCEPTABLE: "converged to the acceptable (relaxed) tolerance",
    Status.MAX_ITER: "iteration limit reached",
    Status.SMALL_STEP: "stopped: step smaller than the step tolerance",
    Status.COST_TOL: "converged: cost below its tolerance",
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
