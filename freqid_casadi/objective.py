"""The relative-error objective, written once for numpy and CasADi (layer L2).

The fitted quantity is the relative residual (SPEC §1)::

    r_i = Phi_i / G_N(j w_i; beta) - 1,      eps(beta) = sum_i w_i |r_i|^2

built as ``Phi * exp(+j w h) * [j w] / K * prod_k den_k / num_k - 1`` with only +-x/ on
(re, im) pairs (STYLE.md §1.2), so the same code evaluates on numpy arrays and on CasADi
SX symbols.

Gauges
------
Each section num_k/den_k can be scaled as a whole (num and den together, SPEC §1), and with a
free gain K each factor's scale can also be traded against K. The optimiser therefore works
on variables ``z`` in a *gauge*, mapped to the thesis's ``beta`` afterwards:

``"dc"`` (the package's default)
    ``num_k = 1 - p2 (w/wr_k)^2 + j p1 (w/wr_k)`` and likewise ``den_k`` with ``q2, q1``:
    every factor has unit DC value and the gain sits in K alone. This removes both
    redundant directions per section, keeps the bounds ``p, q >= 0`` exactly equivalent to
    "roots in the closed left half plane" (a quadratic with positive constant term is
    Hurwitz iff its coefficients are nonnegative), and lets ``p2 -> 0`` represent a zero at
    infinity (relative degree) at a simple bound. ``wr_k`` is a fixed reference frequency
    (the frequency at which the section was inserted), so the variables are O(1).
``"b1"``
    The thesis's parameters with ``b_k = 1`` fixed (SPEC §1's example). One redundant
    direction per section remains (numerator scale against K).
``"raw"``
    The thesis's six parameters per section, all free (both redundant directions left in).

With the first-order basis the sections are ``(1 + j p1 w/wr)/(1 + j q1 w/wr)`` in the dc
gauge and ``(a1 s + a0)/(b1 s + b0)`` (``b0 = 1`` in "b1") otherwise.

Variable scaling: ``h = delay_max * z[0]`` and ``K = gain_ref * z[1]``; frequencies inside
sections are divided by ``wr_k``. With ``scaled=False`` all references are 1.
"""

from dataclasses import dataclass

import numpy as np

from . import _cplx
from .errors import OptionError, StructureError
from .model import RationalDelayModel, Structure

__all__ = ["GAUGES", "Parametrization", "relative_residual", "rel_error_stats",
           "stage_functions", "StageFunctions"]

GAUGES = ("dc", "b1", "raw")


def relative_residual(model, omega, response):
    """Complex relative residual ``Phi/G_N - 1`` of a model at the data, shape (M,)."""
    return np.asarray(response) / model.frequency_response(omega) - 1.0


def rel_error_stats(rel_error):
    """(max, rms) of an array of |relative error| values."""
    rel_error = np.asarray(rel_error, float)
    return float(np.max(rel_error)), float(np.sqrt(np.mean(rel_error ** 2)))


