"""Exact stage derivatives from the model's product structure (layer L2).

:class:`StageFunctions` gives a stage's residual, cost, Jacobian, gradient and exact Hessian
(numpy over points x sections in the dc gauge, or CasADi's AD of the per-point formula
mapped over the points), and :class:`PNormFunctions` those of the minimax polish's p-norm
objective; :func:`stage_functions` builds one. The formula of a section is the gauge's
(:mod:`freqid_casadi.core.gauges`); the parametrization is
:class:`~freqid_casadi.core.objective.Parametrization`.
"""

import dataclasses
import functools
import threading

import numpy as np

from .. import _cplx
from ..errors import OptionError, StructureError
from .gauges import gauge_for
from .model import times_jw_power

__all__ = ["StageFunctions", "PNormFunctions", "stage_functions"]

#: Points per block of the per-iteration products over the points (the Hessian, the column
#: norms, the Jacobian): their O(n x block) scratch stays in cache and the stage keeps no
#: O(n x M) scratch (at 200 000 points and 14 variables it was 135 MB). A stage of at most
#: this many points is one block: the same operations as a whole-array product, bit for bit.
_BLOCK_POINTS = 8192


#: Stages above this many points take their residual and IPOPT's objective from the
#: derivative pieces (:meth:`StageFunctions._eval`, one pass over the points shared with
#: the gradient and Hessian at the same point) instead of evaluating the MX residual too:
#: at 200 000 points each was 12-20 ms per call beside the pieces' 17 ms. The two agree to
#: rounding; at most this many points the MX values are kept, bit for bit.
_PIECES_COST_POINTS = 8192


def _blocks(m):
    """Slices of ``range(m)`` of at most :data:`_BLOCK_POINTS` points, in order (a tuple,
    kept: the Hessian and the column norms ask for it several times per iteration)."""
    return _block_slices(m, _BLOCK_POINTS)


@functools.lru_cache(maxsize=64)
def _block_slices(m, size):
    return tuple(slice(i, min(i + size, m)) for i in range(0, m, size))


def _point_functions(param):
    """Per-point SX Function of one stage (inputs z, omega, phi_re, phi_im, sqrt_w).

    ``derivative_point`` -> r (2,), sq (2,), Ld (2, n), Ln (2, n), T2 (2, N ns^2):
    the pieces of the exact derivatives, using the product structure of the model. With
    ``q = Phi e^{j w h} [j w] / K prod_k den_k/num_k`` and ``r = sqrt_w (q - 1)``:

    - ``dr/dv = sqrt_w q dlog(q)/dv`` with ``dlog q = Ld - Ln``, where ``Ld`` holds the
      log-derivatives of the delay factor, the gain and each ``den_k`` and ``Ln`` those of
      each ``num_k`` (``(d num/dv)/num``, from CasADi's AD of the section formula);
    - ``d2 log q`` is ``Ln Ln^T - Ld Ld^T`` within each section's block, plus
      ``(d2 den/den - d2 num/num)`` (``T2``; structurally zero in the dc gauge), plus
      ``1/z_K^2`` for the gain.

    Each formula is still written once (:meth:`~freqid_casadi.core.gauges.Gauge.pairs`);
    assembling ``J`` and the
    Hessian from these pieces costs O(n) per point plus dense products done by BLAS
    (:class:`StageFunctions`), instead of AD through the whole product chain.
    """
    import casadi as ca

    n = param.n_vars
    z = ca.SX.sym("z", n)
    w = ca.SX.sym("omega")
    phi = (ca.SX.sym("phi_re"), ca.SX.sym("phi_im"))
    sw = ca.SX.sym("sqrt_w")
    inputs = [z, w, phi[0], phi[1], sw]
    names = ["z", "omega", "phi_re", "phi_im", "sqrt_w"]

    h_ref, k_ref, wr = param._refs()
    q = _cplx.mul(phi, (ca.cos(w * h_ref * z[0]), ca.sin(w * h_ref * z[0])))
    k = param.structure.origin_order
    if k == 1:
        q = _cplx.mul(q, (0, w))
    elif k:                                      # times (j w)^k: k poles at 0 removed
        for _ in range(abs(k)):
            q = (_cplx.mul if k > 0 else _cplx.div)(q, (0, w))
    q = (q[0] / (k_ref * z[1]), q[1] / (k_ref * z[1]))
    ld = [(0, w * h_ref), (-1 / z[1], 0)]
    ln = [(0, 0), (0, 0)]
    t2 = []
    ns = param.section_size
    for k in range(param.structure.n_sections):
        v = [z[2 + ns * k + i] for i in range(ns)]
        num, den = param.gauge_obj.pairs(v, w / wr[k], param.chart(k))
        inum, iden = _cplx.inv(num), _cplx.inv(den)
        q = _cplx.mul(q, _cplx.mul(den, inum))
        vv = ca.vertcat(*v)
        d_num = (ca.jacobian(num[0], vv), ca.jacobian(num[1], vv))
        d_den = (ca.jacobian(den[0], vv), ca.jacobian(den[1], vv))
        for i in range(ns):
            ld.append(_cplx.mul((d_den[0][i], d_den[1][i]), iden))
            ln.append(_cplx.mul((d_num[0][i], d_num[1][i]), inum))
        h_num = (ca.hessian(num[0], vv)[0], ca.hessian(num[1], vv)[0])
        h_den = (ca.hessian(den[0], vv)[0], ca.hessian(den[1], vv)[0])
        for a in range(ns):
            for b in range(ns):
                x1 = _cplx.mul((h_den[0][a, b], h_den[1][a, b]), iden)
                x2 = _cplx.mul((h_num[0][a, b], h_num[1][a, b]), inum)
                t2.append((x1[0] - x2[0], x1[1] - x2[1]))
    sq = (q[0] * sw, q[1] * sw)
    row = lambda pairs, part: ca.horzcat(*[p[part] for p in pairs])  # noqa: E731
    outs = [ca.vertcat(sq[0] - sw, sq[1]), ca.vertcat(*sq),
            ca.vertcat(row(ld, 0), row(ld, 1)), ca.vertcat(row(ln, 0), row(ln, 1)),
            ca.vertcat(row(t2, 0), row(t2, 1)) if t2 else ca.SX(2, 0)]
    return ca.Function("derivative_point", inputs, outs, names,
                       ["r", "sq", "Ld", "Ln", "T2"])



