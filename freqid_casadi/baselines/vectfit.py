"""Relaxed vector fitting of C >= 1 channels with one common pole set (layer L3).

The package's one vector fitting. Every channel ``c`` gets its own residues and constant,
all channels share the poles: the weight function ``sigma(s) = dt + sum_k ct_k phi_k(s)``
is common, and its zeros are the next poles (Gustavsen & Semlyen 1999; the relaxation of
Gustavsen 2006). One channel is the single fit (:func:`~freqid_casadi.baselines.vector_fitting`,
the rational start of :func:`freqid_casadi.fit`); many channels are the rational start of
:func:`freqid_casadi.fit_shared` (:mod:`freqid_casadi.modal`).

How each iteration's linear problem is solved depends only on the number of channels: with
one channel the stacked problem in all unknowns is solved as it stands (eliminating the
channel's own unknowns would cost the same QR and round differently from the single fits
this package has always reported); with C > 1 each channel's own unknowns are eliminated by
a QR factorisation of its block (Deschrijver, Mrozowski, Dhaene & De Zutter, IEEE MWCL 18
(2008) 383, "fast VF"), so one iteration costs C small QRs plus one least-squares problem in
the ``n + 1`` shared unknowns instead of one in ``C (n + 1) + n + 1``.

Above ``_TALL_POINTS`` frequencies (16 384) no (2M, unknowns) matrix is formed: each
least-squares problem (of a relocation, or of the final residues) is reduced block by block
of 4096 frequencies to its R factor (LAPACK dgeqrf), which stands for the matrix in the
same problem (the solution agrees to rounding). At 200 000 points and 4 poles one
relocation costs 21 ms and a few MB instead of 270 ms and four 32 MB copies.
"""

import functools
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..errors import DataError, OptionError
from ._ssmodel import check_order

__all__ = ["VectorFit", "vectfit", "fit_residues", "initial_poles"]

# |Im p| <= _REAL_RTOL |p|: a real pole (the eigenvalues of a real matrix).
_REAL_RTOL = 1e-12
_TINY = np.finfo(float).tiny          # the smallest normal float (a zero eigenvalue's scale)
_EPS = np.finfo(np.float64).eps       # dgelsd's rcond, as scipy.linalg.lstsq passes it
# |dt| below this is fixed to it (with its sign) and sigma re-fitted without the relaxation.
_DT_MIN = 1e-8
# Frequencies above which each least-squares problem is reduced chunk by chunk to its R
# factor (:func:`_r_factor`) instead of being formed whole: its (2M, p) matrix at 200 000
# points is 32 MB per copy (formed, stacked, scaled, copied by LAPACK), and a QR of
# cache-sized blocks costs a fraction of LAPACK's one pass over it. Below, the problem is
# solved as it stands, as it always was (same numbers to the last bit).
_TALL_POINTS = 16384
# Frequencies per block of the chunked reduction (2 rows each: real and imaginary parts).
_CHUNK_POINTS = 4096
# Rows from which a least-squares problem with at least twice as many rows as columns is
# solved through its QR factorisation first (:func:`_lstsq`; below, the three LAPACK calls
# cost more than dgelsd's one).
_TALL_ROWS = 256


@dataclass(frozen=True)
class VectorFit:
    """Result of :func:`vectfit`: ``G_c(s) ~ d_c + sum_k r_ck / (s - p_k)``.

    Attributes
    ----------
    poles : ndarray of complex, shape (n + F,)
        rad/s. The ``n`` relocated poles (real ones, increasing, then the upper members of
        the pairs, then their conjugates), then the F fixed ones in the same layout.
    residues : ndarray of complex, shape (C, n + F)
        Each channel's residue of each pole (conjugate poles have conjugate residues).
    constants : ndarray of float, shape (C,)
        Each channel's ``d_c`` (0 unless fitted).
    n_relocated : int
        n, the number of relocated poles (the first ones of ``poles``).
    """

    poles: np.ndarray
    residues: np.ndarray
    constants: np.ndarray
    n_relocated: int

    def response(self, omega):
        """The fitted channels at ``s = j omega``.

        Parameters
        ----------
        omega : array_like of float, shape (K,)
            rad/s.

        Returns
        -------
        ndarray of complex, shape (C, K)
        """
        s = 1j * np.asarray(omega, float)
        terms = self.residues[:, :, None] / (s[None, None, :] - self.poles[None, :, None])
        return self.constants[:, None] + np.sum(terms, axis=1)


