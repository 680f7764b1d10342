"""Frequency-domain subspace identification (McKelvey, Akçay & Ljung 1996), layer L4.

The thesis's "Method II" (SPEC §6): identify an order-n state-space model from frequency
samples in discrete time, after mapping the continuous frequencies to the unit circle by
the bilinear transform, then map the model back. Nothing forces the result to be stable or
minimum phase (thesis fig. 4.7).
"""

import numpy as np
import scipy.linalg

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._ssmodel import StateSpaceModel, bilinear_d2c, check_order

__all__ = ["subspace", "default_bilinear_T"]


def default_bilinear_T(omega):
    """``T = 2 / geometric mean(omega)`` (s): the bilinear map then sends the geometric
    centre of the band to ``z = j`` (a quarter of the circle), so log-spaced data spread
    symmetrically over the upper half circle.

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        rad/s, > 0.

    Returns
    -------
    float
    """
    omega = np.asarray(omega, float)
    return 2.0 / float(np.exp(np.mean(np.log(omega))))


def subspace(data, order, *, q=None, bilinear_T=None):
    """Subspace model of a given order from frequency-response data (no delay).

    Parameters
    ----------
    data : FrequencyData
        ``M`` samples ``response = G(j omega)``, omega in rad/s (any spacing).
    order : int
        Model order n >= 1.
    q : int, optional
        Number of block rows of the data matrices, ``n < q``; default ``2 n``
        (at least ``n + 1``). Needs ``q <= M``.
    bilinear_T : float, optional
        Sampling period T (s) of the bilinear map ``z = (1 + sT/2)/(1 - sT/2)``;
        default :func:`default_bilinear_T`.

    Returns
    -------
    StateSpaceModel
        Continuous time, ``delay = 0``, ``name = "subspace"``.

    Raises
    ------
    DataError
        ``data`` is not a FrequencyData or too short for ``q``.
    OptionError
        Bad ``order``, ``q`` or ``bilinear_T``.

    Notes
    -----
    McKelvey, Akçay & Ljung, IEEE TAC 41 (1996) 960-979, the algorithm for arbitrarily
    spaced frequencies, noise weighting = identity:

    1. ``z_k = exp(j theta_k)``, ``theta_k = 2 arctan(omega_k T / 2)``, so that
       ``Gd(z_k) = G(j omega_k)``.
    2. ``G = [z_k^i G_k]`` and ``W = [z_k^i]`` (i = 0..q-1, k = 1..M), scaled by
       ``1/sqrt(M)``; real data matrices ``[Re, Im]`` side by side (q x 2M), so that the
       model is real. Noise free, ``G = O_q X + Gamma_q W`` with O_q the extended
       observability matrix.
    3. LQ factorisation ``[W; G] = [[R11, 0], [R21, R22]] Q^T``; the n dominant left
       singular vectors of ``R22`` span O_q.
    4. ``C`` = first row of ``U_n``, ``A = (J1 U_n)^+ J2 U_n`` (shift invariance).
    5. ``B, D`` real, by linear least squares on ``G_k = D + C (z_k I - A)^{-1} B`` with
       real and imaginary parts stacked.
    6. Inverse bilinear (Tustin) map to continuous time, :func:`bilinear_d2c`.
    """
    if not isinstance(data, FrequencyData):
        raise DataError(f"data must be a FrequencyData, got {type(data).__name__}")
    n = check_order(order)
    M = data.n_points
    if q is None:
        q = max(2 * n, n + 1)
    q = check_order(q, "q", n + 1)
    if q > M:
        raise DataError(f"subspace needs q <= M: q={q} > M={M} frequency points; "
                        "pass a smaller q (> order) or more data")
    T = default_bilinear_T(data.omega) if bilinear_T is None else float(bilinear_T)
    if not np.isfinite(T) or T <= 0:
        raise OptionError(f"bilinear_T must be a positive number of seconds, got {bilinear_T!r}")

    omega, G = data.omega, data.response
    z = np.exp(2j * np.arctan(omega * T / 2))
    powers = z[None, :] ** np.arange(q)[:, None]              # (q, M)
    Wc = powers / np.sqrt(M)
    Gc = powers * G[None, :] / np.sqrt(M)
    W_re = np.hstack([Wc.real, Wc.imag])                       # (q, 2M)
    G_re = np.hstack([Gc.real, Gc.imag])
    R = scipy.linalg.qr(np.vstack([W_re, G_re]).T, mode="r")[0]   # (2q, 2q) upper
    R22 = R[q:2 * q, q:2 * q].T                                # lower-right block of L
    U, sv, _ = scipy.linalg.svd(R22)
    Un = U[:, :n]
    C = Un[:1, :]
    A = scipy.linalg.lstsq(Un[:-1, :], Un[1:, :])[0]

    # B, D by least squares: G_k = D + sum_j B_j [C (z_k I - A)^{-1}]_j
    eye = np.eye(n)
    Mz = z[:, None, None] * eye - A                            # (M, n, n)
    Phi = np.linalg.solve(np.transpose(Mz, (0, 2, 1)),
                          np.broadcast_to(C.T.astype(complex), (M, n, 1)))[:, :, 0]
    reg = np.hstack([Phi, np.ones((M, 1))])
    lhs = np.vstack([reg.real, reg.imag])
    rhs = np.concatenate([G.real, G.imag])
    theta = scipy.linalg.lstsq(lhs, rhs)[0]
    B, D = theta[:n].reshape(n, 1), float(theta[n])
    Ac, Bc, Cc, Dc = bilinear_d2c(A, B, C, D, T)
    return StateSpaceModel(Ac, Bc, Cc, Dc, 0.0, "subspace")
