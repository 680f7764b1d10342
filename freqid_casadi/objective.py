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
           "stage_functions", "StageFunctions", "PNormFunctions"]

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

    # ---------------------------------------------------------------- damping floor
    def damping_pairs(self):
        """Indices ``(i2, i1)`` of each quadratic's ``(c2, c1)`` variables (dc gauge,
        second-order basis): two per section, numerator then denominator."""
        if self.gauge != "dc" or self.structure.basis != "second-order":
            raise OptionError("a damping floor needs the 'dc' gauge and the second-order "
                              f"basis (got gauge {self.gauge!r}, basis "
                              f"{self.structure.basis!r})")
        ns = self.section_size
        return [(2 + ns * k + j, 2 + ns * k + j + 1) for k in range(self.structure.n_sections)
                for j in (0, 2)]

    def damping_constraints(self, zeta_min):
        """``g(z) >= 0`` for a damping ratio ``>= zeta_min`` of every pole and zero.

        In the dc gauge a quadratic is ``1 + c1 (s/wr) + c2 (s/wr)^2`` with
        ``c2 = (wr/w0)^2`` and ``c1 = 2 zeta0 wr/w0``, so ``zeta0 >= zeta_min`` with
        ``c1 >= 0`` is ``c1^2 - 4 zeta_min^2 c2 >= 0`` (a zero at infinity, ``c2 = 0``, is
        always admissible). Returns a function of an (n,) CasADi/numpy vector giving the
        (2N,) constraint values.
        """
        pairs = self.damping_pairs()
        k4 = 4.0 * float(zeta_min) ** 2

        def g(z):
            vals = [z[i1] * z[i1] - k4 * z[i2] for i2, i1 in pairs]
            if isinstance(z, np.ndarray):
                return np.array(vals, float)
            import casadi as ca

            return ca.vertcat(*vals)

        return g

    def project_damping(self, z, zeta_min):
        """``z`` with each ``c1`` raised (never lowered) to satisfy the damping floor."""
        z = np.array(z, float)
        for i2, i1 in self.damping_pairs():
            floor = 2.0 * float(zeta_min) * np.sqrt(max(z[i2], 0.0))
            if z[i1] < floor:
                z[i1] = floor * (1.0 + 1e-9)
        return z

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
    return ca.Function("derivative_point", inputs, outs, names,
                       ["r", "sq", "Ld", "Ln", "T2"])


