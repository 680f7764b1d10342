"""The two stages of cost_and_coeffs.m (Appendix A), transcribed line by line.

Private to :mod:`freqid_casadi.studies.thesis_matlab`, which re-exports the public names.
``l.N`` are the line numbers printed in Appendix A (see that module's docstring).
"""

import time
from dataclasses import dataclass

import numpy as np

from ._thesis_matlab_kernels import (
    cost_func, create_jacob, first_factor, gain_ratio, grow_tol1, matlab_pinv,
    stage0_residual, stage0_windows, stage_residual, tf_approx, update_damping)

__all__ = ["integrator_stage", "res_antires_stage", "stage0_start", "new_section",
           "SectionStage"]

_STAGE0 = dict(start=1, n=5, t=1200.0, tol1=1e-15, tau=1.0)       # main.m l.7; l.21, l.46, l.62
_SECTIONS = dict(tol1=1e-20, eps1=1e-12, m=1.0, mu1=20.0, t0=1.0, tau=0.1, tt=30.0)  # l.134-178


class _Budget:
    """Caps that the printed code does not have: inner iterations per LM loop and a deadline.

    ``hit`` records which cap stopped a loop (None if none did).
    """

    def __init__(self, max_inner=None, time_budget=None, last_point="trial"):
        self.max_inner = max_inner
        self.time_budget = time_budget
        self.last_point = last_point
        self.deadline = None if time_budget is None else time.perf_counter() + time_budget
        self.hit = None
        self.n_capped = 0

    def ok(self, k):
        if self.max_inner is not None and k >= self.max_inner:
            self.hit, self.n_capped = "max_inner", self.n_capped + 1
            return False
        if self.deadline is not None and time.perf_counter() > self.deadline:
            self.hit = "time_budget"
            return False
        return True

    @property
    def out_of_time(self):
        return self.deadline is not None and time.perf_counter() > self.deadline

    def returned(self, accepted, trial):
        """The point an LM loop returns: the last trial point (as printed; l.121 and l.301
        read it) or, in the deviation study (``last_point="accepted"``), the last accepted."""
        return accepted if self.last_point == "accepted" else trial


def _normal(Jr, eps_p):
    """``A = real(Jr'*Jr)``, ``g = real(Jr'*eps_p)`` (cost_and_coeffs.m l.54, l.56)."""
    JH = Jr.conj().T
    return (JH @ Jr).real, (JH @ eps_p).real


def _lm_step(k, st, A, mu, g, beta):
    """The head of both LM loops: ``k = k + 1``, tol1 grown every 1000 iterations, the step
    ``pinv(A + mu I) g`` and its size test (main.m stage 0 l.66-74; sections l.209-227).

    Returns
    -------
    (int, ndarray or None)
        The new ``k`` and the step, or None when ``norm(delta) < tol1 norm(beta)`` (the
        caller then sets ``stop = false``, l.75 / l.228).
    """
    k += 1                                                              # l.66 / l.209
    st["tol1"] = grow_tol1(k, st["tol1"])                               # l.67-69 / l.210-212
    delta = matlab_pinv(A + mu * np.eye(len(A))) @ g                    # l.72 / l.225
    if np.linalg.norm(delta) < st["tol1"] * np.linalg.norm(beta):       # l.74 / l.227
        return k, None
    return k, delta


def _lm_init(Jr, eps_p, tol1, tau):
    """``A``, ``g``, ``stop`` and ``mu`` before an LM loop; cost_and_coeffs.m prints these
    lines twice: l.54-63 (stage 0) and l.191-204 (stage N)."""
    A, g = _normal(Jr, eps_p)                                 # l.54, l.56 / l.191, l.196
    stop = not np.max(np.abs(g)) < tol1                       # l.57-61 / l.197-202
    mu = tau * np.max(np.diag(A))                             # l.62-63 / l.203-204
    return A, g, stop, mu


def _converged(g, eps_p, tol1):
    """The two stop tests after an accepted step; cost_and_coeffs.m prints them twice:
    l.99-105 (stage 0) and l.276-284 (stage N)."""
    return np.max(np.abs(g)) < tol1 or np.linalg.norm(eps_p) ** 2 < tol1   # l.99-101, l.103-105


def stage0_start(Hi_u, s, integrator=True):
    """Start of stage 0: ``[0, abs(Hi_u(1)*1j*s_(1))]`` (cost_and_coeffs.m l.41, READINGS).

    Parameters
    ----------
    Hi_u, s : ndarray of complex, shape (N,)
        Data and ``1j*omega`` of the first window.
    integrator : bool
        True: ``K0 = |Phi_1| omega_1`` (the printed line); False: ``K = |Phi_1|``.

    Returns
    -------
    ndarray of float, shape (2,)
        ``[h, K]``: delay 0 s and the gain.
    """
    return np.array([0.0, abs(Hi_u[0] * 1j * s[0]) if integrator else abs(Hi_u[0])])


