"""Scale-free termination of a shared-pole stage (layer L3).

The single-channel stages stop when the least-squares residual is *relatively stationary*
(:class:`~freqid_casadi.solvers.termination.Termination`): the Gauss-Newton model cannot
lower the cost by more than the fraction ``ftol``. IPOPT's own ``tol`` is absolute on the
objective scaled by the stage's start cost, which it cannot meet once the cost has fallen by
many orders (measured on the beam: the 5 + 1 polish needs 410 iterations for IPOPT's tol and
is at its optimum to 7 digits long before). This module applies the same test to the
stacked weighted relative residual of :class:`~freqid_casadi.modal._nlp.SharedProblem`,
``r = [sqrt(w_c) Re(Q_c - 1); sqrt(w_c) Im(Q_c - 1)]`` over channels c and points, using
the block structure of its Jacobian (shared columns, then each channel's own block): the
cosine precheck costs one pass over the channels, and the projection ``||P r|| / ||r||``
(only computed when the precheck passes) one small SVD per channel plus one of size
``C n_shared x n_shared`` instead of a dense SVD of the whole Jacobian.
"""

import numpy as np

from .common import SUCCESS_STATUSES, Status
from .ipopt import ipopt_status
from .termination import StageMonitor, Termination, free_variables, \
    hold_tol, moved_onto_bounds, relative_stationarity, rounding_level

__all__ = ["SharedMonitor", "blocks", "column_norms", "gradient_and_norms",
           "block_projected_fraction", "SHARED_TERMINATION", "SNAP", "verdict"]

#: The shared stages' test: as the single-channel stages' default (ftol 1e-12), without the
#: LM polish (its dense Jacobian is what this module avoids).
SHARED_TERMINATION = Termination(ftol=1e-12, polish_steps=0)
#: Largest ``||J_j|| * distance / ||r||`` of a variable :meth:`SharedMonitor.snap` moves
#: onto its bound.
SNAP = 1e-6


def blocks(prob, z, n_points=None):
    """The weighted real residual and Jacobian, per channel.

    Parameters
    ----------
    prob : SharedProblem
    z : ndarray of float, shape (n_vars,)
    n_points : int, optional
        The first ``n_points`` frequencies (default all), ``L`` below.

    Returns
    -------
    (ndarray (C, 2L), ndarray (C, 2L, nl))
        ``r_c`` and ``dr_c / d[shared, own_c]`` (``nl = n_shared + n_own`` columns: the
        shared variables first).
    """
    m = prob.omega.size if n_points is None else int(n_points)
    E, Q, P, _ = prob._local(z, m)
    sw = np.sqrt(prob.weights[:, :m])
    r = (Q - 1.0) * sw
    J = prob._jac(E, Q, P) * sw[:, :, None]
    return (np.concatenate([r.real, r.imag], axis=1),
            np.concatenate([J.real, J.imag], axis=1))


def column_norms(prob, z, n_points=None):
    """``||J_j||`` of the stacked weighted Jacobian, shape (n_vars,), in O(C L nl).

    Parameters
    ----------
    prob : SharedProblem
    z : ndarray of float, shape (n_vars,)
    n_points : int, optional
        The first ``n_points`` frequencies (default all).

    Returns
    -------
    ndarray of float, shape (n_vars,)
    """
    return gradient_and_norms(prob, z, n_points)[2]


def gradient_and_norms(prob, z, n_points=None):
    """Cost, gradient and column norms of the stacked weighted residual from one pass over
    the channels (what the cosine precheck needs after every iteration).

    Parameters
    ----------
    prob : SharedProblem
    z : ndarray of float, shape (n_vars,)
    n_points : int, optional
        The first ``n_points`` frequencies (default all).

    Returns
    -------
    (float, ndarray (n_vars,), ndarray (n_vars,))
        ``||r||^2``, ``2 J^T r`` and ``||J_j||``.
    """
    m = prob.omega.size if n_points is None else int(n_points)
    E, Q, P, _ = prob._local(z, m)
    wt = prob.weights[:, :m]
    J = prob._jac(E, Q, P)
    r = Q - 1.0
    g = 2.0 * np.real(np.einsum("cl,cla->ca", wt * np.conj(r), J))
    sq = np.einsum("cl,cla->ca", wt, J.real ** 2 + J.imag ** 2)
    ns = prob.n_shared

    def stack(a):
        return np.concatenate([a[:, :ns].sum(axis=0), a[:, ns:].ravel()])
    return float(np.sum(wt * (r.real ** 2 + r.imag ** 2))), stack(g), np.sqrt(stack(sq))