def initial_poles(omega, n_poles):
    """Gustavsen & Semlyen's start: ``n // 2`` pairs ``-b/100 +- j b`` with b log-spaced over
    the band (ends included), plus one real pole ``-geomean(omega)`` if n is odd.

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s, increasing, > 0.
    n_poles : int
        n.

    Returns
    -------
    ndarray of complex, shape (n,)
        The real pole first, then the upper members, then their conjugates.
    """
    rp, cp = _initial_split(np.asarray(omega, float), int(n_poles))
    return _join(rp, cp)


def _initial_split(omega, n):
    n_pairs = n // 2
    b = np.geomspace(omega[0], omega[-1], n_pairs) if n_pairs else np.zeros(0)
    cp = -b / 100 + 1j * b
    rp = np.array([-np.exp(np.mean(np.log(omega)))]) if n % 2 else np.zeros(0)
    return rp, cp


def _join(rp, cp):
    return np.concatenate([np.asarray(rp, float) + 0j, cp, np.conj(cp)])


def _split(poles, name):
    """(real poles, upper members of the pairs) of a conjugate-complete set, in its order."""
    poles = np.asarray(poles, complex).ravel()
    if not np.all(np.isfinite(poles)):
        raise OptionError(f"{name} must be finite, got {poles}")
    real = np.abs(poles.imag) <= _REAL_RTOL * np.abs(poles)
    upper, lower = poles[~real & (poles.imag > 0)], poles[~real & (poles.imag < 0)]
    if upper.size != lower.size or not np.allclose(np.sort_complex(np.conj(upper)),
                                                    np.sort_complex(lower)):
        raise OptionError(f"{name} must hold complete conjugate pairs, got {poles}; pass "
                          "both p and conj(p) of every complex pole")
    return poles[real].real, upper


def _basis(s, rp, cp, out=None):
    """Real-formulation partial-fraction basis, shape (M, n): ``1/(s-a)`` per real pole,
    ``1/(s-a) + 1/(s-a*)`` and ``j/(s-a) - j/(s-a*)`` per pair; written into ``out``
    (complex, (M, n) or a view of that shape) when given. All poles in one broadcast
    operation each: the same products as one pole at a time."""
    k = rp.size
    if out is None:
        out = np.empty((s.size, k + 2 * cp.size), complex)
    if k:
        np.divide(1.0, s[:, None] - rp, out=out[:, :k])
    if cp.size:
        u = 1.0 / (s[:, None] - cp)
        v = 1.0 / (s[:, None] - np.conj(cp))
        np.add(u, v, out=out[:, k::2])
        np.subtract(1j * u, 1j * v, out=out[:, k + 1::2])
    return out


def _state_matrices(rp, cp):
    """A and b of Gustavsen's real realisation of the basis (b = 1 or [2, 0])."""
    k = rp.size
    n = k + 2 * cp.size
    A = np.zeros((n, n))
    b = np.zeros(n)
    flat, step = A.reshape(-1), n + 1          # (a view) A[j, j] is flat[j * step]
    flat[:k * step:step] = rp
    b[:k] = 1.0
    if cp.size:
        first = k * step                       # A[k, k]: the first pair's block
        flat[first::step] = np.repeat(cp.real, 2)
        flat[first + 1::2 * step] = cp.imag                     # A[j, j + 1]
        flat[first + n::2 * step] = -cp.imag                    # A[j + 1, j]
        b[k::2] = 2.0
    return A, b


def _split_eigs(lam):
    """Real eigenvalues and the upper members of conjugate pairs of a real matrix."""
    lam = np.asarray(lam, complex)
    tol = _REAL_RTOL * np.maximum(np.abs(lam), _TINY)
    is_real = np.abs(lam.imag) <= tol
    real, upper = lam.real[is_real], lam[~is_real & (lam.imag > 0)]     # (copies)
    real.sort()
    upper.sort()                                 # (np.sort_complex's order: real, imag)
    return real, upper