def new_section(omega_c, tt=30.0):
    """The new section of stage N: the identity scaled by ``tt_`` (cost_and_coeffs.m l.171-178).

    Parameters
    ----------
    omega_c : float
        ``w_maxerr`` (rad/s), the frequency of the largest relative error.
    tt : float
        ``tt_ = 30`` (l.174): ``a = b = tt``, ``zeta = 0.5 sqrt(tt)``, ``omega = omega_c sqrt(tt)``.

    Returns
    -------
    ndarray of float, shape (6,)
        ``[a, zeta_n, omega_n, b, zeta_d, omega_d]``; numerator = denominator, so the section
        is exactly 1 and the model's response is unchanged.
    """
    r = np.sqrt(tt)
    return np.array([tt, 0.5 * r, omega_c * r, tt, 0.5 * r, omega_c * r])


def _stage0_lm(s, Hi_u, beta_i_1, st, integrator, budget):
    """One window of ``integrator_cost_and_coeffs`` (cost_and_coeffs.m l.44-115).

    Returns the last trial point ``beta_i_1`` (what l.44 and l.121 read next) and ``k``.
    """
    beta_i = beta_i_1                                                   # l.44
    t_ = _STAGE0["t"]                                                   # l.46
    fi = first_factor(s, beta_i[0], beta_i[1], integrator)             # l.47
    Jr = create_jacob(s, None, beta_i, Hi_u, fi, 1200.0, integrator)[:, 1:]   # l.49-50
    k, v = 0, 2.0                                                       # l.52-53
    eps_p = stage0_residual(s, Hi_u, beta_i, t_, integrator)           # l.55
    A, g, stop, mu = _lm_init(Jr, eps_p, st["tol1"], _STAGE0["tau"])    # l.54, l.56-63
    while stop and budget.ok(k):                                        # l.65
        k, delta = _lm_step(k, st, A, mu, g, beta_i)                    # l.66-74
        if delta is None:
            stop = False                                                # l.75
            continue
        beta_i_1 = beta_i + delta                                       # l.77
        eps_p_new = stage0_residual(s, Hi_u, beta_i_1, t_, integrator)     # l.78-80
        rho = gain_ratio(eps_p, eps_p_new, delta, mu, g)                # l.81
        if rho > 0:                                                     # l.83
            beta_i = beta_i_1                                           # l.84
            # l.90-91: the Jacobian at the new point, with fi of the previous point
            Jr = create_jacob(s, None, beta_i, Hi_u, fi, 1200.0, integrator)[:, 1:]
            fi = first_factor(s, beta_i[0], beta_i[1], integrator)     # l.95
            eps_p = stage0_residual(s, Hi_u, beta_i, t_, integrator)   # l.96
            A, g = _normal(Jr, eps_p)                                   # l.93, l.97
            if _converged(g, eps_p, st["tol1"]):                        # l.99-105
                stop = False
        mu, v = update_damping(mu, v, rho)                              # l.107-111
    return budget.returned(beta_i, beta_i_1), k                         # l.121 reads beta_i_1


def integrator_stage(H, omega, start=1, n=5, *, integrator=True, budget=None):
    """Stage 0: gain and delay on a window growing 1, 3, 5 points (cost_and_coeffs.m l.20-129).

    Parameters
    ----------
    H : ndarray of complex, shape (M,)
        Frequency response Phi.
    omega : ndarray of float, shape (M,)
        Frequencies in rad/s.
    start, n : int
        ``start`` (1-based first index) and ``n`` of main.m l.7 (1 and 5).
    integrator : bool
        Fit ``exp(-h s) K/s`` (printed) or ``exp(-h s) K`` (the unprinted _noint variant).
    budget : _Budget, optional
        Iteration/time caps (None: as printed, unbounded).

    Returns
    -------
    cost : float
        ``cost_func`` on points 1..fin (RMS relative error).
    coeffs : ndarray of float, shape (6, 1)
        ``[h, K, 0, 0, 0, 0]`` (l.121).
    frep : ndarray of complex, shape (M,)
        The stage's model at every omega (l.125-127).
    nit : int
        LM iterations over the three windows.
    """
    budget = budget or _Budget()
    st = {"tol1": _STAGE0["tol1"]}                                      # l.21 (eps, l.22, unused)
    beta_i_1, nit, fin = None, 0, start
    for fin in stage0_windows(start, n):                                # l.24-35, l.117-118
        s = 1j * omega[start - 1:fin]                                   # l.36-37
        Hi_u = H[start - 1:fin]                                         # l.38
        if beta_i_1 is None:                                            # l.40-42 (Ni == 1)
            beta_i_1 = stage0_start(Hi_u, s, integrator)
        beta_i_1, k = _stage0_lm(s, Hi_u, beta_i_1, st, integrator, budget)
        nit += k
    coeffs = np.concatenate([beta_i_1, np.zeros(4)]).reshape(6, 1)     # l.121
    fi = first_factor(1j * omega[:fin], coeffs[0, 0], coeffs[1, 0], integrator)   # l.122-123
    cost = cost_func(H[:fin], fi)                                       # l.124
    frep = first_factor(1j * omega, coeffs[0, 0], coeffs[1, 0], integrator)       # l.125-127
    return cost, coeffs, frep, nit


