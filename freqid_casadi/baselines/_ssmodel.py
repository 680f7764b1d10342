"""A continuous-time SISO state-space model with the interface of RationalDelayModel.

Every baseline returns a :class:`StateSpaceModel`, so reports can treat the baselines and
the package's own :class:`~freqid_casadi.core.model.RationalDelayModel` alike:
``frequency_response(omega)``, ``poles()``, ``zeros()``, ``is_stable()``,
``is_minimum_phase()``, ``to_control()``, ``order``, ``delay``, ``name``.

The module also holds the small realisation kernels the baselines share: the bilinear
(Tustin) map between discrete and continuous time, a cascade of first-order sections, a
real pole-residue realisation, and SLICOT balanced truncation.
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..errors import DataError, OptionError, StructureError
from ..core.metrics import DelayedResponse
from ..core.model import attach_delay

__all__ = ["StateSpaceModel", "count_rhp"]

# Largest number of complex entries of one batch of resolvent matrices (memory cap).
_BATCH_ENTRIES = 2_000_000


@dataclass(frozen=True, eq=False)
class StateSpaceModel(DelayedResponse):
    """``G(s) = exp(-delay s) (C (sI - A)^{-1} B + D)``, continuous time, one input, one output.

    Parameters
    ----------
    A : array_like of float, shape (n, n)
        State matrix (1/s).
    B : array_like of float, shape (n, 1) or (n,)
        Input matrix.
    C : array_like of float, shape (1, n) or (n,)
        Output matrix.
    D : float or array_like of shape (1, 1)
        Feedthrough.
    delay : float, optional
        Input-output delay in seconds, >= 0 (0 for every baseline that fits data).
    name : str, optional
        Label of the method that produced the model.

    Raises
    ------
    StructureError
        Wrong shapes, non-finite entries or a negative delay.

    Notes
    -----
    Frozen; the matrices are stored as read-only float arrays. ``n = 0`` is a static gain.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: float = 0.0
    delay: float = 0.0
    name: str = "state-space"

    def __post_init__(self):
        A = np.array(self.A, dtype=float, copy=True)
        if A.size == 0:
            A = np.zeros((0, 0))
        if A.ndim != 2 or A.shape[0] != A.shape[1]:
            raise StructureError(f"A must be a square matrix, got shape {np.shape(self.A)}")
        n = A.shape[0]
        B = np.array(self.B, dtype=float, copy=True).reshape(-1, 1) if n else np.zeros((0, 1))
        C = np.array(self.C, dtype=float, copy=True).reshape(1, -1) if n else np.zeros((1, 0))
        if B.shape != (n, 1):
            raise StructureError(f"B must have shape ({n}, 1) for A of order {n}, "
                                 f"got {np.shape(self.B)} (only SISO models are supported)")
        if C.shape != (1, n):
            raise StructureError(f"C must have shape (1, {n}) for A of order {n}, "
                                 f"got {np.shape(self.C)} (only SISO models are supported)")
        D = np.asarray(self.D, dtype=float)
        if D.size != 1:
            raise StructureError(f"D must be a scalar (SISO), got shape {D.shape}")
        D = float(D.reshape(-1)[0])
        for label, M in (("A", A), ("B", B), ("C", C), ("D", np.array([D]))):
            if not np.all(np.isfinite(M)):
                raise StructureError(f"{label} must be finite, it has NaN or inf entries")
        delay = float(self.delay)
        if not np.isfinite(delay) or delay < 0:
            raise StructureError(f"delay must be finite and >= 0 (s), got {self.delay!r}")
        if not isinstance(self.name, str):
            raise StructureError(f"name must be a string, got {type(self.name).__name__}")
        for M in (A, B, C):
            M.setflags(write=False)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "B", B)
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "D", D)
        object.__setattr__(self, "delay", delay)

    __hash__ = None

    def __eq__(self, other):
        return (isinstance(other, StateSpaceModel) and np.array_equal(self.A, other.A)
                and np.array_equal(self.B, other.B) and np.array_equal(self.C, other.C)
                and self.D == other.D and self.delay == other.delay)

    # ------------------------------------------------------------------ properties
    @property
    def order(self):
        """Number of states n (the McMillan degree if the realisation is minimal)."""
        return self.A.shape[0]

    @property
    def n_states(self):
        """Alias of :attr:`order`."""
        return self.order

    # ------------------------------------------------------------------ evaluation
    def rational_response(self, omega):
        """``C (j omega I - A)^{-1} B + D`` without the delay.

        Parameters
        ----------
        omega : array_like of float, shape (M,)
            Frequencies in rad/s.

        Returns
        -------
        ndarray of complex, shape (M,)

        Notes
        -----
        A is reduced once to upper Hessenberg form ``H = Q^T A Q`` (Laub's method, as
        SLICOT TB05AD does); each frequency is then one LU solve with partial pivoting of
        ``(j omega I - H) x = Q^T B``, batched over frequencies.
        """
        omega = np.asarray(omega, dtype=float)
        shape = omega.shape
        w = omega.reshape(-1)
        n = self.order
        if n == 0:
            return np.full(shape, self.D, dtype=complex)
        H, Q = scipy.linalg.hessenberg(self.A, calc_q=True)
        b = (Q.T @ self.B).astype(complex)
        c = (self.C @ Q).reshape(-1)
        out = np.empty(w.size, dtype=complex)
        eye = np.eye(n)
        step = max(1, _BATCH_ENTRIES // (n * n))
        for i0 in range(0, w.size, step):
            wk = w[i0:i0 + step]
            M = 1j * wk[:, None, None] * eye - H
            x = np.linalg.solve(M, np.broadcast_to(b, (wk.size, n, 1)))
            out[i0:i0 + step] = x[:, :, 0] @ c + self.D
        return out.reshape(shape)


    # ------------------------------------------------------------------ poles / zeros
    def poles(self):
        """Eigenvalues of A, complex ndarray of shape (n,) (1/s)."""
        if self.order == 0:
            return np.zeros(0, dtype=complex)
        return np.linalg.eigvals(self.A).astype(complex)

    def zeros(self):
        """Finite transmission zeros, complex ndarray (1/s).

        Computed by SLICOT AB08ND (slycot), as python-control's ``StateSpace.zeros``
        does, called directly: importing python-control (it imports matplotlib) cost
        about 3 s of every process's first fit. The Rosenbrock pencil
        ``[[A - sI, B], [C, D]]`` is reduced so that the infinite zeros are removed
        exactly, then the finite ones are the generalised eigenvalues. Without slycot,
        python-control's own fallback is used.
        """
        if self.order == 0:
            return np.zeros(0, dtype=complex)
        try:
            from slycot import ab08nd
        except ImportError:
            return np.asarray(self._control_ss().zeros(), dtype=complex)
        n = self.order
        A = np.array(self.A, dtype=float).reshape(n, n)
        B = np.array(self.B, dtype=float).reshape(n, -1)
        C = np.array(self.C, dtype=float).reshape(-1, n)
        D = np.array([[self.D]], dtype=float)
        out = ab08nd(n, B.shape[1], C.shape[0], A, B, C, D)
        nu = out[0]
        if nu == 0:
            return np.zeros(0, dtype=complex)
        return np.asarray(scipy.linalg.eigvals(out[8][0:nu, 0:nu], out[9][0:nu, 0:nu]),
                          dtype=complex)

    def is_stable(self):
        """True if every pole has a negative real part."""
        return bool(np.all(self.poles().real < 0))

    def is_minimum_phase(self):
        """True if every finite zero has a negative real part."""
        return bool(np.all(self.zeros().real < 0))

    # ------------------------------------------------------------------ export
    def _control_ss(self):
        import control as ct

        return ct.ss(self.A, self.B, self.C, [[self.D]])

    def to_control(self, pade_order=None):
        """The model as a python-control ``StateSpace``.

        Parameters
        ----------
        pade_order : int, optional
            If given, the delay is included as a Padé approximation of that order;
            otherwise it is left out and stored as the attribute ``delay`` (s), as
            :meth:`RationalDelayModel.to_control` does.

        Returns
        -------
        control.StateSpace
        """
        return attach_delay(self._control_ss(), self.delay, pade_order)

    def __repr__(self):
        return (f"StateSpaceModel(name={self.name!r}, order={self.order}, "
                f"delay={self.delay:.6g}, D={self.D:.6g})")


def count_rhp(model, tol=0.0):
    """Numbers of right-half-plane poles and zeros of a model.

    Parameters
    ----------
    model : object with ``poles()`` and ``zeros()``
        A :class:`StateSpaceModel`, a :class:`~freqid_casadi.core.model.RationalDelayModel`,
        or any object with the same two methods.
    tol : float, optional
        A root counts when its real part is > ``tol`` (default 0).

    Returns
    -------
    n_rhp_poles, n_rhp_zeros : int
        Roots with ``Re > tol``; a model that is stable and minimum phase gives (0, 0).
    """
    p = np.asarray(model.poles(), dtype=complex)
    z = np.asarray(model.zeros(), dtype=complex)
    return int(np.count_nonzero(p.real > tol)), int(np.count_nonzero(z.real > tol))


# --------------------------------------------------------------------------- kernels


def as_abcd(model):
    """``(A, B, C, D, delay, name)`` of a StateSpaceModel, a RationalDelayModel (through
    its ``to_control()``, delay kept) or a python-control ``StateSpace``."""
    if isinstance(model, StateSpaceModel):
        return model.A, model.B, model.C, model.D, model.delay, model.name
    sys = model.to_control() if hasattr(model, "to_control") else model
    try:
        A, B, C, D = (np.asarray(sys.A, float), np.asarray(sys.B, float),
                      np.asarray(sys.C, float), np.asarray(sys.D, float))
    except AttributeError:
        raise DataError(
            f"model must be a StateSpaceModel, a RationalDelayModel or a control.StateSpace, "
            f"got {type(model).__name__}") from None
    if B.shape[1:] != (1,) or C.shape[:1] != (1,):
        raise DataError(f"only SISO models are supported, got B {B.shape}, C {C.shape}")
    delay = float(getattr(model, "delay", getattr(sys, "delay", 0.0)) or 0.0)
    name = getattr(model, "name", None) or type(model).__name__
    return A, B, C, float(D.reshape(-1)[0]), delay, str(name)


def bilinear_d2c(A, B, C, D, T):
    """Continuous-time realisation of ``Gd(z)`` under ``z = (1 + sT/2)/(1 - sT/2)``.

    With ``alpha = 2/T`` and ``E = (I + A)^{-1}``::

        Ac = alpha E (A - I),  Bc = sqrt(2 alpha) E B,  Cc = sqrt(2 alpha) C E,
        Dc = D - C E B

    so that ``Gc(s) = Gd((alpha + s)/(alpha - s))`` exactly (Tustin). The symmetric split
    of ``sqrt(2 alpha)`` keeps the Gramians (hence the Hankel singular values) unchanged.
    Needs ``-1`` not to be an eigenvalue of A.
    """
    A = np.asarray(A, float)
    n = A.shape[0]
    alpha = 2.0 / T
    if n == 0:
        return A, np.zeros((0, 1)), np.zeros((1, 0)), float(np.asarray(D).reshape(-1)[0])
    I = np.eye(n)
    E = np.linalg.solve(I + A, np.hstack([I, np.asarray(B, float).reshape(n, 1)]))
    EI, EB = E[:, :n], E[:, n:]
    Ac = alpha * (EI @ A - EI)
    Bc = np.sqrt(2 * alpha) * EB
    Cc = np.sqrt(2 * alpha) * (np.asarray(C, float).reshape(1, n) @ EI)
    Dc = float(np.asarray(D).reshape(-1)[0] - (np.asarray(C, float).reshape(1, n) @ EB)[0, 0])
    return Ac, Bc, Cc, Dc


def bilinear_c2d(A, B, C, D, T):
    """Inverse of :func:`bilinear_d2c`: ``Gd(z) = Gc(alpha (z - 1)/(z + 1))``, alpha = 2/T.

    With ``F = (alpha I - A)^{-1}``: ``Ad = F (alpha I + A)``, ``Bd = sqrt(2 alpha) F B``,
    ``Cd = sqrt(2 alpha) C F``, ``Dd = D + C F B``.
    """
    A = np.asarray(A, float)
    n = A.shape[0]
    alpha = 2.0 / T
    I = np.eye(n)
    F = np.linalg.solve(alpha * I - A, np.hstack([I, np.asarray(B, float).reshape(n, 1)]))
    FI, FB = F[:, :n], F[:, n:]
    Ad = FI @ (alpha * I + A)
    Bd = np.sqrt(2 * alpha) * FB
    Cd = np.sqrt(2 * alpha) * (np.asarray(C, float).reshape(1, n) @ FI)
    Dd = float(np.asarray(D).reshape(-1)[0] + (np.asarray(C, float).reshape(1, n) @ FB)[0, 0])
    return Ad, Bd, Cd, Dd


def real_cascade(zeros, poles, gain, name, s_ref=None, value_ref=None):
    """Realise ``gain * prod (s - z_k) / prod (s - p_k)`` with real zeros and poles as a
    series of first-order sections ``(s - z_k)/(s - p_k) = 1 + (p_k - z_k)/(s - p_k)``.

    ``len(zeros) <= len(poles)``; extra poles get strictly proper sections ``1/(s - p)``.
    If ``s_ref`` and ``value_ref`` are given, ``gain`` is ignored and chosen so that
    ``G(s_ref) = value_ref``. The state matrix is lower triangular with the poles on its
    diagonal: well conditioned even when the poles span many decades.
    """
    z = np.sort(np.asarray(zeros, float))[::-1]
    p = np.sort(np.asarray(poles, float))[::-1]
    if z.size > p.size:
        raise StructureError(f"improper: {z.size} zeros > {p.size} poles")
    n = p.size
    cvec = np.empty(n)
    dvec = np.empty(n)
    for k in range(n):
        if k < z.size:
            cvec[k], dvec[k] = p[k] - z[k], 1.0
        else:
            cvec[k], dvec[k] = 1.0, 0.0
    # series: u_1 = u, u_{k+1} = y_k = c_k x_k + d_k u_k
    A = np.diag(p)
    B = np.zeros((n, 1))
    C = np.zeros((1, n))
    # coefficient vectors of u_k in terms of (x, u): u_k = L[k] @ x + m[k] u
    L = np.zeros(n)
    m = 1.0
    for k in range(n):
        A[k, :] += L
        B[k, 0] = m
        L = dvec[k] * L
        L[k] += cvec[k]
        m = dvec[k] * m
    C[0, :] = L
    D = m
    if s_ref is not None:
        g = complex((C @ np.linalg.solve(s_ref * np.eye(n) - A, B))[0, 0] + D)
        gain = float(np.real(value_ref / g))
    return StateSpaceModel(A, B * gain, C, D * gain, 0.0, name)


def pair_conjugates(poles, residues, rtol=1e-8):
    """Split poles into real ones and conjugate pairs; average each pair exactly.

    Returns ``(real_p, real_r, cplx_p, cplx_r)``: real arrays for the real poles, and for
    each pair the member with positive imaginary part and its residue. A pole is real if
    ``|Im p| <= rtol |p|``. Each remaining pole in the upper half plane is matched with
    the nearest unused pole in the lower half plane (nearest to its conjugate); the pair
    is replaced by the mean of ``p`` and the conjugate of its partner (same for the
    residues), which makes the realisation real. A match counts only if the partner is
    within ``0.1 |Im p|`` of ``conj(p)``; a pole left without a partner (a real pole whose
    numerical imaginary part exceeded ``rtol``) is taken as real: its real part and the
    real part of its residue.
    """
    poles = np.asarray(poles, complex)
    residues = np.asarray(residues, complex)
    scale = np.maximum(np.abs(poles), np.finfo(float).tiny)
    is_real = np.abs(poles.imag) <= rtol * scale
    upper = [int(i) for i in np.flatnonzero(~is_real & (poles.imag > 0))]
    lower = [int(i) for i in np.flatnonzero(~is_real & (poles.imag < 0))]
    # most oscillatory poles first, so that the near-real ones are what is left over
    upper.sort(key=lambda k: -abs(poles[k].imag))
    real_idx = list(np.flatnonzero(is_real))
    cp, cr = [], []
    for i in upper:
        j = min(lower, key=lambda k: abs(poles[k] - np.conj(poles[i])), default=None)
        if j is None or abs(poles[j] - np.conj(poles[i])) > 0.1 * abs(poles[i].imag):
            real_idx.append(i)
            continue
        lower.remove(j)
        cp.append(0.5 * (poles[i] + np.conj(poles[j])))
        cr.append(0.5 * (residues[i] + np.conj(residues[j])))
    real_idx += lower
    real_idx = np.array(sorted(real_idx), dtype=int)
    return (poles[real_idx].real, residues[real_idx].real, np.array(cp, complex),
            np.array(cr, complex))


def pole_residue_ss(real_p, real_r, cplx_p, cplx_r, d, name):
    """Real block-diagonal realisation of ``d + sum r/(s - p)`` (conjugate pairs counted
    once, by their upper member). A pair ``a = a' + j a''``, ``c = c' + j c''`` becomes
    ``A = [[a', a''], [-a'', a']]``, ``B = [2, 0]^T``, ``C = [c', c'']`` (Gustavsen's real
    form)."""
    n = real_p.size + 2 * cplx_p.size
    A = np.zeros((n, n))
    B = np.zeros((n, 1))
    C = np.zeros((1, n))
    k = 0
    for p, r in zip(real_p, real_r):
        A[k, k], B[k, 0], C[0, k] = p, 1.0, r
        k += 1
    for p, r in zip(cplx_p, cplx_r):
        A[k:k + 2, k:k + 2] = [[p.real, p.imag], [-p.imag, p.real]]
        B[k:k + 2, 0] = [2.0, 0.0]
        C[0, k:k + 2] = [r.real, r.imag]
        k += 2
    return StateSpaceModel(A, B, C, float(np.real(d)), 0.0, name)


def ab09ad(A, B, C, order, dico):
    """SLICOT AB09AD square-root balanced truncation of a stable system.

    Returns ``(Ar, Br, Cr, hsv)``; ``hsv`` are all Hankel singular values, decreasing.
    The reduced order is ``min(order, minimal order)`` (SLICOT's rule).
    """
    from slycot import ab09ad as _ab09ad

    n = A.shape[0]
    nr, Ar, Br, Cr, hsv = _ab09ad(dico, "B", "N", n, 1, 1, np.array(A, float),
                                  np.array(B, float), np.array(C, float), nr=int(order),
                                  tol=0.0)
    return Ar[:nr, :nr], Br[:nr, :], Cr[:, :nr], np.asarray(hsv, float)


def check_order(order, name="order", minimum=1):
    """Validate an integer model order."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise OptionError(f"{name} must be an integer, got {order!r}")
    if order < minimum:
        raise OptionError(f"{name} must be >= {minimum}, got {order}")
    return int(order)