def _lstsq_scaled(Mat, rhs):
    """Least squares with unit-norm columns (scipy's gelsd), solution scaled back."""
    scale = _column_norms(Mat)
    scale[scale == 0] = 1.0
    x = _lstsq(Mat / scale, rhs)
    return x / scale


@functools.lru_cache(maxsize=None)
def _gelsd(m, n):
    """(dgelsd, lwork, liwork) for a real (m, n) problem with one right-hand side and
    ``rcond = eps``: the routine and workspace sizes scipy.linalg.lstsq asks LAPACK for,
    asked once per shape."""
    gelsd, gelsd_lwork = scipy.linalg.get_lapack_funcs(("gelsd", "gelsd_lwork"),
                                                        dtype=np.float64)
    work, iwork, info = gelsd_lwork(m, n, 1, _EPS)
    if info != 0:                                                       # pragma: no cover
        raise ValueError(f"LAPACK dgelsd's workspace query failed (info={info})")
    return gelsd, int(work.real), int(iwork)


@functools.lru_cache(maxsize=None)
def _qr_funcs():
    """LAPACK's (dgeqrf, dormqr), looked up once."""
    return scipy.linalg.get_lapack_funcs(("geqrf", "ormqr"), dtype=np.float64)


def _lstsq(a, b, overwrite=False):
    """``scipy.linalg.lstsq(a, b)[0]`` for a real (m, n) ``a`` and (m,) ``b``: the same
    LAPACK call (dgelsd, ``rcond = eps``, the same workspace), so the same numbers to the
    last bit, without lstsq's per-call wrapping and workspace query, which cost about as
    much as the solve at the sizes of a relocation (a few hundred rows, ten columns) and
    made a third of a vector fitting's time. Non-finite input raises ValueError, as lstsq
    does. ``overwrite=True`` lets LAPACK work in ``a`` and ``b`` (no copies; ``a`` then
    best Fortran-ordered), whose contents are then lost.

    A tall problem (``m >= max(2 n, _TALL_ROWS)``) takes dgelsd's own path for many more
    rows than columns in three calls: ``a = QR`` (dgeqrf), ``Q^T b`` (dormqr), both with
    the workspace dgelsd gives them, then dgelsd on the (n, n) ``R``, which repeats the
    rest of that path. The same numbers to the last bit, in about half the time at a
    thousand rows (dgelsd's one call spends more than twice the QR's time there)."""
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("array must not contain infs or NaNs")
    m, n = a.shape
    gelsd, lwork, liwork = _gelsd(m, n)
    if m >= max(2 * n, _TALL_ROWS):
        geqrf, ormqr = _qr_funcs()
        qr, tau, _, info = geqrf(a, lwork=lwork - n, overwrite_a=overwrite)
        if info == 0:
            qtb, _, info = ormqr("L", "T", qr, tau, b[:, None], lwork=lwork - n,
                                 overwrite_c=overwrite)
        if info != 0:                                                   # pragma: no cover
            raise ValueError(f"LAPACK dgeqrf/dormqr failed (info={info})")
        return _lstsq(np.array(np.triu(qr[:n]), order="F"), qtb[:n, 0].copy(), overwrite=True)
    if m < n:                                # room for the (n,) solution, as lstsq makes
        b = np.concatenate([b, np.zeros(n - m)])
    x, _, _, info = gelsd(a, b, lwork, liwork, _EPS, overwrite, overwrite)
    if info > 0:
        raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")
    if info < 0:                                                        # pragma: no cover
        raise ValueError(f"illegal value in argument {-info} of LAPACK dgelsd")
    return x[:n]


