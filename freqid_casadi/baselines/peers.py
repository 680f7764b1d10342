"""Unconstrained rational fitters used as peers: AAA and relaxed vector fitting (layer L4).

Neither method enforces stability or minimum phase; their models are returned as they come
(vector fitting can optionally flip unstable poles), so a report can count right-half-plane
poles and zeros with :func:`~freqid_casadi.baselines.count_rhp`.
"""

import warnings

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._ssmodel import check_order, pair_conjugates, pole_residue_ss
from .vectfit import fit_residues, vectfit

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
        poles = np.concatenate([rp + 0j, cp, np.conj(cp)])
        res, const = fit_residues(data.omega, data.response, poles, weighting="none")
        rr, cr, d = res[0, :rp.size].real, res[0, rp.size:rp.size + cp.size], const[0]
    return pole_residue_ss(rp, rr, cp, cr, np.real(d), "aaa")


# --------------------------------------------------------------------------- vector fitting


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
    relaxation of Gustavsen, ibid. 21 (2006) 1587-1592: the one-channel case of
    :func:`~freqid_casadi.baselines.vectfit` (its Notes give the linear problem of each
    iteration), started at :func:`~freqid_casadi.baselines.initial_poles`.
    """
    data = _check_data(data)
    n = check_order(n_poles, "n_poles")
    check_order(n_iter, "n_iter", 0)
    if weighting not in ("relative", "none"):
        raise OptionError(f"weighting must be 'relative' or 'none', got {weighting!r}")
    if 2 * data.n_points < 2 * n + 2:
        raise DataError(f"too few points ({data.n_points}) for {n} poles")
    fit = vectfit(data.omega, data.response, n, weights=data.weights, weighting=weighting,
                  n_iter=n_iter, constant=fit_d, stable=enforce_stable_poles)
    poles, residues = fit.poles, fit.residues[0]
    real, upper = poles.imag == 0, poles.imag > 0
    return pole_residue_ss(poles[real].real, residues[real].real, poles[upper],
                           residues[upper], fit.constants[0], "vector-fitting")