def _origin_removed(x, omega, k):
    """``x * (j omega)^k``: the integrator's ``x * (1j * omega)`` for k = 1 (its rounding),
    ``x * 1.0`` for k = 0."""
    return x * (1j * omega if k else 1.0) if k in (0, 1) else times_jw_power(x, omega, k)


#: Inlining a kept template reads its nodes: one thread at a time.
_INLINE_LOCK = threading.Lock()


def residual_template(param, n_points):
    """The weighted residual as one CasADi MX Function of ``(z (n,), refs (2 + N,),
    omega (1, M), Re phi (1, M), Im phi (1, M), sqrt_w (1, M)) -> r (2M,)``, ``refs`` the
    parametrization's ``(h_ref, k_ref, wr_1 .. wr_N)``; one per structure, gauge, charts
    and number of points, kept for the process (the 256 last used).

    Building a stage's MX residual from the formula took 2-4 ms (3-8 % of a default fit's
    CPU on the measured sets, measured); a stage now inlines the kept formula with its data
    and references, in about 0.2 ms. The operations are the same, in the same order, so
    the values are the same to the last bit.

    Parameters
    ----------
    param : Parametrization
    n_points : int

    Returns
    -------
    casadi.Function
    """
    # the formula does not depend on the references (inputs) or the bounds: one key
    canonical = dataclasses.replace(param, omega_ref=(1.0,) * param.structure.n_sections,
                                    gain_ref=1.0, delay_max=1.0, scaled=True, root_floor=0.0)
    return _residual_template(canonical, int(n_points))


@functools.lru_cache(maxsize=256)
def _residual_template(param, n_points):
    import casadi as ca

    n_sec = param.structure.n_sections
    z, refs = ca.MX.sym("z", param.n_vars), ca.MX.sym("refs", 2 + n_sec)
    omega, re, im, sw = (ca.MX.sym(name, 1, n_points) for name in ("omega", "re", "im",
                                                                   "sqrt_w"))
    rr, ri = param.residual_pair(z, omega, (re, im), sw,
                                 refs=(refs[0], refs[1], [refs[2 + k] for k in range(n_sec)]))
    return ca.Function("residual_template", [z, refs, omega, re, im, sw],
                       [ca.vertcat(ca.transpose(rr), ca.transpose(ri))])


