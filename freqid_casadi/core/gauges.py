"""The section gauges of the stage variables, one small object per gauge x basis (layer L2).

A gauge says how a section ``num/den`` is written in the optimiser's variables ``v`` (see
:mod:`freqid_casadi.core.objective` for the three gauges "dc", "b1" and "raw"). Each object
gives the section's variable count, its initial variables, its (re, im) numerator and
denominator at a scaled frequency ``x = w/wr`` (numpy or CasADi), and the maps to and from
the thesis's parameters; :func:`gauge_for` picks one. The formulas are written once here,
so :class:`~freqid_casadi.core.objective.Parametrization` has no gauge branches.
"""

import numpy as np

from ..errors import OptionError, StructureError

__all__ = ["GAUGES", "CHARTS", "Gauge", "gauge_for", "dc_to_thesis"]

#: The gauges of :class:`~freqid_casadi.core.objective.Parametrization`.
GAUGES = ("dc", "b1", "raw")
#: The charts of a dc-gauge quadratic factor: 0 unit constant ``1 + c1 x + c2 x^2``,
#: 1 monic ``c0 + c1 x + x^2``, 2 unit linear coefficient ``c0 + x + c2 x^2`` (see
#: :class:`_DC`).
CHARTS = (0, 1, 2)


class Gauge:
    """One gauge for one basis (subclasses per gauge family).

    Parameters
    ----------
    name : {"dc", "b1", "raw"}
    second : bool
        Second-order basis (else first-order).
    """

    sizes = {}

    def __init__(self, name, second):
        self.name = name
        self.second = second
        self.size = self.sizes[second]

    def new_section(self, omega_num, zeta_num, omega_den, zeta_den, wr, scale_l):
        """Variables of a section with the given natural frequencies (rad/s) and dampings
        at reference ``wr``; ``scale_l`` scales num and den together ("raw" only)."""
        raise NotImplementedError

    def pairs(self, v, x, chart=(0, 0)):
        """(num, den) (re, im) pairs of the section ``v`` at scaled frequency ``x``
        (``chart``: the factors' charts, dc gauge only)."""
        raise NotImplementedError

    def to_thesis(self, v, wr, chart=(0, 0)):
        """(thesis parameters of the section, factor of the gain or None)."""
        raise NotImplementedError

    def from_thesis(self, theta, wr, k, chart=(0, 0)):
        """(variables of the thesis section ``theta``, factor of the gain or None)."""
        raise NotImplementedError


def dc_to_thesis(c2, c1, wr):
    """Thesis form (a, zeta, omega) and scale s of ``1 + c1 (s/wr) + c2 (s/wr)^2``:
    the factor equals ``(a s^2 + 2 zeta omega s + omega^2) / s`` with ``s = omega^2``
    (``a = -1`` for ``c2 < 0``, real roots of opposite signs: free numerators only).

    Parameters
    ----------
    c2, c1 : float
        The factor's coefficients (dc gauge).
    wr : float
        Its reference frequency (rad/s).

    Returns
    -------
    (float, float, float, float)
        ``a, zeta, omega, scale``.
    """
    if c2 != 0:       # c2 < 0 only for free zeros: a = -1, real roots of opposite signs
        omega = wr / np.sqrt(abs(c2))
        return float(np.sign(c2)), c1 / (2 * np.sqrt(abs(c2))), omega, omega * omega
    # zero at infinity: a = 0, omega = wr -> factor (2 zeta wr s + wr^2)/wr^2
    return 0.0, c1 / 2.0, wr, wr * wr


def _quadratic(a, b, chart, x, x2):
    """(re, im) at ``j x`` of a factor in chart ``chart`` (:data:`CHARTS`) with slot
    variables ``(a, b)``: ``1 + b x + a x^2``, ``a + b x + x^2`` or ``b + x + a x^2``;
    affine in ``(a, b)``. ``chart`` is a number or an array of charts (one per row)."""
    if np.isscalar(chart):
        if chart == 1:
            return a - x2, b * x
        if chart == 2:
            return b - a * x2, x + 0 * b
        return 1 - a * x2, b * x
    m1, m2 = (chart == 1) * 1.0, (chart == 2) * 1.0
    m0 = 1.0 - m1 - m2
    return (m0 * (1 - a * x2) + m1 * (a - x2) + m2 * (b - a * x2),
            (m0 + m1) * b * x + m2 * x)


