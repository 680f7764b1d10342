"""A bounded Levenberg-Marquardt polish of a least-squares stage (layer L3).

Near a zero-residual optimum the Gauss-Newton model is exact to second order and LM steps
converge fast where an interior-point method is held back by its barrier (a variable whose
optimum is on its bound, e.g. a delay of 0, stays ``mu / gradient`` away from it) or by an
objective scaling fixed at the stage's start (the gradient's rounding noise exceeds the
scaled tolerance once the cost has fallen by many orders). The polish runs after the IPOPT
solve when its point fails the relative stationarity test, on the stage's own residual and
Jacobian, with the bounds kept by projection.
"""

import numpy as np

__all__ = ["lm_polish"]


def lm_polish(funcs, x, lb, ub, is_stationary, max_steps=10, fast=0.5):
    """Improve ``x`` by projected LM steps until ``is_stationary(x)`` or no progress.

    Parameters
    ----------
    funcs : objective.StageFunctions
        ``residual_jacobian(z) -> (r (2M,), J (2M, n))`` and ``cost(z)``.
    x, lb, ub : ndarray of float, shape (n,)
        Start (feasible) and bounds.
    is_stationary : callable
        ``x -> bool``, the stage's termination test.
    max_steps : int
        Accepted plus rejected steps.
    fast : float
        The polish stops after an accepted step that lowered the cost by less than this
        fraction: it is meant for the fast (Gauss-Newton) regime near a small-residual
        optimum, not to creep along a flat valley.

    Returns
    -------
    (ndarray (n,), int)
        The best point (never worse than ``x``) and the number of steps tried.
    """
    x = np.clip(np.asarray(x, float), lb, ub)
    cost = funcs.cost(x)
    if not np.isfinite(cost) or is_stationary(x):
        return x, 0
    lam = 1e-3
    steps = 0
    fails = 0
    while steps < max_steps and fails < 8:
        steps += 1
        r, jac = funcs.residual_jacobian(x)
        g = jac.T @ r
        d2 = np.einsum("ij,ij->j", jac, jac)
        held = (((x <= lb) & (g > 0)) | ((x >= ub) & (g < 0))) | (lb >= ub) | (d2 <= 0)
        free = ~held
        a = jac[:, free] / np.sqrt(d2[free])
        # (A^T A + lam I) s = -A^T r (A: unit columns) through the eigenvectors of A^T A
        w, v = np.linalg.eigh(a.T @ a)
        step_s = -(v @ ((v.T @ (a.T @ r)) / (np.maximum(w, 0.0) + lam)))
        step = np.zeros_like(x)
        step[free] = step_s / np.sqrt(d2[free])
        x_new = np.clip(x + step, lb, ub)
        c_new = funcs.cost(x_new)
        if np.isfinite(c_new) and c_new < cost:
            slow = c_new > (1.0 - fast) * cost
            x, cost = x_new, c_new
            lam = max(lam / 10.0, 1e-15)
            fails = 0
            if is_stationary(x) or slow:
                break
        else:
            lam *= 10.0
            fails += 1
    return x, steps
