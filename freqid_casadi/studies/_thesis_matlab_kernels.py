"""Kernels of the thesis's MATLAB code (Appendix A): tf_approx.m, create_jacob.m, the
residuals, cost_func and the Levenberg-Marquardt pieces of cost_and_coeffs.m.

Private to :mod:`freqid_casadi.studies.thesis_matlab`, which re-exports them. Line numbers
``l.N`` are those printed in Appendix A (see that module's docstring).
"""

import numpy as np

from ..errors import SolverError

__all__ = ["tf_approx", "create_jacob", "first_factor", "stage0_residual", "stage_residual",
           "coeffs_constraint", "cost_func", "matlab_pinv", "matlab_log", "gain_ratio",
           "update_damping", "grow_tol1", "stage0_windows", "main_loop_continues"]


def first_factor(s, h, gain, integrator=True):
    """``exp(-h s) K / s`` (tf_approx.m l.13) or ``exp(-h s) K`` (the _noint variant).

    Parameters
    ----------
    s : ndarray of complex, shape (N,)
        ``1j*omega``, rad/s.
    h, gain : float
        Delay (s) and gain.
    integrator : bool

    Returns
    -------
    ndarray of complex, shape (N,)
    """
    f = np.exp(-h * s) * gain
    return f / s if integrator else f


def _ctnow(ctnow):
    """``ctnow`` as a (6, C) float array; ``[]`` / None is (6, 0) (``size([]) = [0 0]``)."""
    if ctnow is None:
        return np.zeros((6, 0))
    return np.asarray(ctnow, dtype=float).reshape(6, -1, order="F")


def tf_approx(s, ctnow, beta, integrator=True):
    """Frequency response of the model so far (tf_approx.m l.1-25).

    Parameters
    ----------
    s : ndarray of complex, shape (N,)
        ``1j*omega``, rad/s.
    ctnow : ndarray of float, shape (6, C), or None
        Column 1 ``[h K 0 0 0 0]``, then ``[a zeta_n omega_n b zeta_d omega_d]`` per section.
    beta : ndarray of float, shape (6,), or None
        One more section (the one being fitted), or None (``[]``).
    integrator : bool
        First factor ``exp(-h s) K/s`` (printed) or ``exp(-h s) K`` (tf_approx_noint).

    Returns
    -------
    fi : ndarray of complex, shape (N,)
    """
    s = np.asarray(s, dtype=complex)
    ctnow = _ctnow(ctnow)
    fi = np.ones(s.shape, dtype=complex)                                 # l.8
    for k in range(ctnow.shape[1]):                                      # l.10
        b = ctnow[:, k]                                                  # l.11
        if k == 0:                                                       # l.12-13
            fi = fi * first_factor(s, b[0], b[1], integrator)
        else:                                                            # l.14-16
            fi = fi * (b[0] * s**2 + 2 * b[1] * b[2] * s + b[2]**2) / (
                b[3] * s**2 + 2 * b[4] * b[5] * s + b[5]**2)
    if beta is not None and np.size(beta) > 0:                           # l.20-24
        b = np.asarray(beta, dtype=float)
        fi = fi * (b[0] * s**2 + 2 * b[1] * b[2] * s + b[2]**2) / (
            b[3] * s**2 + 2 * b[4] * b[5] * s + b[5]**2)
    return fi


def _gain_columns(s, beta, Hi_u, fi, t_, integrator, ll_=1.0):
    """Columns of h and K (create_jacob.m l.21-25 and l.45-49), shape (N, 2)."""
    fik = first_factor(s, beta[0], beta[1], integrator)                  # l.21 / l.45
    q = Hi_u / fi / fik
    jr1 = -s * first_factor(s, beta[0], beta[1], integrator) * q         # l.22 / l.46
    jr2 = t_ * first_factor(s, beta[0], 1.0, integrator) * q - ll_ * 1 / beta[1]   # l.24 / l.48
    return np.column_stack([jr1, jr2])


def _section_columns(s, secs, Hi_u, fi, t_, ll_=1.0, alpha=0.0):
    """Columns of C sections (create_jacob.m l.27-38 and l.51-62), shape (N, 6 C).

    ``secs`` has shape (6, C); the columns of section k are Jri2 ... Jri7 of the printed
    code (a, zeta_n, omega_n, b, zeta_d, omega_d), sections in order.
    """
    S = s[:, None]
    a, zn, wn, b, zd, wd = secs
    num = a * S**2 + 2 * zn * wn * S + wn**2
    den = b * S**2 + 2 * zd * wd * S + wd**2 + alpha                     # l.27 / l.51
    q = (Hi_u / fi)[:, None] / (num / den)                               # Hi_u./fi./fik
    cols = (t_ * S**2 / den * q - ll_ * 1 / a,                           # l.30 / l.54
            t_ * 2 * (wn * S) / den * q - ll_ * 1 / zn,                  # l.31 / l.55
            t_ * 2 * (zn * S + wn) / den * q - ll_ * 1 / wn,             # l.32 / l.56
            t_ * (-S**2) * num / den**2 * q - ll_ * 1 / b,               # l.34 / l.58
            t_ * (-S * 2 * wd) * num / den**2 * q - ll_ * 1 / zd,        # l.35 / l.59
            t_ * -2 * (S * zd + wd) * num / den**2 * q - ll_ * 1 / wd)   # l.36 / l.60
    return np.stack(cols, axis=2).reshape(len(s), -1)


