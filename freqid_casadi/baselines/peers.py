"""Unconstrained rational fitters used as peers: AAA and relaxed vector fitting (layer L4).

Neither method enforces stability or minimum phase; their models are returned as they come
(vector fitting can optionally flip unstable poles), so a report can count right-half-plane
poles and zeros with :func:`~freqid_casadi.baselines.count_rhp`.
"""

import warnings

import numpy as np
import scipy.linalg

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._ssmodel import check_order, pair_conjugates, pole_residue_ss

__all__ = ["aaa", "vector_fitting"]


def _check_data(data):
    if not isinstance(data, FrequencyData):
        raise DataError(f"data must be a FrequencyData, got {type(data).__name__}")
    return data


def aaa(data, n_poles, *, rtol=None, refit_residues=True):
    """AAA rational approximation (scipy.interpolate.AAA) at ``s = j omega``.

    Parameters
    ----------
    data : FrequencyData
        Samples ``response = G(j omega)``, omega in rad/s.
    n_poles : int
        Maximum number of poles: AAA is run with ``max_terms = n_poles + 1`` support
        points, i.e. a rational function of type (n, n), n <= n_poles.
    rtol : float, optional
        AAA's relative stopping tolerance (scipy default ``eps**0.75``). AAA stops with
        fewer poles once it is met; the RuntimeWarning scipy gives when ``max_terms`` is
        reached first is suppressed (that is the intended use here).
    refit_residues : bool, optional
        If True (default), keep AAA's poles (made conjugate-symmetric) but re-fit the
        residues and the constant by real linear least squares on the data (absolute
        error, as AAA measures it). If False, use AAA's own residues and value at
        infinity, averaged over conjugate pairs.

    Returns
    -------
    StateSpaceModel
        ``name = "aaa"``: a real pole-residue form ``d + sum r_k/(s - p_k)`` with the
        poles of the approximant (``AAA.poles()``; conjugate pairs averaged, near-real
        poles made real, :func:`~freqid_casadi.baselines._ssmodel.pair_conjugates`) and
        residues and ``d`` as chosen by ``refit_residues`` (AAA's own ones are
        ``AAA.residues()`` and ``d = sum w_j f_j / sum w_j``, the value at infinity).
        Stability and minimum phase are NOT enforced; zeros are the model's transmission
        zeros (they agree with ``AAA.roots()`` when the fit is exact).

    Notes
    -----
    Nakatsukasa, Sète & Trefethen, SIAM J. Sci. Comput. 40 (2018) A1494. The support
    points are on the imaginary axis: the data are fitted together with their mirror
    ``G(-j omega) = conj G(j omega)``, so that the approximant is (nearly) real and its
    poles come in (nearly) conjugate pairs; the small asymmetry is what the realisation
    removes. The barycentric form is type (m-1, m-1) so the model is biproper: for a
    strictly proper plant ``d`` comes out small but nonzero and the
    model gets one very large (possibly right-half-plane) zero.
    """
    from scipy.interpolate import AAA

    data = _check_data(data)
    n = check_order(n_poles, "n_poles")
    s = 1j * data.omega
    f = data.response
    s = np.concatenate([np.conj(s[::-1]), s])
    f = np.concatenate([np.conj(f[::-1]), f])
    if n + 1 > s.size:
        raise DataError(f"AAA needs more points than poles: n_poles={n}, {s.size} points")
    kwargs = {"max_terms": n + 1}
    if rtol is not None:
        kwargs["rtol"] = float(rtol)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = AAA(s, f, **kwargs)
    poles = np.asarray(r.poles(), complex)
    residues = np.asarray(r.residues(), complex)
    w = np.asarray(r.weights)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.sum(w * r.support_values) / np.sum(w)
    if not np.isfinite(d):
        raise DataError("the AAA approximant has a pole at infinity (improper); "
                        "try another n_poles")
    rp, rr, cp, cr = pair_conjugates(poles, residues, rtol=1e-8)
    if refit_residues:
        rr, cr, d = _fit_residues(1j * data.omega, data.response, rp, cp,
                                  np.ones(data.n_points), True)
    return pole_residue_ss(rp, rr, cp, cr, np.real(d), "aaa")