def _r_factor(block, m, n_cols):
    """R factor (n_cols, n_cols) of the stacked real matrix ``[Re A; Im A]`` (2M, n_cols),
    ``A`` complex (M, n_cols) formed ``_CHUNK_POINTS`` rows at a time by ``block(i, j)``
    (which returns ``A[i:j].T``, shape (n_cols, j - i)), each block's QR (LAPACK dgeqrf)
    folded into the running R: ``||A x - b|| = ||R x - Q^T b||``, so a least-squares
    problem in A is one in R (same solution; the rounding differs). Memory O(chunk x
    n_cols) instead of O(M x n_cols)."""
    from scipy.linalg import lapack

    # rows: the running R (n_cols), then the block's real and imaginary parts; a short
    # last block leaves zero rows, which do not change R
    buf = np.zeros((n_cols + 2 * _CHUNK_POINTS, n_cols), order="F")
    below = np.tril_indices(n_cols, -1)           # dgeqrf's reflectors below R's diagonal
    lwork = None
    for i in range(0, m, _CHUNK_POINTS):
        a = block(i, min(i + _CHUNK_POINTS, m))
        k = a.shape[1]
        cols = buf.T                              # (n_cols, rows), C order: a view
        cols[:, n_cols:n_cols + k] = a.real
        cols[:, n_cols + k:n_cols + 2 * k] = a.imag
        if k < _CHUNK_POINTS:
            cols[:, n_cols + 2 * k:] = 0.0
        if lwork is None:
            lwork = int(lapack.dgeqrf_lwork(*buf.shape)[0])
        qr, _, _, info = lapack.dgeqrf(buf, lwork=lwork, overwrite_a=True)
        if info != 0:                                        # pragma: no cover
            raise np.linalg.LinAlgError(f"dgeqrf failed (info={info})")
        buf = qr                                  # the same memory (overwrite_a, F order)
        buf[below] = 0.0
    return np.array(buf[:n_cols])


def _check(omega, response, weights, weighting):
    """(omega (M,), response (C, M), row weights (C, M)) or a DataError/OptionError."""
    omega = np.asarray(omega, float)
    if omega.ndim != 1 or omega.size < 2 or not np.all(np.isfinite(omega)) \
            or np.any(omega <= 0) or np.any(np.diff(omega) <= 0):
        raise DataError("omega must be a 1-D array of at least 2 finite, positive, strictly "
                        f"increasing frequencies (rad/s), got shape {omega.shape}")
    phi = np.asarray(response, complex)
    phi = phi[None, :] if phi.ndim == 1 else phi
    if phi.ndim != 2 or phi.shape[1] != omega.size or phi.shape[0] < 1:
        raise DataError(f"response must have shape (M,) or (C, M) with M = {omega.size} "
                        f"(the frequencies), got {np.shape(response)}")
    if weighting not in ("relative", "none"):
        raise OptionError(f"weighting must be 'relative' or 'none', got {weighting!r}")
    if not np.all(np.isfinite(phi)) or (weighting == "relative" and np.any(phi == 0)):
        raise DataError("response must be finite (and nonzero with weighting='relative', "
                        "whose row weights are 1/|response|): drop or fix those points")
    wt = 1.0 / np.abs(phi) if weighting == "relative" else np.ones(phi.shape)
    if weights is not None:
        w = np.asarray(weights, float)
        if w.shape not in (omega.shape, phi.shape) or not np.all(np.isfinite(w)) \
                or np.any(w < 0):
            raise DataError(f"weights must be finite, >= 0, shape {omega.shape} or "
                            f"{phi.shape}, got shape {w.shape}")
        wt = wt * np.sqrt(w)
    return omega, phi, wt


