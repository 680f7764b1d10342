"""A bounded Levenberg-Marquardt polish of a least-squares stage (layer L3).

Near a zero-residual optimum the Gauss-Newton model is exact to second order and LM steps
converge fast where an interior-point method is held back by its barrier (a variable whose
optimum is on its bound, e.g. a delay of 0, stays ``mu / gradient`` away from it) or by an
objective scaling fixed at the stage's start. The polish runs after the IPOPT solve when its
point fails the stage's termination test
(:class:`~freqid_casadi.solvers.termination.StageMonitor`); each step keeps the variables
strictly inside their bounds (fraction to the boundary 0.99); it stops as soon as a step is slow (the regime of a flat valley, where it would
only creep).
"""

import numpy as np

__all__ = ["lm_polish"]


def lm_polish(problem, x, is_stationary, max_steps=10, fast=0.5):
    """Improve ``x`` by projected LM steps until ``is_stationary(x)`` or no fast progress.

    Parameters
    ----------
    problem : StageProblem
        ``residual``, ``jacobian``, ``eval_cost`` and the bounds ``lb``, ``ub``.
    x : ndarray of float, shape (n,)
        Start (clipped into the bounds).
    is_stationary : callable
        ``x -> bool``, the stage's termination test.
    max_steps : int
        Accepted plus rejected steps.
    fast : float
        Stop after an accepted step that lowered the cost by less than this fraction.

    Returns
    -------
    (ndarray (n,), int)
        The best point (never worse than ``x``) and the number of steps tried.
    """
    lb, ub = problem.lb, problem.ub
    x = np.clip(np.asarray(x, float), lb, ub)
    cost = problem.eval_cost(x)
    if not np.isfinite(cost):
        return x, 0
    lam, steps, fails = 1e-3, 0, 0
    while steps < max_steps and fails < 8:
        steps += 1
        r = np.asarray(problem.residual(x), float)
        jac = np.asarray(problem.jacobian(x), float)
        g = jac.T @ r
        d2 = np.einsum("ij,ij->j", jac, jac)
        held = ((x <= lb) & (g > 0)) | ((x >= ub) & (g < 0)) | (lb >= ub) | (d2 <= 0)
        free = ~held
        if not np.any(free):
            break
        a = jac[:, free] / np.sqrt(d2[free])
        # (A^T A + lam I) s = -A^T r (A: unit columns) through the eigenvectors of A^T A
        w, v = np.linalg.eigh(a.T @ a)
        step = np.zeros_like(x)
        step[free] = -(v @ ((v.T @ (a.T @ r)) / (np.maximum(w, 0.0) + lam))) / np.sqrt(d2[free])
        # fraction to the boundary (as IPOPT's tau = 0.99): a variable inside its bounds
        # stays strictly inside (a damping of exactly 0 is a root on the axis)
        step = np.clip(step, -0.99 * (x - lb), 0.99 * (ub - x))
        x_new = x + step
        c_new = problem.eval_cost(x_new)
        if np.isfinite(c_new) and c_new < cost:
            slow = c_new > (1.0 - fast) * cost
            x, cost = x_new, c_new
            lam, fails = max(lam / 10.0, 1e-15), 0
            if is_stationary(x) or slow:
                break
        else:
            lam, fails = lam * 10.0, fails + 1
    return x, steps