def _chart_to_thesis(a, b, chart, wr):
    """Thesis form and scale (:func:`dc_to_thesis`) of a factor in chart ``chart``: the
    monic ``c0 + c1 x + x^2`` is ``c0 (1 + (c1/c0) x + (1/c0) x^2)`` and the unit-linear
    ``c0 + x + c2 x^2`` is ``c0 (1 + (1/c0) x + (c2/c0) x^2)``."""
    if chart == 1:
        a_, zeta, omega, scale = dc_to_thesis(1.0 / a, b / a, wr)
        return a_, zeta, omega, scale / a
    if chart == 2:
        a_, zeta, omega, scale = dc_to_thesis(a / b, 1.0 / b, wr)
        return a_, zeta, omega, scale / b
    return dc_to_thesis(a, b, wr)


def _chart_from_thesis(a, zeta, omega, chart, wr):
    """(the factor's slot variables, s) with ``a s^2 + 2 zeta omega s + omega^2`` equal to
    ``s`` times the factor in chart ``chart`` (``omega > 0``; chart 1 needs ``a > 0``,
    chart 2 ``zeta > 0``)."""
    c2, c1 = a * wr ** 2 / omega ** 2, 2 * zeta * wr / omega
    if chart == 1:
        return [1.0 / c2, c1 / c2], omega ** 2 * c2
    if chart == 2:
        return [c2 / c1, 1.0 / c1], omega ** 2 * c1
    return [c2, c1], omega ** 2


class _DC(Gauge):
    """Unit-DC factors ``1 + c1 x + c2 x^2`` (``1 + c1 x`` first-order); gain in K.

    A second-order factor may instead be written in another chart of the same quadratic
    (its slot variables ``(a, b)`` in the places of ``(c2, c1)``): the *monic* chart 1,
    ``c0 + c1 x + x^2`` with ``(a, b) = (c0, c1)``, and the *unit-linear* chart 2,
    ``c0 + x + c2 x^2`` with ``(a, b) = (c2, c0)``. The unit-DC chart reaches roots
    leaving the band upwards (``c2 -> 0``) and undamped roots (``c1 -> 0``) at finite
    variables, but a root tending to 0 (an integrator) only at infinite coefficients and
    gain, an infimum no solver reaches; the monic chart reaches roots tending to 0
    (``c0 -> 0``) and undamped roots, the unit-linear chart one root tending to 0 and the
    other to infinity (``c0, c2 -> 0``). :func:`~freqid_casadi.fitting.stages.choose_charts` picks
    them. Nonnegative variables are again "roots in the closed left half plane"; the
    damping ratio is ``b / (2 sqrt(a))`` in charts 0 and 1 (the damping floor's formula,
    slot for slot) and ``1 / (2 sqrt(a b))`` in chart 2.
    """

    sizes = {True: 4, False: 2}

    def new_section(self, omega_num, zeta_num, omega_den, zeta_den, wr, scale_l):
        if self.second:
            return np.array([(wr / omega_num) ** 2, 2 * zeta_num * wr / omega_num,
                             (wr / omega_den) ** 2, 2 * zeta_den * wr / omega_den])
        return np.array([wr / omega_num, wr / omega_den])

    def pairs(self, v, x, chart=(0, 0)):
        """(num, den) (re, im) pairs; ``chart`` (num, den) as in :data:`CHARTS` (0 or 1,
        floats or arrays broadcasting with ``x``; second-order basis only)."""
        if self.second:
            p2, p1, q2, q1 = v
            x2 = x * x
            return _quadratic(p2, p1, chart[0], x, x2), _quadratic(q2, q1, chart[1], x, x2)
        p1, q1 = v
        return (1 + 0 * x, p1 * x), (1 + 0 * x, q1 * x)

    def to_thesis(self, v, wr, chart=(0, 0)):
        if self.second:
            p2, p1, q2, q1 = v
            a, zn, wn, sn = _chart_to_thesis(p2, p1, chart[0], wr)
            b, zd, wd, sd = _chart_to_thesis(q2, q1, chart[1], wr)
            return [a, zn, wn, b, zd, wd], sd / sn
        p1, q1 = v
        return [p1 / wr, 1.0, q1 / wr, 1.0], None

    def from_thesis(self, theta, wr, k, chart=(0, 0)):
        if self.second:
            a, zn, wn, b, zd, wd = theta
            if wn <= 0 or wd <= 0:
                raise StructureError(f"section {k + 1} has a root at s=0 (omega=0); not "
                                     "representable in the dc gauge")
            num, sn = _chart_from_thesis(a, zn, wn, chart[0], wr)
            den, sd = _chart_from_thesis(b, zd, wd, chart[1], wr)
            return num + den, sn / sd
        a1, a0, b1, b0 = theta
        if a0 <= 0 or b0 <= 0:
            raise StructureError(f"section {k + 1} has a root at s=0")
        return [a1 / a0 * wr, b1 / b0 * wr], a0 / b0