@dataclass(frozen=True)
class Parametrization:
    """Map between optimisation variables ``z`` and the model's ``beta``.

    Parameters
    ----------
    structure : Structure
    gauge : {"dc", "b1", "raw"}
    omega_ref : tuple of float, length structure.n_sections
        Reference frequency (rad/s) of each section's variables.
    gain_ref : float
        Scale of the gain variable: K = gain_ref * z[1].
    delay_max : float
        Upper bound of the delay (s); h = delay_max * z[0] when scaled.
    scaled : bool
        If False, all references are 1 and h = z[0] (bound still ``delay_max``).
    """

    structure: Structure
    gauge: str = "dc"
    omega_ref: tuple = ()
    gain_ref: float = 1.0
    delay_max: float = 1.0
    scaled: bool = True

    def __post_init__(self):
        if self.gauge not in GAUGES:
            raise OptionError(f"unknown gauge {self.gauge!r}; choose one of {', '.join(GAUGES)}")
        if len(self.omega_ref) != self.structure.n_sections:
            raise StructureError(
                f"omega_ref needs one frequency per section: got {len(self.omega_ref)} for "
                f"{self.structure.n_sections} sections")
        object.__setattr__(self, "omega_ref", tuple(float(w) for w in self.omega_ref))
        if not (np.isfinite(self.delay_max) and self.delay_max > 0):
            raise OptionError(f"delay_max must be a finite number > 0 (s), got {self.delay_max}")

    # ---------------------------------------------------------------- layout
    @property
    def section_size(self):
        second = self.structure.basis == "second-order"
        return {"dc": 4 if second else 2, "b1": 5 if second else 3,
                "raw": 6 if second else 4}[self.gauge]

    @property
    def n_vars(self):
        return 2 + self.section_size * self.structure.n_sections

    def _refs(self):
        if self.scaled:
            return self.delay_max, self.gain_ref, self.omega_ref
        return 1.0, 1.0, (1.0,) * self.structure.n_sections

    def bounds(self):
        """(lb, ub) arrays of shape (n_vars,): z >= 0, delay <= delay_max, h = 0 if no delay."""
        lb = np.zeros(self.n_vars)
        ub = np.full(self.n_vars, np.inf)
        h_ref = self._refs()[0]
        ub[0] = (self.delay_max / h_ref) if self.structure.delay else 0.0
        return lb, ub

    def extend(self, omega_ref_new):
        """The parametrization with one more section at reference ``omega_ref_new``."""
        return Parametrization(self.structure.with_sections(self.structure.n_sections + 1),
                               self.gauge, self.omega_ref + (float(omega_ref_new),),
                               self.gain_ref, self.delay_max, self.scaled)

    def new_section(self, omega_num, zeta_num, omega_den, zeta_den, omega_ref, scale_l=1.0):
        """Variables of a section to append at reference ``omega_ref`` (rad/s) whose
        numerator/denominator have the given natural frequencies (rad/s) and dampings.

        ``scale_l`` multiplies num and den together (a -> l a, zeta -> sqrt(l) zeta,
        omega -> sqrt(l) omega; the thesis's initial point); it leaves the section unchanged
        and only matters in the "raw" gauge.
        """
        wr = float(omega_ref) if self.scaled else 1.0
        if self.gauge == "dc":
            if self.structure.basis == "second-order":
                return np.array([(wr / omega_num) ** 2, 2 * zeta_num * wr / omega_num,
                                 (wr / omega_den) ** 2, 2 * zeta_den * wr / omega_den])
            return np.array([wr / omega_num, wr / omega_den])
        if self.structure.basis == "second-order":
            sec = [1.0, zeta_num, omega_num / wr, 1.0, zeta_den, omega_den / wr]
            if self.gauge == "raw":
                rl = np.sqrt(scale_l)
                return np.array([scale_l, rl * sec[1], rl * sec[2],
                                 scale_l, rl * sec[4], rl * sec[5]])
            return np.array(sec[:3] + sec[4:])
        sec = [wr / omega_num, 1.0, wr / omega_den, 1.0]
        if self.gauge == "raw":
            return scale_l * np.array(sec)
        return np.array(sec[:3])

    # ---------------------------------------------------------------- formula
    def _sections(self, z):
        """Yield (num, den) (re, im)-pair builders per section as functions of w."""
        n = self.section_size
        _, _, wr = self._refs()
        second = self.structure.basis == "second-order"
        for k in range(self.structure.n_sections):
            v = [z[2 + n * k + i] for i in range(n)]
            yield k, v, wr[k], second

    def ratio(self, z, omega, response_pair):
        """Phi / G_N(j w) as an (re, im) pair; numpy or CasADi.

        Parameters
        ----------
        z : sequence of length n_vars (numpy array or CasADi SX/MX vector)
        omega : float or ndarray, rad/s
        response_pair : (re, im) of Phi at omega
        """
        h_ref, k_ref, _ = self._refs()
        h = h_ref * z[0]
        gain = k_ref * z[1]
        cos, sin = _trig(z)
        q = _cplx.mul(response_pair, (cos(omega * h), sin(omega * h)))
        if self.structure.integrator:
            q = _cplx.mul(q, (0 * omega, omega))
        q = (q[0] / gain, q[1] / gain)
        for k, v, wr, second in self._sections(z):
            x = omega / wr
            num, den = _section_pairs(self.gauge, second, v, x)
            q = _cplx.mul(q, _cplx.div(den, num))
        return q

    def residual_pair(self, z, omega, response_pair, sqrt_weights=None):
        """Weighted (re, im) residual of ``Phi/G_N - 1``."""
        re, im = self.ratio(z, omega, response_pair)
        re = re - 1.0
        if sqrt_weights is not None:
            re, im = re * sqrt_weights, im * sqrt_weights
        return re, im

    # ---------------------------------------------------------------- conversions
    def to_beta(self, z):
        """Thesis parameters ``beta`` (numpy, >= 0) of the variables ``z``."""
        z = np.maximum(np.asarray(z, float), 0.0)
        h_ref, k_ref, wr_all = self._refs()
        h = h_ref * z[0] if self.structure.delay else 0.0
        gain = k_ref * z[1]
        secs = []
        for k, v, wr, second in self._sections(z):
            if second:
                if self.gauge == "dc":
                    p2, p1, q2, q1 = v
                    a, zn, wn, sn = _dc_to_thesis(p2, p1, wr)
                    b, zd, wd, sd = _dc_to_thesis(q2, q1, wr)
                    gain *= sd / sn
                    secs += [a, zn, wn, b, zd, wd]
                else:
                    if self.gauge == "b1":
                        a, zn, wn, zd, wd = v
                        b = 1.0
                    else:
                        a, zn, wn, b, zd, wd = v
                    secs += [a, zn, wn * wr, b, zd, wd * wr]
            else:
                if self.gauge == "dc":
                    p1, q1 = v
                    secs += [p1 / wr, 1.0, q1 / wr, 1.0]
                else:
                    if self.gauge == "b1":
                        a1, a0, b1 = v
                        b0 = 1.0
                    else:
                        a1, a0, b1, b0 = v
                    secs += [a1 / wr, a0, b1 / wr, b0]
        return np.array([h, gain] + [float(s) for s in secs])

    def to_model(self, z):
        """The :class:`RationalDelayModel` of the variables ``z``."""
        return RationalDelayModel(self.structure, self.to_beta(z))

    def from_beta(self, beta):
        """Variables ``z`` reproducing ``beta`` exactly in this gauge (for warm starts)."""
        beta = np.asarray(beta, float)
        h_ref, k_ref, wr_all = self._refs()
        ss = self.structure.section_size
        z = [beta[0] / h_ref, 0.0]
        gain = beta[1]
        second = self.structure.basis == "second-order"
        for k in range(self.structure.n_sections):
            th = beta[2 + ss * k: 2 + ss * (k + 1)]
            wr = wr_all[k]
            if second:
                a, zn, wn, b, zd, wd = th
                if self.gauge == "dc":
                    if wn <= 0 or wd <= 0:
                        raise StructureError(
                            f"section {k + 1} has a root at s=0 (omega=0); not representable "
                            "in the dc gauge")
                    z += [a * wr ** 2 / wn ** 2, 2 * zn * wr / wn,
                          b * wr ** 2 / wd ** 2, 2 * zd * wr / wd]
                    gain *= wn ** 2 / wd ** 2
                elif self.gauge == "b1":
                    if b <= 0:
                        raise StructureError(f"section {k + 1} has b=0; not representable with b=1")
                    # divide num and den by b: a/b, zeta/sqrt(b), omega/sqrt(b)
                    sb = np.sqrt(b)
                    z += [a / b, zn / sb, wn / sb / wr, zd / sb, wd / sb / wr]
                else:
                    z += [a, zn, wn / wr, b, zd, wd / wr]
            else:
                a1, a0, b1, b0 = th
                if self.gauge == "dc":
                    if a0 <= 0 or b0 <= 0:
                        raise StructureError(f"section {k + 1} has a root at s=0")
                    z += [a1 / a0 * wr, b1 / b0 * wr]
                    gain *= a0 / b0
                elif self.gauge == "b1":
                    z += [a1 / b0 * wr, a0 / b0, b1 / b0 * wr]
                else:
                    z += [a1 * wr, a0, b1 * wr, b0]
        z[1] = gain / k_ref
        return np.array(z, float)