# --------------------------------------------------------------------------- vector fitting


def _initial_poles(omega, n):
    """Gustavsen & Semlyen's start: complex pairs ``-b/100 +- j b`` with b log-spaced over
    the band, plus one real pole ``-geomean(omega)`` if n is odd."""
    n_pairs = n // 2
    b = np.geomspace(omega[0], omega[-1], n_pairs) if n_pairs else np.zeros(0)
    cp = -b / 100 + 1j * b
    rp = np.array([-np.exp(np.mean(np.log(omega)))]) if n % 2 else np.zeros(0)
    return rp, cp


def _basis(s, rp, cp):
    """Real-formulation partial-fraction basis, shape (M, n): ``1/(s-a)`` per real pole,
    ``1/(s-a) + 1/(s-a*)`` and ``j/(s-a) - j/(s-a*)`` per pair."""
    cols = [1.0 / (s - a) for a in rp]
    for a in cp:
        u, v = 1.0 / (s - a), 1.0 / (s - np.conj(a))
        cols += [u + v, 1j * u - 1j * v]
    return np.stack(cols, axis=1) if cols else np.zeros((s.size, 0), complex)


def _state_matrices(rp, cp):
    """A and b of Gustavsen's real realisation of the basis (b = 1 or [2, 0])."""
    n = rp.size + 2 * cp.size
    A = np.zeros((n, n))
    b = np.zeros(n)
    k = 0
    for a in rp:
        A[k, k], b[k] = a, 1.0
        k += 1
    for a in cp:
        A[k:k + 2, k:k + 2] = [[a.real, a.imag], [-a.imag, a.real]]
        b[k] = 2.0
        k += 2
    return A, b


def _split_eigs(lam):
    """Real eigenvalues and the upper members of conjugate pairs of a real matrix."""
    lam = np.asarray(lam, complex)
    tol = 1e-12 * np.maximum(np.abs(lam), np.finfo(float).tiny)
    is_real = np.abs(lam.imag) <= tol
    return np.sort(lam[is_real].real), np.sort_complex(lam[~is_real & (lam.imag > 0)])


def _lstsq_scaled(Mat, rhs):
    scale = np.linalg.norm(Mat, axis=0)
    scale[scale == 0] = 1.0
    x = scipy.linalg.lstsq(Mat / scale, rhs)[0]
    return x / scale


def _fit_residues(s, f, rp, cp, wt, fit_d):
    """Real residues (and d) for fixed poles by weighted linear least squares, real and
    imaginary parts stacked. Returns ``(real_r, cplx_r, d)``."""
    Phi = _basis(s, rp, cp)
    n = Phi.shape[1]
    left = Phi if not fit_d else np.hstack([Phi, np.ones((s.size, 1))])
    Mc = wt[:, None] * left
    x = _lstsq_scaled(np.vstack([Mc.real, Mc.imag]),
                      np.concatenate([(wt * f).real, (wt * f).imag]))
    c = x[:n]
    d = float(x[n]) if fit_d else 0.0
    pair = c[rp.size:].reshape(-1, 2)
    return c[:rp.size], pair[:, 0] + 1j * pair[:, 1], d


