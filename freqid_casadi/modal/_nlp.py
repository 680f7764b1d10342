"""One stage NLP of the shared-pole fit: variables, exact sparse derivatives, IPOPT (layer L3).

Channel ``c`` is modelled as
``G_c(s) = exp(-h_c s) K_c [1/s] prod_k N_ck(s) / D_k(s) prod_j N'_cj(s) / D'_cj(s)``
with the denominators ``D_k`` common to all channels and ``k_l`` channel sections
``N'_cj / D'_cj`` (poles and zeros) of each channel's own. In the package's "dc" gauge
(:mod:`freqid_casadi.core.objective`) every factor is ``1 + c1 (s/wr) + c2 (s/wr)^2``, i.e.
``1 - c2 x^2 + j c1 x`` at ``s = j w``, ``x = w/wr``; ``c >= 0`` is exactly "roots in the
closed left half plane". The relative residual of channel ``c`` at ``w_i`` is::

    r_ci = Q_ci - 1,   Q_ci = Phi_ci exp(j w_i h_c) [j w_i] (v_c / g_c) prod D / prod N

with ``v_c = g_c / K_c`` (``g_c`` a reference gain): ``Q`` is linear in ``v``, so a gain of
either sign (``zeros="free"``) is a smooth variable that can cross zero.

Variables ``z = [shared | own_1 | ... | own_C]``: shared = ``(q2, q1)`` of every section
(+ the delay with ``delay="shared"``), own_c = ``v_c`` (+ ``h_c``) + ``(p2, p1)`` of every
numerator section + the channel sections' numerators and denominators
(:meth:`SharedProblem.layout`). The cost ``sum_c sum_i w_ci |r_ci|^2`` couples the
channels only through the shared block, so its Hessian is block-arrowhead;
:class:`SharedProblem` evaluates its exact gradient and Hessian with numpy
(``dQ = Q d log Q``; each factor is affine in its two variables);
:mod:`freqid_casadi.solvers.shared_stage` hands IPOPT only the arrowhead's upper triangle, so the
work per iteration is linear in the number of channels.
"""

import numpy as np

from .. import _cplx

__all__ = ["SharedProblem"]