def _trig(z):
    """cos/sin that work for numpy and for CasADi symbols."""
    if isinstance(z, np.ndarray) or isinstance(z, (list, tuple)):
        return np.cos, np.sin
    import casadi as ca

    return ca.cos, ca.sin


def _section_pairs(gauge, second, v, x):
    """(num, den) (re, im) pairs of one section at scaled frequency x = w/wr."""
    if second:
        if gauge == "dc":
            p2, p1, q2, q1 = v
            x2 = x * x
            return (1 - p2 * x2, p1 * x), (1 - q2 * x2, q1 * x)
        if gauge == "b1":
            a, zn, wn, zd, wd = v
            b = 1.0
        else:
            a, zn, wn, b, zd, wd = v
        x2 = x * x
        return (wn * wn - a * x2, 2 * zn * wn * x), (wd * wd - b * x2, 2 * zd * wd * x)
    if gauge == "dc":
        p1, q1 = v
        return (1 + 0 * x, p1 * x), (1 + 0 * x, q1 * x)
    if gauge == "b1":
        a1, a0, b1 = v
        b0 = 1.0
    else:
        a1, a0, b1, b0 = v
    return (a0 + 0 * x, a1 * x), (b0 + 0 * x, b1 * x)


def _dc_to_thesis(c2, c1, wr):
    """Thesis form (a, zeta, omega) and scale s of ``1 + c1 (s/wr) + c2 (s/wr)^2``:
    the factor equals ``(a s^2 + 2 zeta omega s + omega^2) / s`` with ``s = omega^2``."""
    if c2 > 0:
        omega = wr / np.sqrt(c2)
        return 1.0, c1 / (2 * np.sqrt(c2)), omega, omega * omega
    # zero at infinity: a = 0, omega = wr -> factor (2 zeta wr s + wr^2)/wr^2
    return 0.0, c1 / 2.0, wr, wr * wr