def _unit_basis(a, rcond):
    """Orthonormal basis (2L, k) of the unit-column ``a``'s span (singular values below
    ``rcond`` times the largest dropped)."""
    cn = np.linalg.norm(a, axis=0)
    a = a[:, cn > 0] / cn[cn > 0]
    if a.shape[1] == 0:
        return a
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    return u[:, sv > rcond * sv[0]]


def block_projected_fraction(prob, z, free, n_points=None, rcond=1e-10):
    """``||P r|| / ||r||`` (see :func:`~freqid_casadi.solvers.termination.projected_fraction`)
    of the stacked weighted residual, by block elimination: each channel's own columns are
    projected out of its residual and of its shared columns, then the remaining shared part
    is one least-squares problem of ``n_shared`` columns (its channel blocks reduced by QR).

    Parameters
    ----------
    prob : SharedProblem
    z : ndarray of float, shape (n_vars,)
    free : ndarray of bool, shape (n_vars,)
        Variables not held at a bound (the others' columns are left out).
    n_points : int, optional
        The first ``n_points`` frequencies (default all).
    rcond : float
        Relative singular-value cutoff of the unit-column blocks.

    Returns
    -------
    float
    """
    r, A = blocks(prob, z, n_points)
    total = float(np.sum(r * r))
    if total == 0.0 or not np.any(free):
        return 0.0
    ns, c = prob.n_shared, prob.n_channels
    fs, fo = free[:ns], np.asarray(free[ns:]).reshape(c, -1)
    cs = np.sqrt(np.sum(A[:, :, :ns] ** 2, axis=(0, 1)))
    use = fs & (cs > 0)
    S = A[:, :, :ns][:, :, use] / cs[use]
    proj, rs, ts = 0.0, [], []
    for k in range(c):
        rk, sk = r[k], S[k]
        u = _unit_basis(A[k, :, ns:][:, fo[k]], rcond)
        if u.shape[1]:
            a = u.T @ rk
            proj += float(a @ a)
            rk, sk = rk - u @ a, sk - u @ (u.T @ sk)
        if sk.shape[1]:
            qk, rr = np.linalg.qr(sk)
            rs.append(rr)
            ts.append(qk.T @ rk)
    if rs:
        u, sv, _ = np.linalg.svd(np.vstack(rs), full_matrices=False)
        u = u[:, sv > rcond * max(sv[0], 1.0)]
        a = u.T @ np.concatenate(ts)
        proj += float(a @ a)
    return float(np.sqrt(min(proj / total, 1.0)))


class _Bounds:
    """What :class:`~freqid_casadi.solvers.termination.StageMonitor` asks of its problem
    outside :meth:`SharedMonitor.stationary`: the bounds and the cost."""

    constraints = None

    def __init__(self, prob, n_points):
        self.lb, self.ub = prob.bounds()
        self.n = prob.n_vars
        self._prob, self._m = prob, n_points

    def eval_cost(self, z):
        return self._prob.cost(z, self._m)


