"""The relative-error objective, written once for numpy and CasADi (layer L2).

The fitted quantity is the relative residual (SPEC §1)::

    r_i = Phi_i / G_N(j w_i; beta) - 1,      eps(beta) = sum_i w_i |r_i|^2

built as ``Phi * exp(+j w h) * [j w] / K * prod_k den_k / num_k - 1`` with only +-x/ on
(re, im) pairs (docs/style.md §1.2), so the same code evaluates on numpy arrays and on CasADi
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
    A polish writes overdamped factors in other charts of the same quadratic (monic
    ``c0 + c1 x + x^2``, unit-linear ``c0 + x + c2 x^2``; ``charts``,
    :func:`~freqid_casadi.fitting.stages.choose_charts`): there a root leaving the band downwards
    is at finite variables, on the bound ``root_floor``.
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

from .. import _cplx
from .derivatives import PNormFunctions, StageFunctions, stage_functions
from ..errors import OptionError, StructureError
from .gauges import GAUGES, gauge_for
from .metrics import error_stats
from .model import RationalDelayModel, Structure

__all__ = ["GAUGES", "Parametrization", "relative_residual", "rel_error_stats",
           "stage_functions", "StageFunctions", "PNormFunctions"]


def relative_residual(model, omega, response):
    """Complex relative residual ``Phi/G_N - 1`` of a model at the data.

    Parameters
    ----------
    model : RationalDelayModel
    omega : ndarray of float, shape (M,)
        rad/s.
    response : ndarray of complex, shape (M,)

    Returns
    -------
    ndarray of complex, shape (M,)
    """
    return np.asarray(response) / model.frequency_response(omega) - 1.0


def rel_error_stats(rel_error):
    """(max, rms) of |relative error| values (:func:`~freqid_casadi.core.metrics.error_stats`).

    Parameters
    ----------
    rel_error : array_like of float, shape (M,)

    Returns
    -------
    (float, float)
    """
    stats = error_stats(rel_error)
    return stats.max, stats.rms


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
    charts : tuple of (int, int), optional
        Per section, the charts (:data:`~freqid_casadi.core.gauges.CHARTS`) of its numerator
        and denominator: 0 the unit-DC factor ``1 + c1 x + c2 x^2``, 1 the monic factor
        ``c0 + c1 x + x^2``, 2 the unit-linear factor ``c0 + x + c2 x^2`` (dc gauge,
        second-order basis, minimum-phase zeros; no damping floor with chart 2); empty:
        all 0.
    root_floor : float
        Lower bound (rad/s, >= 0) of the natural frequency ``wr sqrt(c0)`` of every monic
        factor and of ``wr c0`` (below its smaller root) of every unit-linear one: a root
        at 0 (an integrator, or a differentiator in a numerator) stays out of the model
        class by this margin (0: no bound).
    """

    structure: Structure
    gauge: str = "dc"
    omega_ref: tuple = ()
    gain_ref: float = 1.0
    delay_max: float = 1.0
    scaled: bool = True
    charts: tuple = ()
    root_floor: float = 0.0

    def __post_init__(self):
        gauge_for(self.gauge, self.structure.basis)          # OptionError if unknown
        if len(self.omega_ref) != self.structure.n_sections:
            raise StructureError(
                f"omega_ref needs one frequency per section: got {len(self.omega_ref)} for "
                f"{self.structure.n_sections} sections")
        object.__setattr__(self, "omega_ref", tuple(float(w) for w in self.omega_ref))
        if not (np.isfinite(self.delay_max) and self.delay_max > 0):
            raise OptionError(f"delay_max must be a finite number > 0 (s), got {self.delay_max}")
        _check_charts(self)

    # ---------------------------------------------------------------- layout
    @property
    def gauge_obj(self):
        """The :class:`~freqid_casadi.core.gauges.Gauge` of this gauge and basis."""
        return gauge_for(self.gauge, self.structure.basis)

    @property
    def section_size(self):
        return self.gauge_obj.size

    @property
    def n_vars(self):
        return 2 + self.section_size * self.structure.n_sections

    def _refs(self):
        if self.scaled:
            return self.delay_max, self.gain_ref, self.omega_ref
        return 1.0, 1.0, (1.0,) * self.structure.n_sections

    def free_mask(self):
        """Boolean mask, shape (n_vars,), of the variables without a lower bound: the
        numerator variables of every section when ``structure.zeros == "free"`` (dc
        gauge: any real ``1 + c1 x + c2 x^2`` / ``1 + c1 x``, zeros anywhere)."""
        mask = np.zeros(self.n_vars, bool)
        if self.structure.zeros == "free":
            if self.gauge != "dc":
                raise OptionError(f"zeros='free' needs the 'dc' gauge, got {self.gauge!r}")
            ns = self.section_size
            for k in range(self.structure.n_sections):
                mask[2 + ns * k: 2 + ns * k + ns // 2] = True
        return mask

    def bounds(self):
        """(lb, ub) arrays of shape (n_vars,): z >= 0 (numerators free with
        ``zeros="free"``), delay <= delay_max, h = 0 if no delay."""
        lb = np.where(self.free_mask(), -np.inf, 0.0)
        ub = np.full(self.n_vars, np.inf)
        h_ref, _, wr = self._refs()
        ub[0] = (self.delay_max / h_ref) if self.structure.delay else 0.0
        for k, chart in enumerate(self.charts):
            for j in (0, 1):
                e = self.root_floor / wr[k]
                if chart[j] == 1:      # c0 of a monic factor: natural frequency >= floor
                    lb[2 + 4 * k + 2 * j] = e * e
                elif chart[j] == 2:    # c0 of a unit-linear factor: smaller root >= floor
                    lb[2 + 4 * k + 2 * j + 1] = e
        return lb, ub

    def chart(self, k):
        """The (numerator, denominator) charts of section ``k`` (see ``charts``)."""
        return self.charts[k] if self.charts else (0, 0)

    def extend(self, omega_ref_new):
        """The parametrization with one more section at reference ``omega_ref_new``."""
        charts = self.charts + ((0, 0),) if self.charts else ()
        return Parametrization(self.structure.with_sections(self.structure.n_sections + 1),
                               self.gauge, self.omega_ref + (float(omega_ref_new),),
                               self.gain_ref, self.delay_max, self.scaled, charts,
                               self.root_floor)

    def new_section(self, omega_num, zeta_num, omega_den, zeta_den, omega_ref, scale_l=1.0):
        """Variables of a section to append at reference ``omega_ref`` (rad/s) whose
        numerator/denominator have the given natural frequencies (rad/s) and dampings.

        ``scale_l`` multiplies num and den together (a -> l a, zeta -> sqrt(l) zeta,
        omega -> sqrt(l) omega; the thesis's initial point); it leaves the section unchanged
        and only matters in the "raw" gauge.
        """
        wr = float(omega_ref) if self.scaled else 1.0
        return self.gauge_obj.new_section(omega_num, zeta_num, omega_den, zeta_den, wr,
                                          scale_l)

    # ---------------------------------------------------------------- formula
    def _sections(self, z, wr):
        """Yield (num, den) (re, im)-pair builders per section as functions of w."""
        n = self.section_size
        for k in range(self.structure.n_sections):
            v = [z[2 + n * k + i] for i in range(n)]
            yield k, v, wr[k], self.chart(k)

    def ratio(self, z, omega, response_pair, refs=None):
        """Phi / G_N(j w) as an (re, im) pair; numpy or CasADi.

        Parameters
        ----------
        z : sequence of length n_vars (numpy array or CasADi SX/MX vector)
        omega : float or ndarray, rad/s
        response_pair : (re, im) of Phi at omega
        refs : (h_ref, k_ref, wr), optional
            The references (delay, gain, each section's frequency); None: this
            parametrization's. CasADi symbols make a formula for every parametrization of
            this structure (:func:`~freqid_casadi.core.derivatives.residual_template`).
        """
        h_ref, k_ref, wr = self._refs() if refs is None else refs
        h = h_ref * z[0]
        gain = k_ref * z[1]
        cos, sin = _trig(z)
        q = _cplx.mul(response_pair, (cos(omega * h), sin(omega * h)))
        k = self.structure.origin_order
        if k == 1:
            q = _cplx.mul(q, (0 * omega, omega))
        elif k:                                  # times (j omega)^k: k poles at 0 removed
            for _ in range(abs(k)):
                q = (_cplx.mul if k > 0 else _cplx.div)(q, (0 * omega, omega))
        q = (q[0] / gain, q[1] / gain)
        gauge = self.gauge_obj
        for k, v, w_k, chart in self._sections(z, wr):
            num, den = gauge.pairs(v, omega / w_k, chart)
            q = _cplx.mul(q, _cplx.div(den, num))
        return q

    def residual_pair(self, z, omega, response_pair, sqrt_weights=None, refs=None):
        """Weighted (re, im) residual of ``Phi/G_N - 1`` (``refs``: as :meth:`ratio`)."""
        re, im = self.ratio(z, omega, response_pair, refs)
        re = re - 1.0
        if sqrt_weights is not None:
            re, im = re * sqrt_weights, im * sqrt_weights
        return re, im

    # ---------------------------------------------------------------- damping floor
    def damping_pairs(self):
        """Indices ``(i2, i1)`` of each quadratic's ``(c2, c1)`` variables (dc gauge,
        second-order basis): two per section, numerator then denominator."""
        if any(2 in c for c in self.charts):
            raise OptionError("a damping floor needs charts 0 and 1 (not the unit-linear 2)")
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
        """Thesis parameters ``beta`` (numpy; >= 0 but for free numerators) of ``z``."""
        z = np.asarray(z, float)
        z = np.where(self.free_mask(), z, np.maximum(z, 0.0))
        h_ref, k_ref, wr_all = self._refs()
        h = h_ref * z[0] if self.structure.delay else 0.0
        gain = k_ref * z[1]
        secs = []
        gauge = self.gauge_obj
        for k, v, wr, chart in self._sections(z, wr_all):
            theta, factor = gauge.to_thesis(v, wr, chart)
            if factor is not None:
                gain *= factor
            secs += theta
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
        gauge = self.gauge_obj
        for k in range(self.structure.n_sections):
            theta, factor = gauge.from_thesis(beta[2 + ss * k: 2 + ss * (k + 1)], wr_all[k], k,
                                              self.chart(k))
            if factor is not None:
                gain *= factor
            z += theta
        z[1] = gain / k_ref
        return np.array(z, float)


def _check_charts(param):
    """StructureError/OptionError unless ``param.charts`` and ``param.root_floor`` fit."""
    if not (np.isfinite(param.root_floor) and param.root_floor >= 0):
        raise OptionError(f"root_floor must be a finite number >= 0 (rad/s), got "
                          f"{param.root_floor}")
    charts = tuple(tuple(int(c) for c in ch) for ch in param.charts)
    object.__setattr__(param, "charts", charts)
    if not charts:
        return
    st = param.structure
    if len(charts) != st.n_sections or any(len(c) != 2 or set(c) - {0, 1, 2} for c in charts):
        raise StructureError(f"charts needs one (numerator, denominator) pair of 0/1/2 per "
                             f"section ({st.n_sections}), got {charts}")
    if any(map(any, charts)) and (param.gauge != "dc" or st.basis != "second-order"
                                  or st.zeros != "minimum-phase"):
        raise OptionError("charts other than 0 need the 'dc' gauge, the second-order basis "
                          "and minimum-phase zeros")


def _trig(z):
    """cos/sin that work for numpy and for CasADi symbols."""
    if isinstance(z, np.ndarray) or isinstance(z, (list, tuple)):
        return np.cos, np.sin
    import casadi as ca

    return ca.cos, ca.sin