class StageFunctions:
    """Residual, Jacobian and Hessian of one stage's objective, built once per stage.

    ``cost(z) = ||r(z)||^2`` with ``r`` the stacked weighted residual ``[Re; Im]`` (2M,).

    Two evaluation paths, both exact and built from the one formula of
    :meth:`Parametrization.residual_pair` / :meth:`~freqid_casadi.core.gauges.Gauge.pairs`:

    - ``r_fun`` — the residual as a CasADi MX expression *vectorised over the points*
      (each operation is one C loop over M values), which is the NLP's objective;
    - the derivative pieces ``q``, ``L = dlog q/dz`` (and per-section ``dlog num``,
      ``dlog den``), from which ``J``, the gradient and the exact Hessian are assembled with
      dense BLAS products (:meth:`gradient`, :meth:`hessian`). In the "dc" gauge every
      section factor is *affine* in its variables, so its derivative along variable ``i``
      is the formula evaluated at the unit vector ``e_i`` minus its value at 0 — exact,
      computed once per stage, and the pieces are evaluated by numpy over
      (sections x points) arrays. The "b1"/"raw" gauges (polynomial in the variables) use
      CasADi's AD of the per-point section formula, mapped over the points
      (:func:`_point_functions`).

    The products over the points (Hessian, column norms; the Jacobian above 8192 points)
    run over blocks of :data:`_BLOCK_POINTS` points with O(n x block) scratch, and above
    :data:`_PIECES_COST_POINTS` points the residual and IPOPT's objective come from the
    derivative pieces too: a stage holds the pieces (O(n M)) and no O(n M) scratch.

    Parameters
    ----------
    param : Parametrization
    omega : ndarray of float, shape (M,)
        The stage's frequencies, rad/s.
    response : ndarray of complex, shape (M,)
        The data ``Phi`` at ``omega``.
    weights : ndarray of float, shape (M,), optional
        Weights of the squared relative residuals.
    derivatives : {None, "affine", "casadi-map"}
        None picks "affine" for the dc gauge, else "casadi-map".

    Attributes
    ----------
    param : Parametrization
    n_points : int
    r_fun : casadi.Function
        ``z (n,) -> r (2M,)``, symbolic (the NLP's objective is ``sumsqr(r_fun(z))``).
    derivatives : {"affine", "casadi-map"}
        Which derivative path is used (see above).
    """

    def __init__(self, param, omega, response, weights=None, derivatives=None):
        import casadi as ca

        self.param = param
        omega = np.asarray(omega, float)
        resp = np.asarray(response, complex)
        m = omega.size
        n = param.n_vars
        self.n_points = m
        self._sw = np.ones(m) if weights is None else np.sqrt(np.asarray(weights, float))
        self._omega, self._resp, self._r_fun = omega, resp, None   # r_fun: built when asked
        self.derivatives = derivatives = _derivative_path(derivatives, param.gauge)
        self._key = None
        self._work = {}              # scratch arrays of the Hessian and column norms, by shape
        self._cost_buf = None        # (Function, buffer, trigger, z, out) of nlp_cost
        nsec, ns = param.structure.n_sections, param.section_size
        h_ref, k_ref, wr = param._refs()
        self._q0 = _origin_removed(self._sw * resp, omega, param.structure.origin_order)
        self._dlog_delay = 1j * omega * h_ref
        if derivatives == "affine":
            x = omega[None, :] / np.asarray(wr, float).reshape(-1, 1)         # (nsec, M)
            dc = gauge_for("dc", param.structure.basis)
            chart = (0, 0)
            if any(map(any, param.charts)):
                chart = tuple(np.array([c[j] for c in param.charts]).reshape(-1, 1)
                              for j in (0, 1))

            def pair(v):
                num, den = dc.pairs(v, x, chart)
                return (_cplx.to_complex(np.broadcast_arrays(*num)),
                        _cplx.to_complex(np.broadcast_arrays(*den)))

            zero = [np.zeros((nsec, 1))] * ns
            n0, d0 = pair(zero)
            # an affine factor is f(v) = f(0) + sum_i v_i (f(e_i) - f(0)) exactly; one
            # step at a time, keeping only the nonzero difference (O(ns nsec M) memory)
            dnum, dden = {}, {}
            for i in range(ns):
                num_i, den_i = pair([np.ones((nsec, 1)) if j == i else zero[j]
                                     for j in range(ns)])
                for d, f_i, f_0 in ((dnum, num_i, n0), (dden, den_i, d0)):
                    diff = f_i - f_0
                    if np.any(diff != 0):
                        d[i] = diff
                del num_i, den_i
            self._idx_num, self._idx_den = sorted(dnum), sorted(dden)
            if nsec and sorted(self._idx_num + self._idx_den) != list(range(ns)):
                raise StructureError("internal: each dc-gauge variable must enter exactly "
                                     "one of a section's numerator and denominator")
            self._n0, self._d0 = n0, d0
            if nsec:
                # (nsec, k, M), the numerator's negated: dlog q = dlog den - dlog num
                self._neg_dnum_t = -np.stack([dnum.pop(i) for i in self._idx_num], axis=1)
                self._dden_t = np.stack([dden.pop(i) for i in self._idx_den], axis=1)
            self._sl_num, self._sl_den = _as_slice(self._idx_num), _as_slice(self._idx_den)
            # the (k, k) index grids of the Hessian's blocks, made once per stage
            self._ix_num, self._ix_den = _block_index(self._idx_num), \
                _block_index(self._idx_den)
            self._lg = np.empty((n, m), complex)
        else:
            d_point = _point_functions(param)
            z = ca.MX.sym("z", n)
            data = [omega.reshape(1, -1), resp.real.reshape(1, -1), resp.imag.reshape(1, -1),
                    self._sw.reshape(1, -1)]
            zz = ca.repmat(z, 1, m)
            outs = d_point.map(m, "serial")(zz, *data)
            self.d_fun = ca.Function("derivatives", [z], [ca.densify(o) for o in outs],
                                     ["z"], ["r", "sq", "Ld", "Ln", "T2"])
            self.n_t2 = int(d_point.size2_out(4))
            self._ix_full = _block_index(range(ns))
            # zero-copy evaluation: CasADi writes straight into these numpy buffers
            self._zbuf = np.zeros(n)
            self._outs = [np.zeros(2 * c) for c in (m, m, n * m, n * m, self.n_t2 * m)]
            self._buf, self._trigger = self.d_fun.buffer()
            self._buf.set_arg(0, memoryview(self._zbuf))
            for i, out in enumerate(self._outs):
                self._buf.set_res(i, memoryview(out))

    @property
    def r_fun(self):
        """The residual as one CasADi MX expression over all points (vectorised C loops),
        ``z (n,) -> r (2M,)``, built at its first use: above
        :data:`_PIECES_COST_POINTS` points a stage's cost comes from the derivative pieces
        and IPOPT's objective from a callback, so the default fit never builds it there
        (at 200 000 points it took 0.3-0.5 s and ~35 MiB per stage)."""
        if self._r_fun is None:
            import casadi as ca

            param = self.param
            h_ref, k_ref, wr = param._refs()
            z = ca.MX.sym("z", param.n_vars)
            row = lambda a: ca.DM(np.asarray(a, float).reshape(1, -1))  # noqa: E731
            # inlined: the stage's graph is the template's (no call node, whose evaluation
            # took 1.5 us more per call at 500 points), built in 0.2 ms instead of 4
            args = [z, ca.DM([h_ref, k_ref, *wr]), row(self._omega), row(self._resp.real),
                    row(self._resp.imag), row(self._sw)]
            template = residual_template(param, self.n_points)
            with _INLINE_LOCK:
                r = template.call(args, True, False)
            self._r_fun = ca.Function("residual", [z], r, ["z"], ["r"])
        return self._r_fun

    # ------------------------------------------------------------------ evaluation
    def residual(self, z):
        """Stacked residual ``[Re r; Im r]``, ndarray (2M,) (from the derivative pieces
        above :data:`_PIECES_COST_POINTS` points, else the MX residual ``r_fun``)."""
        if self.n_points > _PIECES_COST_POINTS:
            self._eval(z)
            return np.concatenate([self._r.real, self._r.imag])
        return self.r_fun(np.asarray(z, float)).full().reshape(-1)

    def cost(self, z):
        r = self.residual(z)
        return float(r @ r)

    def nlp_cost(self, z):
        """IPOPT's objective ``sumsqr(r_fun(z))`` evaluated by CasADi into a buffer made
        once per stage: the same expression, and bit for bit the same value, as an MX
        objective in the NLP (whose ``nlpsol`` construction took 0.24 s CPU per stage at
        200 000 points; a callback of this, 2 ms). Above :data:`_PIECES_COST_POINTS`
        points: ``||r||^2`` from the derivative pieces (as :meth:`gradient` gives it).

        Parameters
        ----------
        z : ndarray of float, shape (n,)

        Returns
        -------
        float
        """
        if self.n_points > _PIECES_COST_POINTS:
            self._eval(z)
            return float(np.vdot(self._r, self._r).real)
        if self._cost_buf is None:
            import casadi as ca

            zs = ca.MX.sym("z", self.param.n_vars)
            fun = ca.Function("nlp_cost", [zs], [ca.sumsqr(self.r_fun(zs))])
            zbuf, out = np.zeros(self.param.n_vars), np.zeros(1)
            buf, trigger = fun.buffer()
            buf.set_arg(0, memoryview(zbuf))
            buf.set_res(0, memoryview(out))
            self._cost_buf = (fun, buf, trigger, zbuf, out)
        _, _, trigger, zbuf, out = self._cost_buf
        zbuf[:] = z
        trigger()
        return float(out[0])

    def _eval(self, z):
        """Derivative pieces at ``z`` (cached on the bytes of ``z``):

        ``_r`` (M,) complex residual, ``_sq`` (M,) = sqrt_w q, ``_L`` (n, M) = dlog q/dz,
        ``_blk``: per-section ``(index, dlog factor/dv (nsec, k, M), sign)`` (the
        index (:func:`_block_index`) of the k variables the factor depends on, in a
        (nsec, ns, ns) array)
        (the numerator's entries may be negated: only their products are used)
        for the numerators (+1) and denominators (-1), and
        ``_t2`` (M, nsec ns^2) second-derivative terms or None.
        """
        z = np.asarray(z, float).reshape(-1)
        key = z.tobytes()
        if key == self._key:
            return self
        if self.derivatives == "affine":
            self._eval_affine(z)
        else:
            self._eval_casadi(z)
        self._z = z
        self._key = key
        return self

    def _eval_affine(self, z):
        param = self.param
        m = self.n_points
        nsec, ns = param.structure.n_sections, param.section_size
        h_ref, k_ref, _ = param._refs()
        q = self._q0 * np.exp(self._dlog_delay * z[0]) / (k_ref * z[1])
        lg = self._lg
        lg[0] = self._dlog_delay
        lg[1] = -1.0 / z[1]
        self._blk = []
        if nsec:
            v = z[2:].reshape(nsec, ns)
            # complex before the products (the values cast as the products cast them): a
            # real factor makes numpy cast it in buffers, point by point; the ufuncs'
            # reduce is what np.sum and np.prod call, without their Python wrapper
            vn = v[:, self._sl_num, None].astype(complex)                   # (nsec, kn, 1)
            vd = v[:, self._sl_den, None].astype(complex)
            inum = 1.0 / (self._n0 - np.add.reduce(vn * self._neg_dnum_t, axis=1))
            iden = 1.0 / (self._d0 + np.add.reduce(vd * self._dden_t, axis=1))  # (nsec, M)
            q = q * np.multiply.reduce(inum / iden, axis=0)
            # dlog q/dv straight into L's rows: -dnum/num and +dden/den, (nsec, k, M) views
            sec = lg[2:].reshape(nsec, ns, m)
            ln = _product_into(self._neg_dnum_t, inum[:, None, :], sec, self._sl_num)
            ld = _product_into(self._dden_t, iden[:, None, :], sec, self._sl_den)
            # the blocks need products of two log-derivatives: the sign of -dnum cancels
            self._blk = [(self._ix_num, ln, 1.0), (self._ix_den, ld, -1.0)]
        self._sq, self._a = q, None
        self._r = q - self._sw
        self._L, self._t2 = lg, None

    def _eval_casadi(self, z):
        param = self.param
        m, n = self.n_points, param.n_vars
        nsec, ns = param.structure.n_sections, param.section_size
        self._zbuf[:] = z
        self._trigger()
        # a (2, K) output in column-major order is K interleaved (re, im) pairs; the
        # mapped (2, n) blocks come side by side, so (2, n*M) -> complex (M, n)
        r, sq, ld, ln, t2 = (o.view(complex) for o in self._outs)
        self._r, self._sq, self._a = r.copy(), sq.copy(), None
        ld, ln = ld.reshape(m, n), ln.reshape(m, n)
        self._L = np.ascontiguousarray((ld - ln).T)
        sln = np.ascontiguousarray(ln[:, 2:].reshape(m, nsec, ns).transpose(1, 2, 0))
        sld = np.ascontiguousarray(ld[:, 2:].reshape(m, nsec, ns).transpose(1, 2, 0))
        full = self._ix_full
        self._blk = [] if not nsec else [(full, sln, 1.0), (full, sld, -1.0)]
        self._t2 = t2.reshape(m, self.n_t2).copy() if self.n_t2 else None

    def column_norms(self, z):
        """``||J_j||``, ndarray (n,): the 2-norms of the Jacobian's columns (the square
        root of the Gauss-Newton diagonal), O(n M) from the cached pieces.

        Parameters
        ----------
        z : ndarray of float, shape (n,)

        Returns
        -------
        ndarray of float, shape (n,)
        """
        self._eval(z)
        a = self._abs2()
        lg = self._L
        lr, li = self._scratch((lg.shape[0], min(lg.shape[1], _BLOCK_POINTS)), float, 2)
        total = None
        for sl in _blocks(lg.shape[1]):
            k = sl.stop - sl.start
            br, bi = lr[:, :k], li[:, :k]
            np.square(lg[:, sl].real, out=br)
            br += np.square(lg[:, sl].imag, out=bi)
            part = br @ a[sl]
            total = part if total is None else total + part
        return np.sqrt(total)

    def _abs2(self):
        """``|sqrt_w q|^2`` at the current point, (M,), computed once per point (the column
        norms and the Hessian both need it; the caller must not write into it)."""
        if self._a is None:
            self._a = self._sq.real ** 2 + self._sq.imag ** 2
        return self._a

    def _scratch(self, shape, dtype, count):
        """``count`` scratch arrays of ``shape`` and ``dtype``, allocated once per stage:
        the per-iteration products of the Hessian and the column norms write into them
        instead of allocating O(n M) temporaries at every call (same operations, same
        numbers)."""
        key = (shape, np.dtype(dtype).char, count)
        if key not in self._work:
            self._work[key] = [np.empty(shape, dtype) for _ in range(count)]
        return self._work[key]

    def residual_jacobian(self, z):
        """``(r (2M,), J (2M, n))`` with ``J = dr/dz`` stacked ``[Re; Im]``; ``J`` is written
        block by block (no complex (M, n) copy beside it)."""
        self._eval(z)
        m, n = self.n_points, self._L.shape[0]
        if m <= _BLOCK_POINTS:
            # as it always was: a blockwise-filled array, equal entry by entry, sent the
            # actuator's 2-section sequential fit down another path (same errors to 1e-13,
            # other bits); the fits downstream depend on more than the entries
            jc = self._L.T * self._sq[:, None]                       # complex J (M, n)
            return (np.concatenate([self._r.real, self._r.imag]),
                    np.vstack([jc.real, jc.imag]))
        jac = np.empty((2 * m, n))
        for sl in _blocks(m):
            jc = self._L[:, sl].T * self._sq[sl, None]                # complex J rows
            jac[sl] = jc.real
            jac[m + sl.start:m + sl.stop] = jc.imag
        return np.concatenate([self._r.real, self._r.imag]), jac

    def projected_fraction(self, z, free, rcond=1e-10):
        """``||P r|| / ||r||`` without forming the Jacobian: the part of the residual the
        linearised model can remove, as :func:`freqid_casadi.solvers.termination.
        projected_fraction` computes it from ``r`` and ``J`` (its SVD of the unit-column
        ``J[:, free]``), here from a QR of ``[J[:, free] / ||J_j|| | r]`` reduced block by
        block (:data:`_BLOCK_POINTS` points) to its R factor ``[[R, c], [0, rho]]``: the
        singular values and left singular vectors ``U_R`` of ``R`` are those of the
        unit-column Jacobian (``U = Q U_R``), so ``||U_k^T r|| = ||U_R,k^T c||``. Memory
        O(block x n) instead of about four (2M, n) copies (at 200 000 points and 14
        variables, 180 MB); the same number to rounding.

        Parameters
        ----------
        z : ndarray of float, shape (n,)
        free : ndarray of bool, shape (n,)
            The variables the test counts as free.
        rcond : float
            Singular values below ``rcond`` times the largest are dropped.

        Returns
        -------
        float
        """
        self._eval(z)
        r, m = self._r, self.n_points
        nr = float(np.sqrt(np.vdot(r, r).real))
        idx = np.flatnonzero(np.asarray(free, bool))
        if nr == 0.0 or idx.size == 0:
            return 0.0
        cn = self.column_norms(z)[idx]
        idx, cn = idx[cn > 0], cn[cn > 0]
        k = idx.size
        if k == 0:
            return 0.0
        rt = np.zeros((0, k + 1))
        for sl in _blocks(m):
            a = np.empty((k + 1, sl.stop - sl.start), complex)       # [J_free / cn | r]^T
            np.multiply(self._L[idx, sl], self._sq[sl], out=a[:k])
            a[:k] /= cn[:, None]
            a[k] = r[sl]
            rt = np.linalg.qr(np.vstack([rt, a.real.T, a.imag.T]), mode="r")
        u, sv, _ = np.linalg.svd(rt[:k, :k])
        u = u[:, sv > rcond * sv[0]]
        return float(np.linalg.norm(u.T @ rt[:k, k])) / nr

    def gradient(self, z):
        """``(cost, grad)`` with ``grad = 2 J^T r = 2 Re(L c)``, ``c = conj(r) sqrt_w q``."""
        self._eval(z)
        r = self._r
        cc = self._sq.conj() * r                                     # conj(c)
        # Re(L c) = Lr cr - Li ci: one product over the interleaved (re, im) views
        grad = 2.0 * (self._L.view(float) @ cc.view(float))
        return float(np.vdot(r, r).real), grad

    def hessian(self, z, exact=True, point_weights=None):
        """Hessian of the cost, (n, n); with ``point_weights`` (M,) the Hessian of
        ``sum_i point_weights_i |r_i|^2`` instead.

        ``2 Re(J^H J)`` (Gauss-Newton) plus, if ``exact``,
        ``2 Re sum_i c_i (L_i L_i^T + d2 log q_i)`` with ``c_i = conj(r_i) sqrt_w_i q_i``.
        The first two terms are one real product over the interleaved (re, im) parts:
        ``Re sum_i (a_i conj(L_i) + c_i L_i) L_i^T = [Lr Li] [Yr Yi]^T`` with
        ``Y = a L + conj(c L)``, ``a = |sqrt_w q|^2``; ``d2 log q`` is block diagonal
        (per section ``Ln Ln^T - Ld Ld^T + T2``, and ``1/z_K^2`` for the gain).
        """
        self._eval(z)
        lg = self._L
        a = self._abs2()                                              # |sqrt_w q|^2
        c = np.conj(self._r) * self._sq
        if point_weights is not None:
            a, c = a * point_weights, c * point_weights
        # complex, as the product casts it (a real factor is cast in buffers, point by point)
        a = a.astype(complex)
        y, t = self._scratch((lg.shape[0], min(lg.shape[1], _BLOCK_POINTS)), complex, 2)
        h = None
        for sl in _blocks(lg.shape[1]):                  # one block up to _BLOCK_POINTS
            k = sl.stop - sl.start
            lb, yb, tb = lg[:, sl], y[:, :k], t[:, :k]
            np.multiply(lb, a[sl], out=yb)
            if exact:
                np.multiply(lb, c[sl], out=tb)
                yb += np.conjugate(tb, out=tb)
            part = lb.view(float) @ yb.view(float).T
            h = part if h is None else h + part
        h = (h + h.T) / 2.0
        if exact:
            nsec, ns = self.param.structure.n_sections, self.param.section_size
            if nsec:
                # per-section blocks sum_i c_i (ln ln^T - ld ld^T), over the variables each
                # factor depends on: (nsec, k, k) products contracted with c
                blocks = np.zeros((nsec, ns, ns))
                for ix, s_, sign in self._blk:
                    pk = None
                    for sl in _blocks(lg.shape[1]):      # (nsec, k, k, block) at a time
                        sb = s_[:, :, sl]
                        part = (sb[:, :, None] * sb[:, None, :]) @ c[sl]  # (nsec, k, k)
                        pk = part if pk is None else pk + part
                    blocks[ix] += sign * pk.real
                if self._t2 is not None:
                    blocks = blocks + (c @ self._t2).real.reshape(nsec, ns, ns)
                diag = np.arange(nsec)
                hv = h[2:, 2:].reshape(nsec, ns, nsec, ns)        # a view: h is C-ordered
                hv[diag, :, diag, :] += blocks
            h[1, 1] += np.add.reduce(c).real / self._z[1] ** 2
        return 2.0 * h


