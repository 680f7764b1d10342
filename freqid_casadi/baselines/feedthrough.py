"""Moheimani's optimal feedthrough for truncated modal models (layer L4).

S. O. R. Moheimani, "Minimizing the effect of out of bandwidth modes in truncated
structure models", ASME JDSMC 122 (2000) (seed 003; SPEC §4, §6). A modal model
``G(s) = sum_i F_i / (s^2 + omega_i^2)`` truncated to N modes is corrected by a constant K
minimising ``||(G - G_N - K) W||_2`` with W an ideal low-pass filter of cut-off omega_c.
"""

import numpy as np
import scipy.integrate

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._ssmodel import StateSpaceModel, check_order

__all__ = ["moheimani_kopt", "feedthrough_from_data", "modal_model"]


def moheimani_kopt(omega_modes, F_modes, n_kept, omega_c):
    """Closed-form optimal feedthrough K_opt (seed 003 eq. 11).

    Parameters
    ----------
    omega_modes : array_like of float, shape (n_modes,)
        Natural frequencies omega_i (rad/s), > 0, in modal order.
    F_modes : array_like of float, shape (n_modes,)
        Modal gains ``F_i`` (``phi_i(r1) phi_i(r2)`` for a beam).
    n_kept : int
        Number N of leading modes kept in the truncated model (0 <= N < n_modes).
    omega_c : float
        Cut-off of the ideal low-pass weight (rad/s); must be below every discarded
        natural frequency (Moheimani takes omega_c in (omega_N, omega_{N+1})).

    Returns
    -------
    float
        ``K_opt = (1/(2 omega_c)) sum_{i > N} (F_i/omega_i) ln((omega_i + omega_c)/
        (omega_i - omega_c))``.

    Notes
    -----
    Eq. 11 of the seed, identical to SPEC §4. It is eq. 9 integrated term by term:
    ``int_{-wc}^{wc} F/(w_i^2 - w^2) dw = (F/w_i) ln((w_i + wc)/(w_i - wc))``. (The seed's
    eq. 10 prints the lower limit as -infinity; eqs. 8-9, the result (11) and the
    multivariable derivation all use -omega_c, which is what is implemented.) The
    logarithm is evaluated as ``2 artanh(omega_c/omega_i)`` to avoid cancellation when
    omega_c << omega_i.
    """
    w = np.asarray(omega_modes, float).reshape(-1)
    F = np.asarray(F_modes, float).reshape(-1)
    if w.size != F.size:
        raise DataError(f"omega_modes and F_modes must have equal lengths: {w.size} != {F.size}")
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(F))):
        raise DataError("omega_modes and F_modes must be finite")
    if np.any(w <= 0):
        raise DataError(f"omega_modes must be > 0 (rad/s), got min {w.min()!r}")
    N = check_order(n_kept, "n_kept", 0)
    if N >= w.size:
        raise OptionError(f"n_kept={N} leaves no mode to discard (n_modes={w.size})")
    wc = float(omega_c)
    w_out, F_out = w[N:], F[N:]
    if not np.isfinite(wc) or wc <= 0:
        raise OptionError(f"omega_c must be a positive frequency (rad/s), got {omega_c!r}")
    if wc >= w_out.min():
        raise OptionError(f"omega_c={wc} must be below every discarded mode; the lowest "
                          f"discarded omega_i is {w_out.min()!r}: lower omega_c or keep more modes")
    return float(np.sum(F_out / w_out * 2.0 * np.arctanh(wc / w_out)) / (2.0 * wc))


def _as_response_fun(obj, label):
    if hasattr(obj, "frequency_response"):
        return obj.frequency_response
    if callable(obj):
        return obj
    raise DataError(f"{label} must be a callable omega -> response or a model with "
                    f"frequency_response(omega), got {type(obj).__name__}")