class StageFunctions:
    """Residual, Jacobian and Hessian of one stage's objective, built once per stage.

    ``cost(z) = ||r(z)||^2`` with ``r`` the stacked weighted residual ``[Re; Im]`` (2M,).

    Two evaluation paths, both exact and built from the one formula of
    :meth:`Parametrization.residual_pair` / :func:`_section_pairs`:

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
        # the NLP's objective: one MX expression over all points (vectorised C loops)
        z = ca.MX.sym("z", n)
        row = lambda a: ca.DM(np.asarray(a, float).reshape(1, -1))  # noqa: E731
        re, im = param.residual_pair(z, row(omega), (row(resp.real), row(resp.imag)),
                                     row(self._sw))
        self.r_fun = ca.Function("residual", [z], [ca.vertcat(ca.transpose(re),
                                                              ca.transpose(im))],
                                 ["z"], ["r"])
        if derivatives is None:
            derivatives = "affine" if param.gauge == "dc" else "casadi-map"
        if derivatives not in ("affine", "casadi-map"):
            raise OptionError(f"unknown derivatives {derivatives!r}; choose 'affine' or "
                              "'casadi-map'")
        if derivatives == "affine" and param.gauge != "dc":
            raise OptionError("derivatives='affine' needs the 'dc' gauge (its sections are "
                              "affine in the variables); use 'casadi-map'")
        self.derivatives = derivatives
        self._key = None
        nsec, ns = param.structure.n_sections, param.section_size
        h_ref, k_ref, wr = param._refs()
        self._q0 = self._sw * resp * (1j * omega if param.structure.integrator else 1.0)
        self._dlog_delay = 1j * omega * h_ref
        if derivatives == "affine":
            x = omega[None, :] / np.asarray(wr, float).reshape(-1, 1)         # (nsec, M)
            second = param.structure.basis == "second-order"

            def pair(v):
                num, den = _section_pairs("dc", second, v, x)
                return (_cplx.to_complex(np.broadcast_arrays(*num)),
                        _cplx.to_complex(np.broadcast_arrays(*den)))

            zero = [np.zeros((nsec, 1))] * ns
            n0, d0 = pair(zero)
            steps = [pair([np.ones((nsec, 1)) if j == i else zero[j] for j in range(ns)])
                     for i in range(ns)]
            # an affine factor is f(v) = f(0) + sum_i v_i (f(e_i) - f(0)) exactly
            dnum = [s_[0] - n0 for s_ in steps]
            dden = [s_[1] - d0 for s_ in steps]
            self._idx_num = [i for i in range(ns) if np.any(dnum[i] != 0)]
            self._idx_den = [i for i in range(ns) if np.any(dden[i] != 0)]
            if nsec and sorted(self._idx_num + self._idx_den) != list(range(ns)):
                raise StructureError("internal: each dc-gauge variable must enter exactly "
                                     "one of a section's numerator and denominator")
            self._n0, self._d0 = n0, d0
            if nsec:
                # (nsec, k, M), the numerator's negated: dlog q = dlog den - dlog num
                self._neg_dnum_t = -np.stack([dnum[i] for i in self._idx_num], axis=1)
                self._dden_t = np.stack([dden[i] for i in self._idx_den], axis=1)
            self._sl_num, self._sl_den = _as_slice(self._idx_num), _as_slice(self._idx_den)
            self._lg = np.empty((n, m), complex)
        else:
            d_point = _point_functions(param)
            data = [omega.reshape(1, -1), resp.real.reshape(1, -1), resp.imag.reshape(1, -1),
                    self._sw.reshape(1, -1)]
            zz = ca.repmat(z, 1, m)
            outs = d_point.map(m, "serial")(zz, *data)
            self.d_fun = ca.Function("derivatives", [z], [ca.densify(o) for o in outs],
                                     ["z"], ["r", "sq", "Ld", "Ln", "T2"])
            self.n_t2 = int(d_point.size2_out(4))
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
        """Derivative pieces at ``z`` (cached on the bytes of ``z``):

        ``_r`` (M,) complex residual, ``_sq`` (M,) = sqrt_w q, ``_L`` (n, M) = dlog q/dz,
        ``_blk``: per-section ``(indices, dlog factor/dv (nsec, len(indices), M), sign)``
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
            vn = v[:, self._idx_num, None]                                  # (nsec, kn, 1)
            vd = v[:, self._idx_den, None]
            inum = 1.0 / (self._n0 - np.sum(vn * self._neg_dnum_t, axis=1))  # (nsec, M)
            iden = 1.0 / (self._d0 + np.sum(vd * self._dden_t, axis=1))
            q = q * np.prod(inum / iden, axis=0)
            # dlog q/dv straight into L's rows: -dnum/num and +dden/den, (nsec, k, M) views
            sec = lg[2:].reshape(nsec, ns, m)
            ln = _product_into(self._neg_dnum_t, inum[:, None, :], sec, self._sl_num)
            ld = _product_into(self._dden_t, iden[:, None, :], sec, self._sl_den)
            # the blocks need products of two log-derivatives: the sign of -dnum cancels
            self._blk = [(self._idx_num, ln, 1.0), (self._idx_den, ld, -1.0)]
        self._sq = q
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
        self._r, self._sq = r.copy(), sq.copy()
        ld, ln = ld.reshape(m, n), ln.reshape(m, n)
        self._L = np.ascontiguousarray((ld - ln).T)
        sln = np.ascontiguousarray(ln[:, 2:].reshape(m, nsec, ns).transpose(1, 2, 0))
        sld = np.ascontiguousarray(ld[:, 2:].reshape(m, nsec, ns).transpose(1, 2, 0))
        full = list(range(ns))
        self._blk = [] if not nsec else [(full, sln, 1.0), (full, sld, -1.0)]
        self._t2 = t2.reshape(m, self.n_t2).copy() if self.n_t2 else None

    def column_norms(self, z):
        """``||J_j||`` (n,): the 2-norms of the Jacobian's columns (``J`` as in
        :meth:`residual_jacobian`), i.e. the square root of the Gauss-Newton diagonal."""
        self._eval(z)
        a = self._sq.real ** 2 + self._sq.imag ** 2
        return np.sqrt((self._L.real ** 2 + self._L.imag ** 2) @ a)

    def residual_jacobian(self, z):
        """``(r (2M,), J (2M, n))`` with ``J = dr/dz`` stacked ``[Re; Im]``."""
        self._eval(z)
        jc = self._L.T * self._sq[:, None]                           # complex J (M, n)
        return (np.concatenate([self._r.real, self._r.imag]),
                np.vstack([jc.real, jc.imag]))

    def gradient(self, z):
        """``(cost, grad)`` with ``grad = 2 J^T r = 2 Re(L c)``, ``c = conj(r) sqrt_w q``."""
        self._eval(z)
        r = self._r
        cc = self._sq.conj() * r                                     # conj(c)
        # Re(L c) = Lr cr - Li ci: one product over the interleaved (re, im) views
        grad = 2.0 * (self._L.view(float) @ cc.view(float))
        return float(np.vdot(r, r).real), grad

    def hessian(self, z, exact=True, clip=False, point_weights=None):
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
        a = self._sq.real ** 2 + self._sq.imag ** 2                   # |sqrt_w q|^2
        c = np.conj(self._r) * self._sq
        if point_weights is not None:
            a, c = a * point_weights, c * point_weights
        if not exact:
            y = lg * a
        else:
            y = lg * a
            y += np.conj(lg * c)
        h = lg.view(float) @ y.view(float).T
        h = (h + h.T) / 2.0
        if exact:
            nsec, ns = self.param.structure.n_sections, self.param.section_size
            if nsec:
                # per-section blocks sum_i c_i (ln ln^T - ld ld^T), over the variables each
                # factor depends on: (nsec, k, k) products contracted with c
                blocks = np.zeros((nsec, ns, ns))
                for idx, s_, sign in self._blk:
                    pk = (s_[:, :, None] * s_[:, None, :]) @ c            # (nsec, k, k)
                    blocks[:, np.ix_(idx, idx)[0], np.ix_(idx, idx)[1]] += sign * pk.real
                if self._t2 is not None:
                    blocks = blocks + (c @ self._t2).real.reshape(nsec, ns, ns)
                diag = np.arange(nsec)
                hv = h[2:, 2:].reshape(nsec, ns, nsec, ns)        # a view: h is C-ordered
                hv[diag, :, diag, :] += blocks
            h[1, 1] += np.sum(c).real / self._z[1] ** 2
        h = 2.0 * h
        if clip:
            # modified Newton: clip negative curvature to zero (eigen-clip)
            lam, vec = np.linalg.eigh(h)
            h = (vec * np.maximum(lam, 0.0)) @ vec.T
            h = (h + h.T) / 2.0
        return h


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

    def hessian(self, z, exact=True, clip=False):
        """Exact Hessian of ``F`` (n, n); ``exact=False`` drops the residuals' second
        derivatives inside ``hess e_i`` (Gauss-Newton-like)."""
        _, grad, u, beta, ge = self._parts(z)
        h = 0.5 * self.funcs.hessian(z, exact=exact, point_weights=u)
        h += 0.5 * (0.5 * self.p - 1.0) * ((ge * beta) @ ge.T)
        h -= self.p * np.outer(grad, grad)
        h = (h + h.T) / 2.0
        if clip:
            lam, vec = np.linalg.eigh(h)
            h = (vec * np.maximum(lam, 0.0)) @ vec.T
            h = (h + h.T) / 2.0
        return h


def _as_slice(idx):
    """A slice for a run of consecutive indices (a view when indexing), else the list."""
    if idx and list(idx) == list(range(idx[0], idx[-1] + 1)):
        return slice(idx[0], idx[-1] + 1)
    return list(idx)


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
    """Build the :class:`StageFunctions` of one stage (once per stage)."""
    return StageFunctions(param, omega, response, weights, derivatives)