class SharedMonitor(StageMonitor):
    """The :class:`~freqid_casadi.solvers.termination.Termination` test of one shared stage
    (after every IPOPT iteration through
    :func:`~freqid_casadi.solvers.termination.iteration_callback`, and at the returned
    point).

    Parameters
    ----------
    prob : SharedProblem
    term : Termination
    n_points : int, optional
        The stage's window (first ``n_points`` frequencies; default all).
    """

    def __init__(self, prob, term, n_points=None):
        super().__init__(_Bounds(prob, n_points), term)
        self.shared, self.window = prob, n_points
        m = prob.omega.size if n_points is None else int(n_points)
        self.n_points = prob.n_channels * m
        self.evaluations = 0             # projections computed (the costly part)
        self.rescale_below = 0.0
        self.point = None                # the point last tested (after snap)

    def arm(self, cost):
        """Start of a solve: :meth:`check` stops it (reason "rescale") once the cost is
        below ``cost``."""
        self.rescale_below, self.reason, self.history = float(cost), None, []

    def check(self, x):
        """After an iteration at ``x``: True to stop (stationary, stalled, or the cost fell
        below the armed level)."""
        if super().check(x):
            return True
        if self.history and self.history[-1] < self.rescale_below:
            self.reason = "rescale"
            return True
        return False

    def stationary(self, x):
        """(stationary?, cost) at ``x`` or at ``x`` with the variables IPOPT keeps just off
        a bound moved onto it (:meth:`snap`; the point tested is :attr:`point`): the cosine
        precheck, then the block projection."""
        prob, m, term = self.shared, self.window, self.term
        x = np.clip(np.asarray(x, float), self.problem.lb, self.problem.ub)
        cost, grad, cn = gradient_and_norms(prob, x, m)
        if not (np.isfinite(cost) and np.all(np.isfinite(grad))):
            return False, cost
        x, cost, grad, cn = self.snap(x, cost, grad, cn)
        self.point = x
        norm_r = float(np.sqrt(max(cost, 0.0)))
        n_vars = prob.n_shared + prob.n_own
        noise = term.noise_factor * rounding_level(cost, self.n_points, n_vars)
        free = free_variables(grad, x, self.problem.lb, self.problem.ub, cn, norm_r,
                              hold_tol(term, noise))
        cmax, _ = relative_stationarity(grad, cn, cost, free, self.n_points, n_vars)
        self.cos, self.allowed, self.proj = cmax, np.sqrt(term.ftol) + noise, float("nan")
        if cmax > self.allowed:
            return False, cost
        self.evaluations += 1
        self.proj = block_projected_fraction(prob, x, free, m, term.rcond)
        self.proj_allowed = float(np.sqrt(term.ftol + noise))
        return self.proj <= self.proj_allowed, cost

    def snap(self, x, cost, grad, cn):
        """``(x, cost, grad, cn)`` with the variables within ``SNAP * ||r|| / ||J_j||`` of
        a bound whose gradient points out of the box moved onto it, if that does not raise
        the cost; else the arguments unchanged. IPOPT's interior keeps such a variable
        ``~ mu / gradient`` off its bound (measured: a numerator coefficient 6.8e-10 off 0,
        its cosine 2e-3, so the test failed at a point IPOPT called converged); the
        single-channel polish's :meth:`StageMonitor._onto_bounds` makes the same move
        (:func:`~freqid_casadi.solvers.termination.moved_onto_bounds`)."""
        xs = moved_onto_bounds(x, grad, cn, self.problem.lb, self.problem.ub,
                               SNAP * np.sqrt(max(cost, 0.0)))
        if xs is None:
            return x, cost, grad, cn
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # (a numerator moved onto its bound can vanish at a data point: the trial's
            # cost is then not finite, and it is not taken)
            c2, g2, n2 = gradient_and_norms(self.shared, xs, self.window)
        if np.isfinite(c2) and c2 <= cost and np.all(np.isfinite(g2)):
            return xs, c2, g2, n2
        return x, cost, grad, cn


def verdict(monitor, x, status):
    """``success``, ``stationary`` and ``message`` of a stage solve that returned ``x``.

    Parameters
    ----------
    monitor : SharedMonitor or None
        The stage's test (None: IPOPT's status alone decides).
    x : ndarray of float, shape (n_vars,)
    status : str
        IPOPT's return_status.

    Returns
    -------
    dict
        ``success`` (IPOPT converged or ``x`` is relatively stationary), ``stationary``,
        ``message``, ``x`` (the point tested: ``x`` or :meth:`SharedMonitor.snap`'s).
    """
    ipopt_ok = ipopt_status(status) in SUCCESS_STATUSES
    ok = monitor is not None and ipopt_status(status) != Status.ERROR and \
        monitor.stationary(x)[0]
    x = monitor.point if ok else x
    test = f"{monitor.test_text(explain=not (ok or ipopt_ok))}; " if monitor is not None else ""
    if ok or ipopt_ok:
        how = "relative stationarity" if ok else "IPOPT's tolerance"
        msg = f"converged ({how}: {test}{status})"
    else:
        msg = f"not converged: not stationary ({test}{status})"
    return {"success": bool(ok or ipopt_ok), "stationary": bool(ok), "message": msg, "x": x}
