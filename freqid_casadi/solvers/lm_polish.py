"""A bounded Levenberg-Marquardt polish of a least-squares stage (layer L3).

Near a zero-residual optimum the Gauss-Newton model is exact to second order and LM steps
converge fast where an interior-point method is held back by its barrier (a variable whose
optimum is on its bound, e.g. a delay of 0, stays ``mu / gradient`` away from it) or by an
objective scaling fixed at the stage's start. The polish runs after the IPOPT solve when its
point fails the stage's termination test
(:class:`~freqid_casadi.solvers.termination.StageMonitor`); each step keeps the variables
strictly inside their bounds (fraction to the boundary 0.99); it stops as soon as a step
is slow (the regime of a flat valley, where it would only creep).

Away from a zero residual, Gauss-Newton misjudges the directions the data barely determine:
there ``J^T J`` is tiny (singular values of the scaled Jacobian down to 1e-10 of the
largest) and the second-order term ``sum_i r_i grad^2 r_i`` of the Hessian dominates, so
a Gauss-Newton step overshoots and LM creeps. :func:`newton_polish` then takes Newton steps
with the exact Hessian (Jacobi scaled; curvature below its rounding level floored there,
negative curvature by its magnitude, so every step descends), with backtracking. It runs
only at the end of a fit's final stages (``Termination.newton``; inside the loop it would
change the path of the stages after it). Measured on example A at 10 sections: the final
stage ended at IPOPT's limit with the gradient test passed (max cos 3.1e-8) but
||P r||/||r|| 0.58; four Newton steps lower the cost by 3e-8 (relative) and ||P r||/||r||
to 2.7e-8. Its steps stay inside the box, so an optimum on a bound is not reached (A at 9
sections). Steps projected onto the box do reach those. But on the actuator at 3 sections
they put a denominator's leading coefficient onto 0, a pole at infinity that trades
against the delay. The covariance holds that coefficient there and reported the delay as
determined, 9.2 +- 0.4 ms against 7.0 ms at 2 sections, where it is not.
"""

import numpy as np

__all__ = ["lm_polish", "newton_polish"]


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
        free = _not_held(x, g, lb, ub) & ~(d2 <= 0)
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


def newton_polish(problem, x, is_stationary, max_steps=10, free_mask=None):
    """Improve ``x`` by Newton steps with the exact Hessian until ``is_stationary(x)``, a
    step that lowers the cost cannot be found, or ``max_steps`` (see the module docstring).

    The variables not in ``free_mask(x)`` stay where they are; the others are scaled by the
    Jacobian's column norms ``||J_j||``. In the eigenvectors of the scaled Hessian a
    curvature ``|lambda|`` below ``nu = 10 eps n max|lambda|`` (its rounding level) counts as
    ``nu`` and a negative one as ``|lambda|``, so the step descends; it is tried at full
    length, then 1/4, 1/16 and 1/64, within the fraction to the boundary 0.99.

    Parameters
    ----------
    problem : StageProblem
        ``eval_gradient``, ``eval_column_norms``, ``eval_hessian``, ``eval_cost`` and the
        bounds ``lb``, ``ub``.
    x : ndarray of float, shape (n,)
        Start (clipped into the bounds).
    is_stationary : callable
        ``x -> bool``, the stage's termination test.
    max_steps : int
        Largest number of accepted steps.
    free_mask : callable, optional
        ``(x, cost, grad, col_norms) -> ndarray of bool (n,)``, the variables to move (the
        termination test's free variables, :meth:`~.termination.StageMonitor.free_mask`);
        default those not on a bound the gradient pushes them against.

    Returns
    -------
    (ndarray (n,), int)
        The best point (never worse than ``x``) and the number of steps taken.
    """
    lb, ub = problem.lb, problem.ub
    x = np.clip(np.asarray(x, float), lb, ub)
    cost = problem.eval_cost(x)
    steps = 0
    while steps < max_steps and np.isfinite(cost) and cost > 0:
        step = _newton_step(problem, x, free_mask)
        if step is None:
            break
        for t in (1.0, 0.25, 0.0625, 0.015625):
            # fraction to the boundary, as the LM polish (see the module docstring)
            x_new = x + np.clip(t * step, -0.99 * (x - lb), 0.99 * (ub - x))
            c_new = problem.eval_cost(x_new)
            if np.isfinite(c_new) and c_new < cost:
                break
        else:
            break
        x, cost, steps = x_new, c_new, steps + 1
        if is_stationary(x):
            break
    return x, steps


def _newton_step(problem, x, free_mask):
    """The step of :func:`newton_polish` at ``x`` (None: no free variable or no finite
    Hessian)."""
    cost, g = problem.eval_gradient(x)
    cn = problem.eval_column_norms(x)
    free = (_not_held(x, g, problem.lb, problem.ub) if free_mask is None
            else np.asarray(free_mask(x, cost, g, cn), bool)) & (cn > 0)
    if not np.any(free) or not np.all(np.isfinite(g[free])):
        return None
    d = cn[free]
    h = np.asarray(problem.eval_hessian(x, exact=True), float)[np.ix_(free, free)]
    h = h / np.outer(d, d)
    if not np.all(np.isfinite(h)):
        return None
    lam, v = np.linalg.eigh((h + h.T) / 2.0)
    nu = 10.0 * np.finfo(float).eps * lam.size * np.max(np.abs(lam))
    if not nu > 0:
        return None
    step = np.zeros_like(x)
    step[free] = -(v @ ((v.T @ (g[free] / d)) / np.maximum(np.abs(lam), nu))) / d
    return step


def _not_held(x, g, lb, ub):
    """Mask of the variables not on a bound the gradient ``g`` pushes them against (and
    not fixed by ``lb == ub``)."""
    return ~(((x <= lb) & (g > 0)) | ((x >= ub) & (g < 0)) | (lb >= ub))