def vectfit(omega, response, n_poles, *, weights=None, weighting="relative", n_iter=10,
            initial=None, fixed=None, constant=True, stable=False):
    """Relaxed vector fitting of one or more channels with common poles.

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        rad/s, positive, strictly increasing.
    response : array_like of complex, shape (M,) or (C, M)
        The channels' samples ``G_c(j omega)``; one channel may be given as a 1-D array.
    n_poles : int
        n >= 1, the poles relocated by the iterations.
    weights : array_like of float, shape (M,) or (C, M), optional
        Squared-residual weights; their square roots multiply the row weights.
    weighting : {"relative", "none"}, optional
        Row weights ``1/|G_c|`` (the relative error, the package's measure; default) or 1.
    n_iter : int, optional
        Pole-relocation iterations, >= 0 (default 10; 0 fits residues at ``initial``).
    initial : array_like of complex, shape (n,), optional
        Starting poles, conjugate pairs complete; default :func:`initial_poles`.
    fixed : array_like of complex, shape (F,), optional
        Poles kept as they are (conjugate pairs complete): in the basis of the fitted
        functions but not in sigma's, so the iterations relocate only the other n (a
        channel's own poles beside shared ones).
    constant : bool, optional
        Fit a constant ``d_c`` per channel (default True); else the fit is strictly proper.
    stable : bool, optional
        Flip relocated poles with ``Re > 0`` to the left half plane after each iteration
        (Gustavsen & Semlyen's option). Default False.

    Returns
    -------
    VectorFit
        Poles, each channel's residues and constant.

    Raises
    ------
    DataError
        Bad frequencies, responses or weights, or fewer rows than unknowns.
    OptionError
        Bad ``n_poles``, ``n_iter``, ``weighting`` or pole sets.

    Notes
    -----
    Each iteration solves, real and imaginary parts stacked, real unknowns, the linear
    least-squares problem (per channel c, with the current poles' real basis ``phi_k``)

        w_c (sum_k c_ck phi_k + d_c) - w_c G_c (sum_k ct_k phi_k + dt) = 0,
        (||w G|| / M) Re sum_i (sum_k ct_k phi_k(s_i) + dt) = ||w G||     (relaxation)

    and the new poles are the zeros of ``sigma``, ``eig(A - b ct^T / dt)`` with ``(A, b)``
    Gustavsen's real realisation of the basis. If ``|dt|`` falls below 1e-8 it is fixed to
    ``1e-8 sign(dt)`` and sigma re-fitted without the relaxation row, as Gustavsen does.
    The residues are finally fitted per channel at the last poles (:func:`fit_residues`).
    """
    n = check_order(n_poles, "n_poles")
    k_iter = check_order(n_iter, "n_iter", 0)
    omega, phi, wt = _check(omega, response, weights, weighting)
    if initial is None:
        rp, cp = _initial_split(omega, n)
    else:
        rp, cp = _split(initial, "initial")
        if rp.size + 2 * cp.size != n:
            raise OptionError(f"initial must hold n_poles = {n} poles, got "
                              f"{rp.size + 2 * cp.size}")
    fixed = ((np.zeros(0), np.zeros(0, complex)) if fixed is None
             else _split(fixed, "fixed"))
    nd = 1 if constant else 0
    n_own = n + fixed[0].size + 2 * fixed[1].size + nd
    if 2 * omega.size < n_own + n + 1:
        raise DataError(f"too few points ({omega.size}) for {n} poles: vector fitting needs "
                        f"2 M >= {n_own + n + 1} (real and imaginary parts); fit fewer poles")
    s = 1j * omega
    if omega.size > _TALL_POINTS:
        for _ in range(k_iter):
            rp, cp = _relocate_tall(s, phi, wt, rp, cp, fixed, nd, stable)
    elif k_iter:
        consts = _constants(s, phi, wt, fixed)
        for _ in range(k_iter):
            rp, cp = _relocate(s, phi, wt, rp, cp, fixed, nd, stable, consts)
    return _residues(s, phi, wt, [(rp, cp), fixed], nd, n)


def _relocate(s, phi, wt, rp, cp, fixed, nd, stable, consts=None):
    """One iteration: the zeros of the fitted sigma -> (real poles, upper members).
    ``consts``: :func:`_constants` of the fit (the same at every iteration), or None to
    compute them here."""
    m = s.size
    n = rp.size + 2 * cp.size
    sig = np.empty((m, n + 1), complex)                          # ct, dt
    Phi = _basis(s, rp, cp, out=sig[:, :n])                      # (M, n)
    sig[:, n] = 1.0
    extra, norm = _constants(s, phi, wt, fixed) if consts is None else consts
    if phi.shape[0] == 1:
        return _relocate_one(phi[0], wt[0], Phi, sig, extra, nd, norm, rp, cp, stable)
    left = [Phi] + ([] if extra is None else [extra])
    left = np.hstack(left + [sig[:, n:]]) if nd else np.hstack(left)  # c (fixed, own), d
    nl = left.shape[1]
    rows = []                                   # each channel's own unknowns eliminated
    for c in range(phi.shape[0]):
        Mc = wt[c][:, None] * np.hstack([left, -phi[c][:, None] * sig])
        r = np.linalg.qr(np.vstack([Mc.real, Mc.imag]), mode="r")
        rows.append(r[nl:nl + n + 1, nl:])
    K = np.vstack(rows)
    return _relocated(K, 0, norm, np.add.reduce(sig, axis=0).real, m, n, rp, cp, stable)