def create_jacob(s, ctnow, cnewinit, Hi_u, fi, t_, integrator=True):
    """The matrix create_jacob.m returns (l.1-65), its leading zero column included.

    Parameters
    ----------
    s : ndarray of complex, shape (N,)
    ctnow : ndarray of float, shape (6, C), or None
        Sections fitted so far (column 1 ``[h K 0 0 0 0]``).
    cnewinit : ndarray of float, shape (2,) or (6,)
        ``[h, K]`` (stage 0, l.44-49) or the new section (l.50-62).
    Hi_u, fi : ndarray of complex, shape (N,)
        Data and the model's response the caller passes (not necessarily at this point).
    t_ : float
        Barrier parameter.
    integrator : bool

    Returns
    -------
    J : ndarray of complex, shape (N, 1 + n_params)
        The caller drops column 1 (``Jr(:, 2:end)``).

    Notes
    -----
    Against the residuals it is used with (``eps_p`` of cost_and_coeffs.m l.55 and l.195)
    this is not ``-d eps_p / d beta`` (the sign the step ``+pinv(A + mu I) g`` needs):

    * section and gain columns: ``J = -d eps_p/d beta - 2/beta``: the data part is right, the
      barrier part ``-1/beta`` has the wrong sign (l.24, l.30-36, l.48, l.54-60);
    * delay column in the section stage: ``J = -(1/t) d eps_p/d h`` (l.22 lacks ``t_``);
    * gain column in stage 0, whose residual is ``data - (1/t) log K``: ``J = -t d eps_p/dK
      - 2/K``: the data part is scaled by ``t = 1200`` and the delay column is not.

    ``tests/test_thesis_matlab.py`` asserts each relation against finite differences.
    """
    s = np.asarray(s, dtype=complex)
    ctnow = _ctnow(ctnow)
    cols = [np.zeros((len(s), 1), dtype=complex)]                        # l.14
    with np.errstate(divide="ignore", invalid="ignore"):
        if ctnow.shape[1] >= 1:                                          # l.18-25 (k == 1)
            cols.append(_gain_columns(s, ctnow[:, 0], Hi_u, fi, t_, integrator))
        if ctnow.shape[1] >= 2:                                          # l.26-39 (k >= 2)
            cols.append(_section_columns(s, ctnow[:, 1:], Hi_u, fi, t_))
        beta = np.asarray(cnewinit, dtype=float).reshape(-1)             # l.43
        if beta.size == 2:                                               # l.44-49
            cols.append(_gain_columns(s, beta, Hi_u, fi, t_, integrator))
        else:                                                            # l.50-62
            cols.append(_section_columns(s, beta.reshape(6, 1), Hi_u, fi, t_))
    return np.hstack(cols)