def _pack(ctnow, beta_i):
    """``[reshape(ctnow, [], 1); beta_i]`` without entries 3:6 (l.206-207): ``[h K theta..]``."""
    return np.delete(np.concatenate([ctnow.reshape(-1, order="F"), beta_i]), [2, 3, 4, 5])


def _unpack(beta_all):
    """``reshape([b(1:2); zeros(4,1); b(3:end)], 6, [])`` (l.241-242, l.264-265, l.301-302)."""
    return np.concatenate([beta_all[:2], np.zeros(4), beta_all[2:]]).reshape(6, -1, order="F")


def _sumt_pass(s, Hi_u, ctnow, beta_i_2, t_, st, integrator, budget):
    """One barrier problem ``t_`` of the section stage (cost_and_coeffs.m l.183-294).

    Returns the pass's ``beta_i_2_all`` (the last *trial* point, l.301) and ``k``.
    """
    beta_i = beta_i_2                                                   # l.183
    fi = tf_approx(s, ctnow, beta_i, integrator)                        # l.185
    Jr = create_jacob(s, ctnow, beta_i, Hi_u, fi, t_, integrator)[:, 1:]    # l.187-188
    k, v = 0, 2.0                                                       # l.189-190
    eps_p = stage_residual(Hi_u, fi, beta_i, ctnow, t_)                 # l.192-195
    A, g, stop, mu = _lm_init(Jr, eps_p, st["tol1"], _SECTIONS["tau"])  # l.191, l.196-204
    beta_i_all = _pack(ctnow, beta_i)                                   # l.206-207
    beta_i_2_all = beta_i_all                   # see READINGS (l.301): no trial, no change
    while stop and budget.ok(k):                                        # l.208 (k < Inf)
        k, delta = _lm_step(k, st, A, mu, g, beta_i_all)                # l.209-227
        if delta is None:
            stop = False                                                # l.228
            continue
        beta_i_2_all = beta_i_all + delta                               # l.232
        if beta_i_2_all[0] < 0:                                         # l.234-236: only h
            beta_i_2_all[0] = 0.0
        ctnow = _unpack(beta_i_2_all)            # l.241-242: ctnow now ends with the new section
        beta_i_2 = ctnow[:, -1]                                         # l.243
        fi_new = tf_approx(s, ctnow[:, :-1], beta_i_2, integrator)      # l.244
        # l.246-250: the barrier set is the whole new ctnow, so the new section's logs count
        # twice here (once as beta_i_2, once in coeffs_constraint); at l.195 they count once.
        eps_p_new = stage_residual(Hi_u, fi_new, beta_i_2, ctnow, t_)
        rho = gain_ratio(eps_p, eps_p_new, delta, mu, g)                # l.252
        if rho > 0:                                                     # l.254
            beta_i_all = beta_i_2_all                                   # l.255
            # l.258-259: beta_i is still the previous iterate's new section (updated at l.266)
            Jr = create_jacob(s, ctnow[:, :-1], beta_i, Hi_u, fi_new, t_, integrator)[:, 1:]
            ctnow = _unpack(beta_i_2_all)                               # l.264-265
            beta_i = ctnow[:, -1]                                       # l.266
            fi = tf_approx(s, ctnow[:, :-1], beta_i, integrator)        # l.267
            eps_p = stage_residual(Hi_u, fi, beta_i, ctnow, t_)         # l.269-273
            A, g = _normal(Jr, eps_p)                                   # l.261, l.274
            if _converged(g, eps_p, st["tol1"]):                        # l.276-284
                stop = False
        mu, v = update_damping(mu, v, rho)                              # l.286-290
    return budget.returned(beta_i_all, beta_i_2_all), k                 # l.301 reads it