def _constants(s, phi, wt, fixed):
    """What every relocation of a fit uses unchanged: the fixed poles' basis (None without
    fixed poles) and ``||wt phi||``, the relaxation's scale."""
    extra = _basis(s, *fixed) if fixed[0].size + fixed[1].size else None
    return extra, np.linalg.norm(wt * phi)


def _column_norms(a):
    """``np.linalg.norm(a, axis=0)`` of a real (m, n) ``a``: the same sums (its path for
    one axis, ``sqrt(add.reduce(conj(a) a))``, whose conjugate of a real array is a copy)."""
    return np.sqrt(np.add.reduce(a * a, axis=0))


def _relocate_one(phi, wt, Phi, sig, extra, nd, norm, rp, cp, stable):
    """:func:`_relocate` of one channel: the stacked problem in all unknowns as it stands,
    ``[Re; Im]`` of ``wt * [Phi, extra, 1 | -phi sig]`` and the relaxation row written
    into one matrix (no stacked copies; each entry the same product as ``wt * M`` in
    complex arithmetic, whose imaginary part of ``wt`` is zero), its columns scaled into a
    Fortran-ordered copy that LAPACK takes without copying it again."""
    m, n = Phi.shape
    nl = n + (0 if extra is None else extra.shape[1]) + nd
    A = np.empty((2 * m + 1, nl + n + 1))         # [Re rows; Im rows; relaxation row]
    re, im, w = A[:m], A[m:2 * m], wt[:, None]
    for cols, block in ((slice(0, n), Phi),
                        (slice(n, nl - nd), extra),
                        (slice(nl, None), -phi[:, None] * sig)):
        if block is not None:
            np.multiply(block.real, w, out=re[:, cols])
            np.multiply(block.imag, w, out=im[:, cols])
    if nd:
        re[:, nl - 1], im[:, nl - 1] = wt, 0.0
    A[-1, :nl] = 0.0
    np.multiply(np.add.reduce(sig, axis=0).real, norm / m, out=A[-1, nl:])
    rhs = np.zeros(2 * m + 1)
    rhs[-1] = norm
    scale = _column_norms(A)
    scale[scale == 0] = 1.0
    scaled = np.empty(A.shape, order="F")
    np.divide(A, scale, out=scaled)
    x = _lstsq(scaled, rhs, overwrite=True) / scale
    return _new_poles(A[:-1], nl, x[nl:nl + n], x[-1], rp, cp, stable)


def _relocate_tall(s, phi, wt, rp, cp, fixed, nd, stable):
    """:func:`_relocate` of many frequencies (above ``_TALL_POINTS``): each channel's
    matrix reduced block by block to its R factor (:func:`_r_factor`), which stands for it
    in the same least-squares problems; memory O(chunk x unknowns)."""
    m = s.size
    n = rp.size + 2 * cp.size
    n_fixed = fixed[0].size + 2 * fixed[1].size
    nl = n + n_fixed + nd
    colsum = np.zeros(n + 1)

    def block(c, i, j):                 # the matrix's rows i:j, transposed (columns, rows)
        w, wphi = wt[c, i:j], -wt[c, i:j] * phi[c, i:j]
        a = np.empty((nl + n + 1, j - i), complex)
        _basis_rows(a[:n], s[i:j], rp, cp)                          # Phi
        if c == 0:
            colsum[:n] += np.real(np.sum(a[:n], axis=1))
            colsum[n] += j - i
        np.multiply(a[:n], wphi, out=a[nl:nl + n])                  # sigma: Phi, 1
        a[-1] = wphi
        a[:n] *= w
        if n_fixed:
            _basis_rows(a[n:n + n_fixed], s[i:j], *fixed)
            a[n:n + n_fixed] *= w
        if nd:
            a[nl - 1] = w
        return a

    rs = [_r_factor(lambda i, j, c=c: block(c, i, j), m, nl + n + 1)
          for c in range(phi.shape[0])]
    if phi.shape[0] == 1:
        K, lead = rs[0], nl
    else:
        K, lead = np.vstack([r[nl:nl + n + 1, nl:] for r in rs]), 0
    norm = np.linalg.norm(wt * phi)
    return _relocated(K, lead, norm, colsum, m, n, rp, cp, stable)