def _point_functions(param):
    """Per-point SX Functions of one stage (inputs z, omega, phi_re, phi_im, sqrt_w).

    ``residual_point`` -> r (2,): the weighted residual (re, im).

    ``derivative_point`` -> r (2,), sq (2,), Ld (2, n), Ln (2, n), T2 (2, N ns^2):
    the pieces of the exact derivatives, using the product structure of the model. With
    ``q = Phi e^{j w h} [j w] / K prod_k den_k/num_k`` and ``r = sqrt_w (q - 1)``:

    - ``dr/dv = sqrt_w q dlog(q)/dv`` with ``dlog q = Ld - Ln``, where ``Ld`` holds the
      log-derivatives of the delay factor, the gain and each ``den_k`` and ``Ln`` those of
      each ``num_k`` (``(d num/dv)/num``, from CasADi's AD of the section formula);
    - ``d2 log q`` is ``Ln Ln^T - Ld Ld^T`` within each section's block, plus
      ``(d2 den/den - d2 num/num)`` (``T2``; structurally zero in the dc gauge), plus
      ``1/z_K^2`` for the gain.

    Each formula is still written once (:func:`_section_pairs`); assembling ``J`` and the
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
    re, im = param.residual_pair(z, w, phi, sw)
    r_point = ca.Function("residual_point", inputs, [ca.vertcat(re, im)], names, ["r"])

    h_ref, k_ref, wr = param._refs()
    q = _cplx.mul(phi, (ca.cos(w * h_ref * z[0]), ca.sin(w * h_ref * z[0])))
    if param.structure.integrator:
        q = _cplx.mul(q, (0, w))
    q = (q[0] / (k_ref * z[1]), q[1] / (k_ref * z[1]))
    ld = [(0, w * h_ref), (-1 / z[1], 0)]
    ln = [(0, 0), (0, 0)]
    t2 = []
    ns = param.section_size
    second = param.structure.basis == "second-order"
    for k in range(param.structure.n_sections):
        v = [z[2 + ns * k + i] for i in range(ns)]
        num, den = _section_pairs(param.gauge, second, v, w / wr[k])
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
    d_point = ca.Function("derivative_point", inputs, outs, names,
                          ["r", "sq", "Ld", "Ln", "T2"])
    return r_point, d_point


class StageFunctions:
    """Residual, Jacobian and Hessian of one stage's objective, built once per stage.

    ``cost(z) = ||r(z)||^2`` with ``r`` the stacked weighted residual ``[Re; Im]`` (2M,).

    Attributes
    ----------
    param : Parametrization
    n_points : int
    r_fun : casadi.Function
        ``z (n,) -> r (2M,)``, symbolic (the NLP's objective is ``sumsqr(r_fun(z))``).
    d_fun : casadi.Function
        ``z -> (r, sq, Ld, Ln, T2)`` mapped over points (see :func:`_point_functions`).
    """

    def __init__(self, param, omega, response, weights=None, parallel=False):
        import casadi as ca

        self.param = param
        omega = np.asarray(omega, float)
        resp = np.asarray(response, complex)
        m = omega.size
        self.n_points = m
        sw = np.ones(m) if weights is None else np.sqrt(np.asarray(weights, float))
        r_point, d_point = _point_functions(param)
        mode = ("thread", 2) if parallel else ("serial",)
        data = [omega.reshape(1, -1), resp.real.reshape(1, -1), resp.imag.reshape(1, -1),
                sw.reshape(1, -1)]
        n = param.n_vars
        z = ca.MX.sym("z", n)
        zz = ca.repmat(z, 1, m)
        r2 = r_point.map(m, *mode)(zz, *data)                       # (2, M)
        self.r_fun = ca.Function("residual", [z], [ca.vec(ca.transpose(r2))], ["z"], ["r"])
        outs = d_point.map(m, *mode)(zz, *data)
        self.d_fun = ca.Function("derivatives", [z], [ca.densify(o) for o in outs], ["z"],
                                 ["r", "sq", "Ld", "Ln", "T2"])
        self.n_t2 = int(d_point.size2_out(4))
        self._key = None
        # zero-copy evaluation: CasADi writes straight into these numpy buffers
        self._zbuf = np.zeros(n)
        self._outs = [np.zeros(2 * c) for c in (m, m, n * m, n * m, self.n_t2 * m)]
        self._buf, self._trigger = self.d_fun.buffer()
        self._buf.set_arg(0, memoryview(self._zbuf))
        for i, out in enumerate(self._outs):
            self._buf.set_res(i, memoryview(out))

    # ------------------------------------------------------------------ evaluation
    def residual(self, z):
        """Stacked residual ``[Re r; Im r]``, ndarray (2M,)."""
        return self.r_fun(np.asarray(z, float)).full().reshape(-1)

    def cost(self, z):
        r = self.residual(z)
        return float(r @ r)

    def _eval(self, z):
        z = np.asarray(z, float).reshape(-1)
        key = z.tobytes()
        if key != self._key:
            m, n = self.n_points, self.param.n_vars
            self._zbuf[:] = z
            self._trigger()
            # a (2, K) output in column-major order is K interleaved (re, im) pairs; the
            # mapped (2, n) blocks come side by side, so (2, n*M) -> complex (M, n)
            # views, not copies (memory at large M): the buffers change only at the next
            # new point, when every quantity derived from them is recomputed too
            r, sq, ld, ln, t2 = (o.view(complex) for o in self._outs)
            self._r, self._sq = r, sq
            self._ld = ld.reshape(m, n)
            self._ln = ln.reshape(m, n)
            self._t2 = t2.reshape(m, self.n_t2) if self.n_t2 else None
            self._jc = self._sq[:, None] * (self._ld - self._ln)    # complex J (M, n)
            self._z = z
            self._key = key
        return self

    def residual_jacobian(self, z):
        """``(r (2M,), J (2M, n))`` with ``J = dr/dz`` stacked ``[Re; Im]``."""
        self._eval(z)
        return (np.concatenate([self._r.real, self._r.imag]),
                np.vstack([self._jc.real, self._jc.imag]))

    def gradient(self, z):
        """``(cost, grad)`` with ``grad = 2 J^T r`` (n,)."""
        self._eval(z)
        r, jc = self._r, self._jc
        return float(np.vdot(r, r).real), 2.0 * (jc.real.T @ r.real + jc.imag.T @ r.imag)

    def hessian(self, z, exact=True, clip=False):
        """Hessian of the cost, (n, n): ``2 J^T J`` (Gauss-Newton) plus, if ``exact``,
        ``2 Re sum_i c_i (L_i L_i^T + Lambda_i)`` with ``c_i = conj(r_i) sqrt_w_i q_i``."""
        self._eval(z)
        jc = self._jc
        h = 2.0 * (jc.real.T @ jc.real + jc.imag.T @ jc.imag)
        if not exact:
            return h
        m = self.n_points
        c = np.conj(self._r) * self._sq                             # (M,)
        lg = self._ld - self._ln
        h2 = lg.T @ (c[:, None] * lg)                                # sum c L L^T
        ns, nsec = self.param.section_size, self.param.structure.n_sections
        if nsec:
            lnr = self._ln[:, 2:].reshape(m, nsec, ns)
            ldr = self._ld[:, 2:].reshape(m, nsec, ns)
            # per-section blocks sum_i c_i (ln ln^T - ld ld^T): batched matmul over sections
            lnt, ldt = np.transpose(lnr, (1, 2, 0)), np.transpose(ldr, (1, 2, 0))
            blocks = (np.matmul(lnt * c, np.transpose(lnr, (1, 0, 2)))
                      - np.matmul(ldt * c, np.transpose(ldr, (1, 0, 2))))
            if self._t2 is not None:
                blocks = blocks + np.einsum("m,mk->k", c, self._t2).reshape(nsec, ns, ns)
            for k in range(nsec):
                sl = slice(2 + ns * k, 2 + ns * (k + 1))
                h2[sl, sl] += blocks[k]
        h2[1, 1] += np.sum(c) / self._z[1] ** 2
        h = h + 2.0 * h2.real
        if clip:
            # modified Newton: clip negative curvature to zero (eigen-clip)
            lam, vec = np.linalg.eigh(h)
            h = (vec * np.maximum(lam, 0.0)) @ vec.T
        return h


def stage_functions(param, omega, response, weights=None, parallel=False):
    """Build the :class:`StageFunctions` of one stage (once per stage)."""
    return StageFunctions(param, omega, response, weights, parallel)