def matlab_log(x):
    """MATLAB's ``log``: complex for negative entries (``log(-2) = 0.693 + 3.14i``).

    Parameters
    ----------
    x : array_like of float

    Returns
    -------
    ndarray of complex
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log(np.asarray(x, dtype=complex))


def stage0_residual(s, Hi_u, beta, t_=1200.0, integrator=True):
    """``eps_p = (Hi_u-fi)./fi - 1/t_*log(beta(2))`` (cost_and_coeffs.m l.55, l.80, l.96).

    Parameters
    ----------
    s, Hi_u : ndarray of complex, shape (N,)
    beta : ndarray of float, shape (2,)
        ``[h (s), K]``.
    t_ : float
        1200 (l.46).
    integrator : bool

    Returns
    -------
    ndarray of complex, shape (N,)
    """
    fi = first_factor(s, beta[0], beta[1], integrator)
    return (Hi_u - fi) / fi - 1 / t_ * matlab_log(beta[1])


def coeffs_constraint(ctnow):
    """Barrier coefficients of ``ctnow``: all but h and the four padding zeros (l.192-194).

    Parameters
    ----------
    ctnow : ndarray of float, shape (6, C)

    Returns
    -------
    ndarray of float, shape (6 C - 5,)
        ``[K, theta_1, ..., theta_{C-1}]``.
    """
    c = _ctnow(ctnow).reshape(-1, order="F")                             # l.192
    c = np.delete(c, 0)                                                  # l.193
    return np.delete(c, [1, 2, 3, 4])                                    # l.194


def stage_residual(Hi_u, fi, beta_i, ctnow, t_):
    """``eps_p = t_*(Hi_u-fi)./fi - sum(log(beta_i)) - sum(log(coeffs_constraint))`` (l.195).

    Also l.250 and l.273, where ``ctnow`` already ends with the new section.

    Parameters
    ----------
    Hi_u, fi : ndarray of complex, shape (N,)
    beta_i : ndarray of float, shape (6,)
        The new section.
    ctnow : ndarray of float, shape (6, C)
        The columns whose coefficients enter the barrier (:func:`coeffs_constraint`).
    t_ : float

    Returns
    -------
    ndarray of complex, shape (N,)
        The same real barrier constant is subtracted from every complex residual.
    """
    barrier = np.sum(matlab_log(beta_i)) + np.sum(matlab_log(coeffs_constraint(ctnow)))
    return t_ * (Hi_u - fi) / fi - barrier


def cost_func(H, H_new):
    """``sqrt(sum(abs((H-H_new)./H_new).^2)/length(H))``: RMS relative error (l.341-344).

    Parameters
    ----------
    H, H_new : ndarray of complex, shape (N,)

    Returns
    -------
    float
    """
    return float(np.sqrt(np.sum(np.abs((H - H_new) / H_new) ** 2) / len(H)))


def matlab_pinv(A):
    """MATLAB's ``pinv``: singular values below ``max(size(A))*norm(A)*eps`` are dropped.

    Parameters
    ----------
    A : ndarray of float, shape (n, n)

    Returns
    -------
    ndarray of float, shape (n, n)

    Raises
    ------
    SolverError
        If A holds Inf or NaN (MATLAB's svd stops there with an error).
    """
    if not np.all(np.isfinite(A)):
        raise SolverError("pinv of a matrix with Inf or NaN (MATLAB stops here: 'Input to SVD "
                          "must not contain NaN or Inf'); the LM step cannot be computed")
    return np.linalg.pinv(A, rcond=max(A.shape) * np.finfo(float).eps)


def gain_ratio(eps_p, eps_p_new, delta, mu, g):
    """``rho = (norm(eps_p)^2-norm(eps_p_new)^2)/(delta'*(mu*delta+g))`` (l.81, l.252).

    Parameters
    ----------
    eps_p, eps_p_new : ndarray of complex, shape (N,)
        Residuals at the current point and at the trial point.
    delta, g : ndarray of float, shape (n,)
        Step and ``real(Jr'*eps_p)``.
    mu : float
        Damping.

    Returns
    -------
    float
        NaN if the trial residual is not finite (then ``rho > 0`` is false, as in MATLAB).
    """
    with np.errstate(invalid="ignore", over="ignore"):
        return float((np.linalg.norm(eps_p) ** 2 - np.linalg.norm(eps_p_new) ** 2)
                     / (delta @ (mu * delta + g)))


def update_damping(mu, v, rho):
    """Nielsen's update as the code writes it (l.107-111, l.286-290).

    Parameters
    ----------
    mu, v : float
        Damping and its growth factor.
    rho : float
        Gain ratio; the step was accepted iff ``rho > 0`` (False for NaN).

    Returns
    -------
    mu, v : float
        ``mu*max(1/3, 1-(2 rho-1)^3), 2`` after a success, else ``mu*v, 2 v``.
    """
    if rho > 0:
        return mu * max(1 / 3, 1 - (2 * rho - 1) ** 3), 2.0
    return mu * v, 2 * v


def grow_tol1(k, tol1):
    """``if mod(k, 1000) == 0, tol1 = tol1*10`` (l.67-69, l.210-212).

    tol1 is never reset: it keeps growing over the windows of stage 0 and over the ten
    barrier problems of a section stage, which is what finally stops a loop that does not
    converge (``norm(delta) < tol1*norm(beta)``).

    Parameters
    ----------
    k : int
        Inner iteration counter (1-based, reset per LM loop).
    tol1 : float

    Returns
    -------
    float
    """
    return tol1 * 10 if k % 1000 == 0 else tol1


def stage0_windows(start=1, n=5):
    """Last indices ``fin`` (1-based) of stage 0's windows (cost_and_coeffs.m l.24-35, l.117-118).

    Parameters
    ----------
    start, n : int
        main.m l.7 passes 1 and 5.

    Returns
    -------
    list of int
        ``[1, 3, 5]`` for start 1, n 5: the window grows 1 -> 3 -> 5 points.
    """
    ni, Ni, out = 1, 1, []                                               # l.24-25
    while Ni + ni <= n + 2:                                              # l.28
        if Ni + ni > n:                                                  # l.30-33
            Ni, ni = n, 1
        out.append(start + Ni + ni - 2)                                  # l.35
        Ni, ni = Ni + 1, ni + 1                                          # l.117-118
    return out


def main_loop_continues(g, cost_all, NN=9):
    """``while (g < NN || cost_all > 1e-2)`` (main.m l.29).

    Parameters
    ----------
    g : int
        Sections added so far.
    cost_all : float
        main.m l.25 sets it to Inf and never assigns it again, so the printed loop never
        ends; :func:`~freqid_casadi.studies.thesis_matlab.run_thesis_matlab` stops it at
        the requested number of sections.
    NN : int

    Returns
    -------
    bool
    """
    return g < NN or cost_all > 1e-2
