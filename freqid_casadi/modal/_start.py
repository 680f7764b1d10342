"""Rational start of the shared-pole fit: vector fitting with one common pole set (layer L6).

The vector fitting itself is the package's one implementation,
:func:`freqid_casadi.baselines.vectfit` (C channels, common poles, each channel's own
unknowns eliminated by a QR factorisation of its block, relocated poles flipped to the left
half plane, rows weighted by ``1/|Phi_c|``, the fit's relative error). This module adds
what the modal start needs around it: starting poles at the resonances the channels share
(:func:`peak_poles`), residues at given poles (:func:`lsfd_residues`), each channel's
zeros from its pole-residue form (:func:`channel_zeros`) and the dc-gauge section
variables of poles and zeros (:func:`factor_variables`).
"""

import numpy as np
import scipy.linalg

from ..baselines import fit_residues, vectfit

__all__ = ["shared_vector_fitting", "channel_zeros", "factor_variables", "peak_poles",
           "lsfd_residues"]


def _initial_poles(omega, n):
    """Pairs ``-b/100 +- j b`` (b spread over the band) and one real pole if n is odd."""
    b = np.linspace(omega[0], omega[-1], n // 2 + 2)[1:-1] if n // 2 else np.zeros(0)
    if omega[-1] / omega[0] > 30:
        b = np.geomspace(omega[0], omega[-1], n // 2 + 2)[1:-1] if n // 2 else b
    poles = list(-b / 100 + 1j * b) + list(np.conj(-b / 100 + 1j * b))
    if n % 2:
        poles.append(-np.sqrt(omega[0] * omega[-1]))
    return np.array(poles, complex)


def peak_poles(omega, phi, n, weights=None):
    """Starting poles at the resonances the channels agree on.

    The peaks of ``sum_c w_c |Phi_c| / max|Phi_c|`` (each channel normalised, so each has
    one vote, ``w_c`` its mean weight) are the frequencies where most channels resonate;
    the ``n // 2`` highest local maxima (at least 1 % of the band's length apart, relative)
    give pairs ``omega_k (-zeta_k + j)``, ``zeta_k`` from the peak's half-power width
    (at least the grid's spacing there over ``2 omega_k``); missing pairs fall back to the
    spread of :func:`_initial_poles`, an odd ``n`` adds its real pole. Lightly damped modes
    then need one or two vector-fitting iterations instead of many from 1 % damping
    (which on a dense grid of a 0.01 % damped test does not reach them).

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
    phi : ndarray of complex, shape (C, M)
    n : int
        Number of poles.
    weights : ndarray of float, shape (C, M), optional

    Returns
    -------
    ndarray of complex, shape (n,)
    """
    mag = np.abs(phi) / np.maximum(np.max(np.abs(phi), axis=1, keepdims=True), 1e-300)
    w = np.ones(phi.shape[0]) if weights is None else np.mean(weights, axis=1)
    total = np.sum(w[:, None] * mag, axis=0)
    m = omega.size
    if m < 3 or n < 2:
        return _initial_poles(omega, n)
    inner = np.arange(1, m - 1)
    peaks = inner[(total[1:-1] >= total[:-2]) & (total[1:-1] > total[2:])]
    peaks = peaks[np.argsort(total[peaks])[::-1]]
    chosen, gap = [], 0.01
    for i in peaks:
        if all(abs(omega[i] - omega[j]) > gap * omega[j] for j in chosen):
            chosen.append(i)
        if len(chosen) == n // 2:
            break
    pairs = []
    for i in sorted(chosen):
        half = total[i] / np.sqrt(2)
        lo, hi = i, i
        while lo > 0 and total[lo - 1] > half:
            lo -= 1
        while hi < m - 1 and total[hi + 1] > half:
            hi += 1
        width = max(omega[hi] - omega[lo], omega[min(i + 1, m - 1)] - omega[i - 1] if i else 0)
        zeta = float(np.clip(width / (2 * omega[i]), 1e-6, 0.5))
        pairs.append(omega[i] * (-zeta + 1j * np.sqrt(1 - zeta * zeta)))
    fill = _initial_poles(omega, 2 * (n // 2 - len(pairs)))
    upper = np.concatenate([np.array(pairs, complex), fill[fill.imag > 0]])
    poles = list(upper) + list(np.conj(upper))
    if n % 2:
        poles.append(-np.sqrt(omega[0] * omega[-1]) + 0j)
    return np.array(poles, complex)


def shared_vector_fitting(omega, phi, n_poles, weights=None, n_iter=10, fixed=None,
                          initial=None, constant=False):
    """Common poles and per-channel residues of ``Phi_c(s) ~ d_c + sum_k r_k / (s - p_k)``.

    Parameters
    ----------
    omega : ndarray of float, shape (M,), rad/s
    phi : ndarray of complex, shape (C, M)
    n_poles : int
        Poles relocated by the iterations.
    weights : ndarray of float, shape (C, M), optional
        Multiply the relative row weights ``1/|Phi|`` (as squared-residual weights).
    n_iter : int
    fixed : ndarray of complex, shape (F,), optional
        Poles kept as they are (conjugate pairs complete, closed left half plane): in the
        basis of the fitted function but not in the weight function's, so the iterations
        relocate only the ``n_poles`` others (a channel's own poles beside shared ones).
    initial : ndarray of complex, shape (n_poles,), optional
        Starting poles (conjugate pairs complete), e.g. :func:`peak_poles`; default pairs
        with 1 % damping spread over the band.
    constant : bool
        Fit a constant ``d_c`` per channel (the "upper residual" of modal analysis: what
        the modes above the band leave in it, and the high-frequency limit of an
        accelerance); without it ``d_c = 0`` (strictly proper). A strictly proper fit of an
        accelerance biases every pole (measured: 0.05 Hz at 307 Hz on a noise-free beam).

    Returns
    -------
    poles : ndarray of complex, shape (n_poles + F,)
        The relocated poles (closed left half plane; the real ones, the upper members of
        the pairs, their conjugates), then the fixed ones in the same layout
        (:class:`~freqid_casadi.baselines.VectorFit`).
    residues : ndarray of complex, shape (C, n_poles + F)
    constants : ndarray of float, shape (C,)
        Only with ``constant=True``: each channel's ``d_c``.
    """
    poles = vectfit(omega, phi, n_poles, weights=weights, n_iter=n_iter,
                    initial=_initial_poles(omega, n_poles) if initial is None else initial,
                    fixed=fixed, constant=constant, stable=True).poles
    # the residues from the modal start's own LSFD step, as before vectfit was shared
    residues, consts = lsfd_residues(omega, phi, poles, weights, constant)
    return (poles, residues, consts) if constant else (poles, residues)


def lsfd_residues(omega, phi, poles, weights=None, constant=True):
    """Each channel's residues at given poles: linear least squares of
    ``Phi_c(s) ~ d_c + sum_k r_ck / (s - p_k)`` with the relative row weights ``1/|Phi|``
    (times ``sqrt(weights)``), the "least-squares frequency-domain" (LSFD) step of modal
    analysis.

    Parameters
    ----------
    omega : ndarray of float, shape (M,), rad/s
    phi : ndarray of complex, shape (C, M)
    poles : ndarray of complex, shape (n,)
        Conjugate pairs complete.
    weights : ndarray of float, shape (C, M), optional
    constant : bool
        Fit the constant ``d_c`` (else 0).

    Returns
    -------
    residues : ndarray of complex, shape (C, n)
        Conjugate poles get conjugate residues.
    constants : ndarray of float, shape (C,)
    """
    return fit_residues(omega, phi, poles, weights=weights, constant=constant, scaled=False)


def channel_zeros(poles, residues, constant=0.0):
    """Finite zeros of ``d + sum_k r_k/(s - p_k)``: generalised eigenvalues of the
    Rosenbrock pencil of its diagonal realisation; complex (<= n-1, or n with ``d != 0``)."""
    n = len(poles)
    mat = np.zeros((n + 1, n + 1), complex)
    mat[:n, :n] = np.diag(poles)
    mat[:n, n] = 1.0
    mat[n, :n] = residues
    mat[n, n] = constant
    e = np.zeros((n + 1, n + 1))
    e[:n, :n] = np.eye(n)
    with np.errstate(all="ignore"):
        z = scipy.linalg.eigvals(mat, e)
    scale = np.max(np.abs(poles))
    z = z[np.isfinite(z) & (np.abs(z) < 1e6 * scale)]
    return np.where(np.abs(z.imag) <= 1e-9 * np.abs(z), z.real + 0j, z)


def factor_variables(roots, wr=None, floor=0.0):
    """dc-gauge variables ``(c2, c1)`` per section of ``prod (1 - s/root)``.

    Parameters
    ----------
    roots : complex array
        Conjugate pairs complete; paired with the sections in order of magnitude.
    wr : ndarray of float, shape (N,), optional
        Sections' reference frequencies (rad/s), increasing; default the factors' own
        natural frequencies.
    floor : float
        Smallest root magnitude (rad/s) kept (a root at 0 is not representable).

    Returns
    -------
    vars : ndarray of float, shape (N, 2)
        Sections beyond the roots get ``(0, 0)`` (a factor 1).
    wr : ndarray of float, shape (N,)
    """
    roots = np.asarray(roots, complex)
    roots = np.where(np.abs(roots) < floor, -floor + 0j, roots)
    cplx = roots[roots.imag > 0]
    real = np.sort(roots[roots.imag == 0].real)
    factors = [(abs(z), 1.0 / abs(z) ** 2, -2 * z.real / abs(z) ** 2) for z in cplx]
    for k in range(0, real.size - 1, 2):
        a, b = real[k], real[k + 1]
        factors.append((np.sqrt(abs(a * b)), 1.0 / (a * b), -(1 / a + 1 / b)))
    if real.size % 2:
        factors.append((abs(real[-1]), 0.0, -1.0 / real[-1]))
    factors.sort(key=lambda f: f[0])
    if wr is None:
        wr = np.array([f[0] for f in factors])
    out = np.zeros((len(wr), 2))
    for k, (_, c2, c1) in enumerate(factors[:len(wr)]):
        out[k] = c2 * wr[k] ** 2, c1 * wr[k]
    return out, np.asarray(wr, float)