class PNormFunctions:
    """The p-norm stand-in for the largest squared relative residual,
    ``F(z) = (1/p) log sum_i (e_i/s)^(p/2)`` with ``e_i = |r_i|^2``, and its exact gradient
    and Hessian from a stage's :class:`StageFunctions` (same interface: ``param``,
    ``gradient``, ``hessian``).

    With softmax weights ``w_i = (e_i/s)^(p/2) / sum_j (e_j/s)^(p/2)`` and ``u_i = w_i/e_i``:
    ``grad F = 1/2 sum_i u_i grad e_i`` and
    ``hess F = 1/2 sum_i u_i hess e_i + 1/2 (p/2 - 1) sum_i (u_i/e_i) grad e_i grad e_i^T
    - p grad F grad F^T``, where ``sum_i u_i hess e_i`` is the stage Hessian with point
    weights ``u`` and ``grad e_i = 2 Re(c_i L_i)``: about the cost of one least-squares
    Hessian, instead of AD through the log-sum-exp.

    Parameters
    ----------
    funcs : StageFunctions
    p : float >= 2
    s : float > 0
        Scale of ``e`` (the largest ``e_i`` at the start), so the terms are O(1).
    """

    def __init__(self, funcs, p, s):
        self.funcs = funcs
        self.param = funcs.param
        self.n_points = funcs.n_points
        self.p = float(p)
        self.s = float(s)
        self._key, self._cached = None, None

    def _parts(self, z):
        """(F, grad F, u, u/e, grad e) at ``z``, cached: IPOPT asks for the gradient and
        the Hessian at the same point."""
        key = np.asarray(z, float).tobytes()
        if key != self._key:
            self._cached, self._key = self._compute(z), key
        return self._cached

    def _compute(self, z):
        f = self.funcs
        f._eval(z)
        e = np.maximum(f._r.real ** 2 + f._r.imag ** 2, 1e-300)
        le = np.log(e)
        t = 0.5 * self.p * (le - np.log(self.s))
        lse = float(np.max(t) + np.log(np.sum(np.exp(t - np.max(t)))))
        lw = t - lse                                                 # log softmax weights
        u = np.exp(lw - le)                                          # w_i / e_i
        c = np.conj(f._r) * f._sq
        ge = 2.0 * (f._L.real * c.real - f._L.imag * c.imag)         # grad e_i, (n, M)
        grad = 0.5 * (ge @ u)
        return lse / self.p, grad, u, np.exp(lw - 2.0 * le), ge

    def gradient(self, z):
        """``(F, grad F)``."""
        value, grad, *_ = self._parts(z)
        return value, grad

    def hessian(self, z, exact=True):
        """Exact Hessian of ``F`` (n, n); ``exact=False`` drops the residuals' second
        derivatives inside ``hess e_i`` (Gauss-Newton-like)."""
        _, grad, u, beta, ge = self._parts(z)
        h = 0.5 * self.funcs.hessian(z, exact=exact, point_weights=u)
        h += 0.5 * (0.5 * self.p - 1.0) * ((ge * beta) @ ge.T)
        h -= self.p * np.outer(grad, grad)
        return (h + h.T) / 2.0