def vector_fitting(data, n_poles, *, n_iter=10, enforce_stable_poles=False,
                   weighting="relative", fit_d=True):
    """Relaxed vector fitting of a rational model with ``n_poles`` poles.

    Parameters
    ----------
    data : FrequencyData
        Samples ``response = G(j omega)``, omega in rad/s. ``data.weights`` (if any)
        multiply the weighting below.
    n_poles : int
        Number of poles n >= 1 (model order).
    n_iter : int, optional
        Pole-relocation iterations (default 10).
    enforce_stable_poles : bool, optional
        Flip relocated poles with Re > 0 to the left half plane (Gustavsen & Semlyen's
        option). Default False: the unconstrained peer.
    weighting : {"relative", "none"}, optional
        Row weights ``1/|G|`` (the relative error, the package's measure; default) or 1.
    fit_d : bool, optional
        Fit a constant term d (default True); else the model is strictly proper.

    Returns
    -------
    StateSpaceModel
        ``name = "vector-fitting"``: Gustavsen's real pole-residue realisation. Minimum
        phase is never enforced; stability only with ``enforce_stable_poles``.

    Notes
    -----
    Gustavsen & Semlyen, IEEE Trans. Power Delivery 14 (1999) 1052-1061, with the
    relaxation of Gustavsen, ibid. 21 (2006) 1587-1592. Each iteration solves, with real
    and imaginary parts stacked and real unknowns, the linear least-squares problem

        w (sum c_k phi_k + d) - w G (sum ct_k phi_k + dt) = 0,
        (||w G|| / M) Re sum_i (sum ct_k phi_k(s_i) + dt) = ||w G||     (relaxation)

    with ``phi_k`` the real partial-fraction basis of the current poles; the new poles are
    the zeros of ``sigma = dt + ct^T (sI - A)^{-1} b``, i.e. ``eig(A - b ct^T / dt)``. If
    ``|dt|`` falls below 1e-8 it is fixed to ``1e-8 sign(dt)`` and the problem re-solved
    without the relaxation row, as Gustavsen does. The residues c and d are finally fitted
    with the last poles. Starting poles: :func:`_initial_poles`.
    """
    data = _check_data(data)
    n = check_order(n_poles, "n_poles")
    k_iter = check_order(n_iter, "n_iter", 0)
    if weighting not in ("relative", "none"):
        raise OptionError(f"weighting must be 'relative' or 'none', got {weighting!r}")
    if 2 * data.n_points < 2 * n + 2:
        raise DataError(f"too few points ({data.n_points}) for {n} poles")
    omega, f = data.omega, data.response
    s = 1j * omega
    M = omega.size
    wt = 1.0 / np.abs(f) if weighting == "relative" else np.ones(M)
    if data.weights is not None:
        wt = wt * np.sqrt(data.weights)
    rp, cp = _initial_poles(omega, n)
    n_d = 1 if fit_d else 0

    for _ in range(k_iter):
        Phi = _basis(s, rp, cp)                                  # (M, n)
        ones = np.ones((M, 1))
        left = Phi if not fit_d else np.hstack([Phi, ones])     # c, d
        right = -f[:, None] * np.hstack([Phi, ones])             # ct, dt
        Mc = wt[:, None] * np.hstack([left, right])
        Mr = np.vstack([Mc.real, Mc.imag])
        rhs = np.zeros(2 * M)
        norm_f = np.linalg.norm(wt * f)
        relax = np.concatenate([np.zeros(n + n_d),
                                np.real(np.sum(np.hstack([Phi, ones]), axis=0))])
        relax *= norm_f / M
        x = _lstsq_scaled(np.vstack([Mr, relax]), np.concatenate([rhs, [norm_f]]))
        ct, dt = x[n + n_d:n + n_d + n], x[-1]
        if abs(dt) < 1e-8:
            dt = 1e-8 if dt >= 0 else -1e-8
            # non-relaxed problem with fixed dt: move the dt column to the right side
            x2 = _lstsq_scaled(Mr[:, :-1], -dt * Mr[:, -1])
            ct = x2[n + n_d:]
        A, b = _state_matrices(rp, cp)
        lam = np.linalg.eigvals(A - np.outer(b, ct) / dt)
        if enforce_stable_poles:
            lam = np.where(lam.real > 0, -np.conj(lam), lam)
        rp, cp = _split_eigs(lam)

    real_r, cplx_r, d = _fit_residues(s, f, rp, cp, wt, fit_d)
    return pole_residue_ss(rp, real_r, cp, cplx_r, d, "vector-fitting")