class SharedProblem:
    """Variables, bounds and exact derivatives of one stage (see the module docstring).

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s.
    phi : ndarray of complex, shape (C, M)
    weights : ndarray of float, shape (C, M)
    g : ndarray of float, shape (C,)
        Reference gains (K_c = g_c / v_c).
    wr : sequence of float, length N
        Reference frequency (rad/s) of each shared section.
    integrator : bool
    delay : {"per-channel", "shared", False}
    free : ndarray of bool, shape (C,)
        Channels whose gain and numerator coefficients are unbounded.
    delay_max : float
        s; h = delay_max * z_h with 0 <= z_h <= 1.
    wl : array_like of float, shape (C, k), optional
        Reference frequency (rad/s) of each channel's own (local) sections; default none
        (k = 0).
    """

    def __init__(self, omega, phi, weights, g, wr, integrator, delay, free, delay_max,
                 wl=None):
        self.omega, self.phi, self.weights, self.g = omega, phi, weights, g
        self.wr = np.asarray(wr, float)
        self.integrator, self.delay, self.free = integrator, delay, np.asarray(free, bool)
        self.delay_max = float(delay_max)
        n, c = self.wr.size, phi.shape[0]
        self.wl = np.zeros((c, 0)) if wl is None else np.asarray(wl, float).reshape(c, -1)
        k = self.wl.shape[1]
        self.n_sections, self.n_channels, self.n_local = n, c, k
        self.n_shared = 2 * n + (delay == "shared")
        self._op = 1 + (delay == "per-channel")          # own block: v, (h), p, lp, lq
        self._olp = self._op + 2 * n
        self._olq = self._olp + 2 * k
        self.n_own = self._olq + 2 * k
        self.n_vars = self.n_shared + c * self.n_own
        self._cache = (None, None)
        self._jcache = None
        self._sparsity = None

    # ------------------------------------------------------------------ layout
    def layout(self):
        """Indices into ``z`` of every block (dict of int arrays): ``q`` (N, 2), ``hs`` (0 or
        1,) the shared delay, ``v`` (C,), ``h`` (C,) or (0,), ``p`` (C, N, 2), ``lp`` and
        ``lq`` (C, k, 2) the local sections' numerators and denominators."""
        n, k, c, ns, no = self.n_sections, self.n_local, self.n_channels, self.n_shared, \
            self.n_own
        own = ns + no * np.arange(c)[:, None]                               # (C, 1)
        return {"q": np.arange(2 * n).reshape(n, 2),
                "hs": np.arange(2 * n, ns),
                "v": own[:, 0],
                "h": (own + 1)[:, 0] if self.delay == "per-channel" else np.zeros(0, int),
                "p": (own + self._op + np.arange(2 * n)).reshape(c, n, 2),
                "lp": (own + self._olp + np.arange(2 * k)).reshape(c, k, 2),
                "lq": (own + self._olq + np.arange(2 * k)).reshape(c, k, 2)}

    def bounds(self):
        """(lb, ub), shape (n_vars,): denominators and delays >= 0 (delay <= delay_max);
        gains and numerators >= 0 for minimum-phase channels, free otherwise."""
        lb, ub = np.zeros(self.n_vars), np.full(self.n_vars, np.inf)
        idx = self.layout()
        ub[idx["hs"]] = 1.0
        ub[idx["h"]] = 1.0
        for c in np.flatnonzero(self.free):
            lb[idx["v"][c]] = -np.inf
            lb[idx["p"][c]] = -np.inf
            lb[idx["lp"][c]] = -np.inf
        return lb, ub

    def split(self, z):
        """(q (N, 2), v (C,), h (C,) in s, p (C, N, 2)) of the variables ``z``."""
        z = np.asarray(z, float)
        idx = self.layout()
        if self.delay == "shared":
            h = np.full(self.n_channels, z[idx["hs"][0]])
        elif self.delay == "per-channel":
            h = z[idx["h"]]
        else:
            h = np.zeros(self.n_channels)
        return z[idx["q"]], z[idx["v"]], h * self.delay_max, z[idx["p"]]

    def split_local(self, z):
        """(lp, lq), each (C, k, 2): the local sections' numerator and denominator
        variables."""
        z = np.asarray(z, float)
        idx = self.layout()
        return z[idx["lp"]], z[idx["lq"]]

    def join(self, q, v, h, p, lp=None, lq=None):
        """Inverse of :meth:`split` and :meth:`split_local` (h in s; local sections default
        to factors 1)."""
        z = np.zeros(self.n_vars)
        idx = self.layout()
        z[idx["q"]] = np.reshape(q, (-1, 2))
        z[idx["hs"]] = float(np.mean(h)) / self.delay_max
        z[idx["v"]] = v
        z[idx["h"]] = np.asarray(h, float) / self.delay_max if idx["h"].size else 0.0
        z[idx["p"]] = np.reshape(p, idx["p"].shape)
        if lp is not None:
            z[idx["lp"]] = np.reshape(lp, idx["lp"].shape)
        if lq is not None:
            z[idx["lq"]] = np.reshape(lq, idx["lq"].shape)
        return z

    # ------------------------------------------------------------------ evaluation
    def ratio(self, z, n_points=None):
        """``Q = Phi / G`` per channel, complex (C, L), on the first ``n_points``."""
        return self._pieces(z, n_points)[0]

    def _pieces(self, z, n_points):
        m = self.omega.size if n_points is None else int(n_points)
        q, v, h, p = self.split(z)
        lp, lq = self.split_local(z)
        w = self.omega[:m]
        x = w[None, :] / self.wr[:, None]                                   # (N, L)
        x2 = x * x
        den = 1.0 - q[:, 0:1] * x2 + 1j * q[:, 1:2] * x                     # (N, L)
        num = 1.0 - p[:, :, 0:1] * x2[None] + 1j * p[:, :, 1:2] * x[None]   # (C, N, L)
        xl = w[None, None, :] / self.wl[:, :, None]                         # (C, k, L)
        xl2 = xl * xl
        lnum = 1.0 - lp[:, :, 0:1] * xl2 + 1j * lp[:, :, 1:2] * xl         # (C, k, L)
        lden = 1.0 - lq[:, :, 0:1] * xl2 + 1j * lq[:, :, 1:2] * xl
        base = self.phi[:, :m] * np.exp(1j * w[None, :] * h[:, None]) / self.g[:, None]
        if self.integrator:
            base = base * (1j * w)[None, :]
        P = base * np.prod(den, axis=0)[None, :] / np.prod(num, axis=1) * \
            np.prod(lden, axis=1) / np.prod(lnum, axis=1)
        return v[:, None] * P, P, v, (x, x2, den, num, xl, xl2, lnum, lden), w

    def cost(self, z, n_points=None):
        """``sum_c sum_i w_ci |Q_ci - 1|^2`` on the first ``n_points``."""
        m = self.omega.size if n_points is None else int(n_points)
        r = self.ratio(z, m) - 1.0
        return float(np.sum(self.weights[:, :m] * (r.real ** 2 + r.imag ** 2)))

    def _local(self, z, m):
        """Per-channel log-derivative columns E (C, L, nl), column v set to 1, and pieces."""
        key = (np.asarray(z, float).tobytes(), m)
        if self._cache[0] == key:
            return self._cache[1]
        Q, P, v, (x, x2, den, num, xl, xl2, lnum, lden), w = self._pieces(z, m)
        n, c, k = self.n_sections, self.n_channels, self.n_local
        cols = [np.broadcast_to(np.stack([-x2 / den, 1j * x / den], axis=1)
                                .reshape(2 * n, m), (c, 2 * n, m))]
        jw = np.broadcast_to((1j * self.delay_max) * w, (c, 1, m))
        if self.delay == "shared":
            cols.append(jw)
        cols.append(np.ones((c, 1, m), complex))                          # v (see _jac)
        if self.delay == "per-channel":
            cols.append(jw)
        cols.append(np.stack([x2[None] / num, -1j * x[None] / num], axis=2).reshape(c, 2 * n, m))
        cols.append(np.stack([xl2 / lnum, -1j * xl / lnum], axis=2).reshape(c, 2 * k, m))
        cols.append(np.stack([-xl2 / lden, 1j * xl / lden], axis=2).reshape(c, 2 * k, m))
        E = np.concatenate(cols, axis=1).transpose(0, 2, 1)               # (C, L, nl)
        self._cache = (key, (E, Q, P, v))
        self._jcache = None                  # J of this point, made once (see _jac)
        return self._cache[1]

    @property
    def _iv(self):
        return self.n_shared                     # local index of v

    def gradient(self, z, n_points=None):
        """(cost, gradient (n_vars,)) on the first ``n_points``."""
        m = self.omega.size if n_points is None else int(n_points)
        E, Q, P, v = self._local(z, m)
        wt = self.weights[:, :m]
        r = Q - 1.0
        J = self._jac(E, Q, P)
        g = 2.0 * np.real(np.einsum("cl,cla->ca", wt * np.conj(r), J))
        cost = float(np.sum(wt * (r.real ** 2 + r.imag ** 2)))
        ns = self.n_shared
        return cost, np.concatenate([g[:, :ns].sum(axis=0), g[:, ns:].ravel()])

    def _jac(self, E, Q, P):
        """``dQ/dz`` per channel (C, L, nl), cached with the point's E (the gradient and the
        Hessian at one point both need it; at 9 channels x 48 000 points one product
        costs a fifth of an evaluation)."""
        if getattr(self, "_jcache", None) is not None and self._jcache[0] is E:
            return self._jcache[1]
        J = Q[:, :, None] * E
        J[:, :, self._iv] = P
        self._jcache = (E, J)
        return J

    def hessian_parts(self, z, n_points=None):
        """The exact Hessian of the cost in three parts: ``ss`` (ns, ns) the shared block
        (summed over channels), ``so`` (C, ns, no) each channel's coupling to the shared
        variables and ``oo`` (C, no, no) its own block; no channel-channel block exists.

        The shared columns of the log-derivatives are the same for every channel, so the
        shared block is one product with channel-summed weights; each channel costs two
        products of its own columns.
        """
        m = self.omega.size if n_points is None else int(n_points)
        E, Q, P, v = self._local(z, m)
        wt = self.weights[:, :m]
        ns = self.n_shared
        mask = self._second_order_mask(v)
        J = self._jac(E, Q, P)
        u = wt * np.conj(Q - 1.0) * P
        es = E[0, :, :ns]                               # identical for every channel
        ss = ((es.conj().T * np.sum(wt * np.abs(Q) ** 2, axis=0)) @ es).real + \
            ((es.T * np.sum(v[:, None] * u, axis=0)) @ es).real * self._base_mask()[:ns, :ns]
        c, no = self.n_channels, self.n_own
        so, oo = np.empty((c, ns, no)), np.empty((c, no, no))
        for k in range(c):                              # per channel: BLAS products
            jo, eo = J[k, :, ns:], E[k, :, ns:]
            so[k] = ((es.conj().T * (wt[k] * np.conj(Q[k]))) @ jo).real + \
                ((es.T * u[k]) @ eo).real * mask[k, :ns, ns:]
            oo[k] = ((jo.conj().T * wt[k]) @ jo).real + \
                ((eo.T * u[k]) @ eo).real * mask[k, ns:, ns:]
        return 2.0 * ss, 2.0 * so, 2.0 * oo

    def _base_mask(self):
        """``1 + s_ab`` (see :meth:`_second_order_mask`), shape (nl, nl) in the local order
        (shared, then one channel's own variables)."""
        nl, ns = self.n_shared + self.n_own, self.n_shared
        base = np.ones((nl, nl))
        starts = [(2 * k, 0.0) for k in range(self.n_sections)]                  # D_k
        starts += [(ns + self._op + 2 * k, 2.0) for k in range(self.n_sections)]  # N_ck
        starts += [(ns + self._olp + 2 * k, 2.0) for k in range(self.n_local)]   # local N
        starts += [(ns + self._olq + 2 * k, 0.0) for k in range(self.n_local)]   # local D
        for o, val in starts:
            base[o:o + 2, o:o + 2] = val
        return base

    def _second_order_mask(self, v):
        """d2 Q_ab = Q E_a E_b (1 + s_ab) with s = -1 inside a denominator factor, +1 inside a
        numerator factor (each affine: d2 log F = -dF dF / F^2), 0 else; the v row/column
        (Q = v P) is P E_b, and d2 Q / dv2 = 0."""
        iv = self._iv
        base = self._base_mask()
        mask = v[:, None, None] * base[None]
        mask[:, iv, :] = 1.0
        mask[:, :, iv] = 1.0
        mask[:, iv, iv] = 0.0
        return mask

    def casadi_cost(self, z, n_points=None):
        """The cost as a CasADi expression of the symbol ``z`` (SX or MX, (n_vars, 1)),
        the same formula on (re, im) pairs; its AD Hessian has the block-arrowhead pattern
        of :meth:`hessian_pattern` (checked by the tests)."""
        import casadi as ca

        m = self.omega.size if n_points is None else int(n_points)
        w = self.omega[:m]
        idx = self.layout()
        cost = 0
        for c in range(self.n_channels):
            hz = (z[int(idx["hs"][0])] if self.delay == "shared" else z[int(idx["h"][c])]
                  if self.delay == "per-channel" else 0.0)
            ph = self.phi[c, :m] / self.g[c] * ((1j * w) if self.integrator else 1.0)
            v = z[int(idx["v"][c])]
            q = _cplx.mul((ph.real * v, ph.imag * v),
                          _cplx.expj(w * self.delay_max * hz, ca.cos, ca.sin))
            pairs = [(self.wr[k], idx["q"][k], idx["p"][c, k])
                     for k in range(self.n_sections)]
            pairs += [(self.wl[c, k], idx["lq"][c, k], idx["lp"][c, k])
                      for k in range(self.n_local)]
            for wr, iq, ip in pairs:
                x = w / wr
                den = (1 - z[int(iq[0])] * x * x, z[int(iq[1])] * x)
                num = (1 - z[int(ip[0])] * x * x, z[int(ip[1])] * x)
                q = _cplx.mul(q, _cplx.div(den, num))
            cost = cost + ca.sum1(ca.DM(self.weights[c, :m]) * ((q[0] - 1) ** 2 + q[1] ** 2))
        return cost

    # ------------------------------------------------------------------ sparse Hessian
    def hessian_pattern(self):
        """(rows, cols, order): upper triangle of the block-arrowhead Hessian in the order
        :meth:`hessian_values` returns its values, and the permutation to CasADi's
        column-major order."""
        if self._sparsity is None:
            ns, no, c = self.n_shared, self.n_own, self.n_channels
            rs, cs = np.triu_indices(ns)
            ro, co = np.triu_indices(no)
            rows, cols = [rs], [cs]
            for k in range(c):
                o = ns + k * no
                a, b = np.meshgrid(np.arange(ns), o + np.arange(no), indexing="ij")
                rows += [a.ravel(), o + ro]
                cols += [b.ravel(), o + co]
            rows, cols = np.concatenate(rows), np.concatenate(cols)
            self._sparsity = (rows, cols, np.lexsort((rows, cols)))
        return self._sparsity

    def hessian_values(self, z, n_points=None):
        """Nonzeros of the upper triangle of the Hessian, in :meth:`hessian_pattern` order."""
        ss, so, oo = self.hessian_parts(z, n_points)
        rs, cs = np.triu_indices(self.n_shared)
        ro, co = np.triu_indices(self.n_own)
        return np.concatenate([ss[rs, cs], np.concatenate(
            [so.reshape(so.shape[0], -1), oo[:, ro, co]], axis=1).ravel()])

    def hessian_dense(self, z, n_points=None):
        """The full symmetric Hessian, shape (n_vars, n_vars) (for tests)."""
        rows, cols, _ = self.hessian_pattern()
        h = np.zeros((self.n_vars, self.n_vars))
        h[rows, cols] = self.hessian_values(z, n_points)
        return h + np.triu(h, 1).T