def _derivative_path(derivatives, gauge):
    """The derivative path of a stage ("affine" or "casadi-map"; None: "affine" in the dc
    gauge, else "casadi-map"), checked against the gauge."""
    if derivatives is None:
        return "affine" if gauge == "dc" else "casadi-map"
    if derivatives not in ("affine", "casadi-map"):
        raise OptionError(f"unknown derivatives {derivatives!r}; choose 'affine' or "
                          "'casadi-map'")
    if derivatives == "affine" and gauge != "dc":
        raise OptionError("derivatives='affine' needs the 'dc' gauge (its sections are "
                          "affine in the variables); use 'casadi-map'")
    return derivatives


def _as_slice(idx):
    """A slice for a run of consecutive indices (a view when indexing), else the list."""
    if idx and list(idx) == list(range(idx[0], idx[-1] + 1)):
        return slice(idx[0], idx[-1] + 1)
    return list(idx)


def _block_index(idx):
    """The index of the (k, k) blocks of ``idx`` in a (nsec, ns, ns) array: slices for a
    run of consecutive indices (a view), else the grid ``np.ix_(idx, idx)``."""
    sl = _as_slice(list(idx))
    return (slice(None),) + ((sl, sl) if isinstance(sl, slice) else np.ix_(sl, sl))


def _product_into(a, b, sec, sl):
    """``a * b`` written into ``sec[:, sl]``; returns the written block (a view if ``sl`` is
    a slice)."""
    if isinstance(sl, slice):
        out = sec[:, sl]
        np.multiply(a, b, out=out)
        return out
    out = a * b
    sec[:, sl] = out
    return out


def stage_functions(param, omega, response, weights=None, derivatives=None):
    """Build the :class:`StageFunctions` of one stage (once per stage).

    Parameters
    ----------
    param : Parametrization
    omega, response, weights, derivatives
        As :class:`StageFunctions`.

    Returns
    -------
    StageFunctions
    """
    return StageFunctions(param, omega, response, weights, derivatives)