def feedthrough_from_data(data_full_fun, truncated_model_fun, omega_c, *, points=None,
                          epsrel=1e-13, limit=500):
    """Data-based optimal feedthrough ``K = (1/(2 wc)) int_{-wc}^{wc} Re(G - G_r)(j w) dw``.

    Parameters
    ----------
    data_full_fun : callable, model or FrequencyData
        The full response G: a callable ``omega -> response`` (rad/s -> complex), an
        object with ``frequency_response(omega)``, or measured FrequencyData.
    truncated_model_fun : callable or model
        The truncated model G_r, same conventions (not FrequencyData).
    omega_c : float
        Cut-off (rad/s) of the ideal low-pass weight.
    points : sequence of float, optional
        Breakpoints for ``scipy.integrate.quad`` in (0, omega_c), e.g. the kept natural
        frequencies, where G and G_r are both large and their difference cancels.
    epsrel : float, optional
        Relative tolerance of ``quad`` (default 1e-13).
    limit : int, optional
        Maximum number of ``quad`` subintervals (default 500).

    Returns
    -------
    float
        K (same units as G).

    Notes
    -----
    SPEC §6 and the first line of the seed's multivariable K_opt: the optimal constant is
    the mean of Re(G - G_r) over the pass band. ``Re G(j w)`` is even in w for a real
    system, so the integral over [-wc, wc] is twice the one over [0, wc].

    With callables the integral is computed by adaptive Gauss-Kronrod quadrature
    (``quad``). With FrequencyData it is the trapezoidal rule on the samples in
    (0, omega_c] (the value at omega_c linearly interpolated, and Re(G - G_r) held
    constant on [0, omega_1] below the first sample); this needs ``omega_c`` inside the
    data band and is only as accurate as the data's density.
    """
    wc = float(omega_c)
    if not np.isfinite(wc) or wc <= 0:
        raise OptionError(f"omega_c must be a positive frequency (rad/s), got {omega_c!r}")
    if isinstance(truncated_model_fun, FrequencyData):
        raise DataError("truncated_model_fun must be a model or callable, not FrequencyData")
    g_r = _as_response_fun(truncated_model_fun, "truncated_model_fun")

    if isinstance(data_full_fun, FrequencyData):
        omega, resp = data_full_fun.omega, data_full_fun.response
        if not omega[0] < wc <= omega[-1]:
            raise DataError(f"omega_c={wc} must lie inside the data band "
                            f"({omega[0]!r}, {omega[-1]!r}] rad/s")
        keep = omega < wc
        w = np.concatenate([omega[keep], [wc]])
        g_at_wc = np.interp(wc, omega, resp.real)
        re_g = np.concatenate([resp.real[keep], [g_at_wc]])
        y = re_g - np.real(np.asarray(g_r(w), complex))
        integral = y[0] * w[0] + scipy.integrate.trapezoid(y, w)
        return float(integral / wc)

    g = _as_response_fun(data_full_fun, "data_full_fun")

    def integrand(x):
        xa = np.array([x], float)
        return float(np.real(np.asarray(g(xa), complex).reshape(-1)[0]
                             - np.asarray(g_r(xa), complex).reshape(-1)[0]))

    pts = None
    if points is not None:
        pts = [float(p) for p in points if 0 < float(p) < wc]
    val, _ = scipy.integrate.quad(integrand, 0.0, wc, points=pts or None, epsabs=0.0,
                                  epsrel=epsrel, limit=int(limit))
    return float(val / wc)


def modal_model(omega_modes, F_modes, *, zeta=0.0, feedthrough=0.0, name="modal"):
    """``sum_i F_i / (s^2 + 2 zeta_i omega_i s + omega_i^2) + feedthrough`` as a state space.

    Parameters
    ----------
    omega_modes : array_like of float, shape (n_modes,)
        Natural frequencies (rad/s), > 0.
    F_modes : array_like of float, shape (n_modes,)
        Modal gains.
    zeta : float or array_like, optional
        Modal damping ratios (default 0: Moheimani's undamped model, poles on the
        imaginary axis).
    feedthrough : float, optional
        Constant term, e.g. :func:`moheimani_kopt`.
    name : str, optional

    Returns
    -------
    StateSpaceModel
        Order ``2 n_modes``; block i has ``A_i = [[0, 1], [-w_i^2, -2 zeta_i w_i]]``,
        ``B_i = [0, 1]^T``, ``C_i = [F_i, 0]``.
    """
    w = np.asarray(omega_modes, float).reshape(-1)
    F = np.asarray(F_modes, float).reshape(-1)
    if w.size != F.size:
        raise DataError(f"omega_modes and F_modes must have equal lengths: {w.size} != {F.size}")
    z = np.broadcast_to(np.asarray(zeta, float), w.shape)
    n = 2 * w.size
    A = np.zeros((n, n))
    B = np.zeros((n, 1))
    C = np.zeros((1, n))
    for i in range(w.size):
        k = 2 * i
        A[k:k + 2, k:k + 2] = [[0.0, 1.0], [-w[i] ** 2, -2 * z[i] * w[i]]]
        B[k + 1, 0] = 1.0
        C[0, k] = F[i]
    return StateSpaceModel(A, B, C, float(feedthrough), 0.0, name)
