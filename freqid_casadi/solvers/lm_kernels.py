"""The Levenberg-Marquardt kernels of the barrier method (layer L3, numpy only).

The model decrease, the gain ratio and the damping update of
:func:`~freqid_casadi.solvers.barrier_lm.barrier_lm` (thesis §3.1.1, eq. 3.2-3.5; Nielsen's
damping update), as small pure functions with their own tests.
"""

import math

import numpy as np

__all__ = ["predicted_decrease", "model_decrease", "gain_ratio", "update_damping"]


# --------------------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------------------
def predicted_decrease(delta, g, sigma_or_D):
    """Decrease of the quadratic LM model for the step ``delta``.

    Parameters
    ----------
    delta : ndarray of float, shape (n,)
        Step, the solution of ``(A + D) delta = -g``.
    g : ndarray of float, shape (n,)
        Gradient of the objective at the current point.
    sigma_or_D : float or ndarray of float, shape (n,)
        The damping: a scalar ``sigma`` (``D = sigma*I``, thesis) or the diagonal of ``D``
        (``sigma*diag(A)``, Marquardt).

    Returns
    -------
    float
        ``L(0) - L(delta) = -g.delta - delta.A.delta/2 = delta.(D delta - g)/2`` where
        ``L(delta) = phi + g.delta + delta.A.delta/2``.

    Notes
    -----
    The thesis (Step v) writes the denominator of the gain ratio as
    ``delta^T (sigma delta + g)``; it solves ``(A + sigma I) delta = +g`` with
    ``A = J^H J``, ``g = J^H F`` for the objective ``||F||^2``, so its ``g`` is minus half
    the gradient used here and its ``A`` half the Hessian. Both give the same ratio.
    """
    delta = np.asarray(delta, float)
    g = np.asarray(g, float)
    d_delta = np.asarray(sigma_or_D, float) * delta
    return 0.5 * float(delta @ (d_delta - g))


def model_decrease(delta, g, A):
    """Decrease ``L(0) - L(delta) = -(g.delta + delta.A.delta/2)`` of the quadratic model.

    Parameters
    ----------
    delta : ndarray of float, shape (n,)
        Any step.
    g : ndarray of float, shape (n,)
        Gradient of the objective at the current point.
    A : ndarray of float, shape (n, n)
        Hessian (approximation) of the objective, without damping.

    Returns
    -------
    float
        Equals :func:`predicted_decrease` when ``delta`` solves ``(A + D) delta = -g``.
        :func:`barrier_lm` evaluates it at the step actually taken,
        ``delta = (x + delta) - x`` after rounding, so that the actual and the predicted
        decrease refer to the same step even when ``x - lb`` is near the rounding level of
        ``x``.
    """
    delta = np.asarray(delta, float)
    g = np.asarray(g, float)
    return -float(g @ delta + 0.5 * (delta @ (np.asarray(A, float) @ delta)))


def gain_ratio(phi_old, phi_new, delta, g, sigma_or_D):
    """Gain ratio ``rho`` = actual / predicted decrease (thesis §3.1.1, Step v).

    Parameters
    ----------
    phi_old, phi_new : float
        Objective at the current point and at ``x + delta``.
    delta, g, sigma_or_D
        As in :func:`predicted_decrease`.

    Returns
    -------
    float
        ``(phi_old - phi_new) / predicted_decrease(delta, g, sigma_or_D)``; ``-inf`` when the
        new objective is not finite or the predicted decrease is not positive (a step to
        reject). Equals 1 when the objective is exactly the quadratic model.
    """
    pred = predicted_decrease(delta, g, sigma_or_D)
    return _ratio(float(phi_old) - float(phi_new), pred)


def _ratio(actual, pred):
    if not (math.isfinite(actual) and math.isfinite(pred)) or pred <= 0.0:
        return -math.inf
    return actual / pred


def update_damping(sigma, nu, rho):
    """Nielsen's damping update used by the thesis (§3.1.1, Steps vi and ix).

    Parameters
    ----------
    sigma : float
        Current damping (> 0).
    nu : float
        Current growth factor (2 after a success, doubled after each failure).
    rho : float
        Gain ratio of the last trial step.

    Returns
    -------
    (float, float)
        ``(sigma*max(1/3, 1-(2 rho-1)^3), 2)`` if ``rho > 0`` (step accepted), else
        ``(sigma*nu, 2 nu)``.
    """
    sigma = float(sigma)
    nu = float(nu)
    rho = float(rho)
    if rho > 0.0:
        return sigma * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 2.0
    return sigma * nu, 2.0 * nu