_NAMES = ("h", "K", "", "", "", "")
_SECTION_NAMES = ("a", "zeta_num", "omega_num", "b", "zeta_den", "omega_den")


def _coeffs_rejected(coeffs):
    """The checks of cost_and_coeffs.m l.309-327.

    Returns None if they pass, else why MATLAB would return NaN coefficients (naming the
    first offending coefficient).
    """
    for k in range(coeffs.shape[1]):                                    # l.311
        col = coeffs[:, k]                                              # l.312
        names = _NAMES if k == 0 else [f"{n}[{k}]" for n in _SECTION_NAMES]
        if np.sum(col < -0.0) > 0:                                      # l.313 (eps = 0, l.137)
            i = int(np.flatnonzero(col < 0)[0])
            return f"negative coefficient {names[i]} = {col[i]:.4g} (l.313)"
        if np.sum(col[4:]) == 0 and k > 0:                              # l.320
            return f"section {k} has zeta_den + omega_den = 0 (l.320)"
    return None


@dataclass(frozen=True, eq=False)
class SectionStage:
    """What ``res_antires_cost_and_coeffs`` returns, plus counters.

    Attributes
    ----------
    cost : float
        ``cost_func`` on 1..fin (inf if l.313-325 reject the coefficients).
    coeffs : ndarray of float, shape (6, C + 1)
        The coefficients (also when rejected, where MATLAB returns NaN: for diagnosis).
    frep : ndarray of complex, shape (M,), or None if rejected
    pass_nit : tuple of int
        LM iterations of each barrier problem t = 1, 20, ..., 20^9.
    tol1 : float
        tol1 at the end (1e-20 grown tenfold every 1000 iterations).
    rejected : str or None
        Why l.313-325 reject the coefficients (MATLAB returns NaN), None if they pass.
    """

    cost: float
    coeffs: np.ndarray
    frep: object
    pass_nit: tuple
    tol1: float
    rejected: object

    @property
    def nit(self):
        """LM iterations over all barrier problems."""
        return int(sum(self.pass_nit))


def res_antires_stage(H, omega, start, n, ctnow, *, integrator=True, budget=None):
    """Stage N: add one section at ``n`` rad/s and refit on 1..start (cost_and_coeffs.m l.132-338).

    Parameters
    ----------
    H : ndarray of complex, shape (M,)
    omega : ndarray of float, shape (M,)
        rad/s.
    start : int
        ``w_index_pre`` of main.m (1-based last point of the window).
    n : float
        ``w_maxerr`` of main.m, rad/s: omega_n = omega_d of the new section (l.168-169).
    ctnow : ndarray of float, shape (6, C)
        Coefficients so far: column 1 ``[h K 0 0 0 0]``, then one column per section.
    integrator : bool
    budget : _Budget, optional

    Returns
    -------
    SectionStage
    """
    budget = budget or _Budget()
    st = {"tol1": _SECTIONS["tol1"]}                                    # l.134
    t_ = _SECTIONS["t0"]                                                # l.139
    fin = min(int(start), len(H))                                       # l.156-160
    s = 1j * omega[:fin]                                                # l.162-163
    Hi_u = H[:fin]                                                      # l.164
    w, tt = float(n), _SECTIONS["tt"]                                   # l.168-169, l.174
    beta_i_2 = new_section(w, tt)                                       # l.171-179
    coeffs, pass_nit = None, []
    while _SECTIONS["m"] / t_ > _SECTIONS["eps1"]:                      # l.181
        beta_i_2_all, k = _sumt_pass(s, Hi_u, ctnow, beta_i_2, t_, st, integrator, budget)
        pass_nit.append(k)
        coeffs = _unpack(beta_i_2_all)                                  # l.301-302
        beta_i_2, ctnow = coeffs[:, -1], coeffs[:, :-1]                 # l.303-304
        t_ *= _SECTIONS["mu1"]                                          # l.305
        if budget.out_of_time:
            break
    rejected = _coeffs_rejected(coeffs)
    if rejected:
        return SectionStage(np.inf, coeffs, None, tuple(pass_nit), st["tol1"], rejected)
    fi = tf_approx(s, ctnow, beta_i_2, integrator)                      # l.330-333
    cost = cost_func(H[:fin], fi[:fin])                                 # l.334
    frep = tf_approx(1j * omega, ctnow, beta_i_2, integrator)           # l.335-336
    return SectionStage(cost, coeffs, frep, tuple(pass_nit), st["tol1"], None)