def _basis_rows(out, s, rp, cp):
    """:func:`_basis` transposed, written into ``out`` (n, K): ``1/(s - a)`` per real pole;
    per pair, with ``d = (s - Re a)^2 + (Im a)^2 = (s - a)(s - conj a)``, ``2 (s - Re a)/d``
    and ``-2 Im a / d`` (the sum and the rotated difference of its two fractions)."""
    k = rp.size
    if k:
        np.divide(1.0, s[None, :] - rp[:, None], out=out[:k])
    if cp.size:
        x = s[None, :] - cp.real[:, None]                          # (pairs, K)
        inv = 1.0 / (x * x + (cp.imag ** 2)[:, None])
        np.multiply(x, 2.0 * inv, out=out[k::2])
        np.multiply(inv, -2.0 * cp.imag[:, None], out=out[k + 1::2])


def _relocated(K, lead, norm, colsum, m, n, rp, cp, stable):
    """The new poles from the stacked problem ``K`` (its first ``lead`` columns the
    channel's own unknowns, then ct (n) and dt) with the relaxation row ``colsum * norm /
    m`` (``colsum``: the real parts of the column sums of sigma's basis, (n + 1,))."""
    relax = np.concatenate([np.zeros(lead), colsum])
    relax *= norm / m
    x = _lstsq_scaled(np.vstack([K, relax]), np.concatenate([np.zeros(K.shape[0]), [norm]]))
    return _new_poles(K, lead, x[lead:lead + n], x[-1], rp, cp, stable)


def _new_poles(K, lead, ct, dt, rp, cp, stable):
    """The zeros of sigma, ``eig(A - b ct^T / dt)``, as (real poles, upper members); a
    ``|dt|`` below ``_DT_MIN`` is fixed to it and ``ct`` re-fitted from ``K`` (the problem
    without its relaxation row) with ``dt``'s column on the right-hand side."""
    if abs(dt) < _DT_MIN:
        dt = _DT_MIN if dt >= 0 else -_DT_MIN
        ct = _lstsq_scaled(K[:, :-1], -dt * K[:, -1])[lead:]
    A, b = _state_matrices(rp, cp)
    lam = np.linalg.eigvals(A - b[:, None] * ct / dt)          # (np.outer's products)
    if stable:
        lam = np.where(lam.real > 0, -np.conj(lam), lam)
    return _split_eigs(lam)


def _coefficients(s, phi, wt, sets, nd, scaled=True):
    """Real basis coefficients (C, n_cols) of each channel at fixed poles: weighted linear
    least squares, real and imaginary parts stacked (columns of unit norm if ``scaled``)."""
    if s.size > _TALL_POINTS:
        return _coefficients_tall(s, phi, wt, sets, nd, scaled)
    cols = [_basis(s, rp, cp) for rp, cp in sets if rp.size + cp.size]
    cols = cols or [np.zeros((s.size, 0), complex)]
    left = np.hstack(cols + [np.ones((s.size, 1))]) if nd else np.hstack(cols)
    out = []
    for c in range(phi.shape[0]):
        Mc = wt[c][:, None] * left
        f = wt[c] * phi[c]
        solve = _lstsq_scaled if scaled else (lambda a, b: scipy.linalg.lstsq(a, b)[0])
        out.append(solve(np.vstack([Mc.real, Mc.imag]), np.concatenate([f.real, f.imag])))
    return np.array(out).reshape(phi.shape[0], left.shape[1])