class _Polynomial(Gauge):
    """The thesis's polynomial sections, all free ("raw") or with ``b = 1`` ("b1")."""

    sizes = {True: 6, False: 4}

    def __init__(self, name, second):
        super().__init__(name, second)
        self.raw = name == "raw"
        if not self.raw:
            self.size -= 1

    def _full(self, v):
        """The section's thesis coefficients with ``b`` (``b0``) = 1 filled in for "b1"."""
        if self.raw:
            return list(v)
        if self.second:
            a, zn, wn, zd, wd = v
            return [a, zn, wn, 1.0, zd, wd]
        a1, a0, b1 = v
        return [a1, a0, b1, 1.0]

    def new_section(self, omega_num, zeta_num, omega_den, zeta_den, wr, scale_l):
        if self.second:
            sec = [1.0, zeta_num, omega_num / wr, 1.0, zeta_den, omega_den / wr]
            if self.raw:
                rl = np.sqrt(scale_l)
                return np.array([scale_l, rl * sec[1], rl * sec[2],
                                 scale_l, rl * sec[4], rl * sec[5]])
            return np.array(sec[:3] + sec[4:])
        sec = [wr / omega_num, 1.0, wr / omega_den, 1.0]
        if self.raw:
            return scale_l * np.array(sec)
        return np.array(sec[:3])

    def pairs(self, v, x, chart=(0, 0)):
        if self.second:
            a, zn, wn, b, zd, wd = self._full(v)
            x2 = x * x
            return (wn * wn - a * x2, 2 * zn * wn * x), (wd * wd - b * x2, 2 * zd * wd * x)
        a1, a0, b1, b0 = self._full(v)
        return (a0 + 0 * x, a1 * x), (b0 + 0 * x, b1 * x)

    def to_thesis(self, v, wr, chart=(0, 0)):
        if self.second:
            a, zn, wn, b, zd, wd = self._full(v)
            return [a, zn, wn * wr, b, zd, wd * wr], None
        a1, a0, b1, b0 = self._full(v)
        return [a1 / wr, a0, b1 / wr, b0], None

    def from_thesis(self, theta, wr, k, chart=(0, 0)):
        if self.second:
            a, zn, wn, b, zd, wd = theta
            if self.raw:
                return [a, zn, wn / wr, b, zd, wd / wr], None
            if b <= 0:
                raise StructureError(f"section {k + 1} has b=0; not representable with b=1")
            # divide num and den by b: a/b, zeta/sqrt(b), omega/sqrt(b)
            sb = np.sqrt(b)
            return [a / b, zn / sb, wn / sb / wr, zd / sb, wd / sb / wr], None
        a1, a0, b1, b0 = theta
        if self.raw:
            return [a1 * wr, a0, b1 * wr, b0], None
        return [a1 / b0 * wr, a0 / b0, b1 / b0 * wr], None


def gauge_for(name, basis):
    """The :class:`Gauge` object of gauge ``name`` and ``basis``.

    Parameters
    ----------
    name : {"dc", "b1", "raw"}
    basis : {"second-order", "first-order"}

    Returns
    -------
    Gauge

    Raises
    ------
    OptionError
        Unknown gauge.
    """
    if name not in GAUGES:
        raise OptionError(f"unknown gauge {name!r}; choose one of {', '.join(GAUGES)}")
    second = basis == "second-order"
    return _DC(name, second) if name == "dc" else _Polynomial(name, second)