def _coefficients_tall(s, phi, wt, sets, nd, scaled):
    """:func:`_coefficients` of many frequencies: each channel's ``[A | f]`` reduced block
    by block to its R factor (:func:`_r_factor`), whose leading block and last column
    stand for ``A`` and ``f`` in the same least-squares problem."""
    n_cols = sum(rp.size + 2 * cp.size for rp, cp in sets) + nd

    def block(c, i, j):                   # [A | f] of channel c, rows i:j, transposed
        a = np.empty((n_cols + 1, j - i), complex)
        k = 0
        for rp, cp in sets:
            _basis_rows(a[k:k + rp.size + 2 * cp.size], s[i:j], rp, cp)
            k += rp.size + 2 * cp.size
        if nd:
            a[k] = 1.0
        a[-1] = phi[c, i:j]
        a *= wt[c, i:j]
        return a

    solve = _lstsq_scaled if scaled else (lambda a, b: scipy.linalg.lstsq(a, b)[0])
    out = []
    for c in range(phi.shape[0]):
        r = _r_factor(lambda i, j, c=c: block(c, i, j), s.size, n_cols + 1)
        out.append(solve(r[:n_cols, :n_cols], r[:n_cols, n_cols]))
    return np.array(out).reshape(phi.shape[0], n_cols)


def _residues(s, phi, wt, sets, nd, n_relocated, scaled=True):
    """:class:`VectorFit` of the pole sets ``[(real, upper), ...]`` (in that order)."""
    coef = _coefficients(s, phi, wt, sets, nd, scaled)
    poles, residues, k = [], [], 0
    for rp, cp in sets:
        real = coef[:, k:k + rp.size]
        pair = coef[:, k + rp.size:k + rp.size + 2 * cp.size].reshape(phi.shape[0], -1, 2)
        upper = pair[:, :, 0] + 1j * pair[:, :, 1]
        k += rp.size + 2 * cp.size
        poles.append(_join(rp, cp))
        residues.append(np.concatenate([real + 0j, upper, np.conj(upper)], axis=1))
    consts = np.array([float(v) for v in coef[:, k]]) if nd else np.zeros(phi.shape[0])
    return VectorFit(np.concatenate(poles), np.concatenate(residues, axis=1), consts,
                     int(n_relocated))


def fit_residues(omega, response, poles, *, weights=None, weighting="relative",
                 constant=True, scaled=True):
    """Each channel's residues at given poles (the "least-squares frequency-domain" step).

    Linear least squares of ``G_c(s) ~ d_c + sum_k r_ck / (s - p_k)``, real and imaginary
    parts stacked, with the row weights of :func:`vectfit`.

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        rad/s, positive, strictly increasing.
    response : array_like of complex, shape (M,) or (C, M)
    poles : array_like of complex, shape (n,)
        rad/s, conjugate pairs complete.
    weights : array_like of float, shape (M,) or (C, M), optional
        Squared-residual weights.
    weighting : {"relative", "none"}, optional
        Row weights ``1/|G_c|`` (default) or 1.
    constant : bool, optional
        Fit ``d_c`` (default True); else 0.
    scaled : bool, optional
        Solve with the columns scaled to unit norm (default True, as :func:`vectfit`);
        False: the plain least-squares solution (scipy's gelsd), the modal start's LSFD
        step (:func:`freqid_casadi.modal._start.lsfd_residues`). The two differ at rounding
        level, except where the problem is rank-deficient to working precision (a strictly
        proper channel's constant), where gelsd's cut-off keeps different noise.

    Returns
    -------
    residues : ndarray of complex, shape (C, n)
        In the order of ``poles``; conjugate poles get conjugate residues.
    constants : ndarray of float, shape (C,)
    """
    omega, phi, wt = _check(omega, response, weights, weighting)
    given = np.asarray(poles, complex).ravel()
    rp, cp = _split(given, "poles")
    if 2 * omega.size < given.size + int(bool(constant)):
        raise DataError(f"too few points ({omega.size}) for {given.size} residues")
    fit = _residues(1j * omega, phi, wt, [(rp, cp)], 1 if constant else 0, given.size,
                    bool(scaled))
    # the fit lists the real poles, the upper members, their conjugates: back to the
    # caller's order (a lower member takes the conjugate of its nearest upper one)
    real = np.abs(given.imag) <= _REAL_RTOL * np.abs(given)
    upper, lower = ~real & (given.imag > 0), ~real & (given.imag < 0)
    order = np.zeros(given.size, int)
    order[real] = np.arange(rp.size)
    order[upper] = rp.size + np.arange(cp.size)
    order[lower] = [rp.size + cp.size + int(np.argmin(np.abs(np.conj(cp) - p)))
                    for p in given[lower]]
    return fit.residues[:, order], fit.constants
