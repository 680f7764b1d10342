"""The section gauges of the stage variables, one small object per gauge x basis (layer L2).

A gauge says how a section ``num/den`` is written in the optimiser's variables ``v`` (see
:mod:`freqid_casadi.objective` for the three gauges "dc", "b1" and "raw"). Each object
gives the section's variable count, its initial variables, its (re, im) numerator and
denominator at a scaled frequency ``x = w/wr`` (numpy or CasADi), and the maps to and from
the thesis's parameters; :func:`gauge_for` picks one. The formulas are written once here,
so :class:`~freqid_casadi.objective.Parametrization` has no gauge branches.
"""

import numpy as np

from .errors import OptionError, StructureError

__all__ = ["GAUGES", "Gauge", "gauge_for", "dc_to_thesis"]

#: The gauges of :class:`~freqid_casadi.objective.Parametrization`.
GAUGES = ("dc", "b1", "raw")


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

    def pairs(self, v, x):
        """(num, den) (re, im) pairs of the section ``v`` at scaled frequency ``x``."""
        raise NotImplementedError

    def to_thesis(self, v, wr):
        """(thesis parameters of the section, factor of the gain or None)."""
        raise NotImplementedError

    def from_thesis(self, theta, wr, k):
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


class _DC(Gauge):
    """Unit-DC factors ``1 + c1 x + c2 x^2`` (``1 + c1 x`` first-order); gain in K."""

    sizes = {True: 4, False: 2}

    def new_section(self, omega_num, zeta_num, omega_den, zeta_den, wr, scale_l):
        if self.second:
            return np.array([(wr / omega_num) ** 2, 2 * zeta_num * wr / omega_num,
                             (wr / omega_den) ** 2, 2 * zeta_den * wr / omega_den])
        return np.array([wr / omega_num, wr / omega_den])

    def pairs(self, v, x):
        if self.second:
            p2, p1, q2, q1 = v
            x2 = x * x
            return (1 - p2 * x2, p1 * x), (1 - q2 * x2, q1 * x)
        p1, q1 = v
        return (1 + 0 * x, p1 * x), (1 + 0 * x, q1 * x)

    def to_thesis(self, v, wr):
        if self.second:
            p2, p1, q2, q1 = v
            a, zn, wn, sn = dc_to_thesis(p2, p1, wr)
            b, zd, wd, sd = dc_to_thesis(q2, q1, wr)
            return [a, zn, wn, b, zd, wd], sd / sn
        p1, q1 = v
        return [p1 / wr, 1.0, q1 / wr, 1.0], None

    def from_thesis(self, theta, wr, k):
        if self.second:
            a, zn, wn, b, zd, wd = theta
            if wn <= 0 or wd <= 0:
                raise StructureError(f"section {k + 1} has a root at s=0 (omega=0); not "
                                     "representable in the dc gauge")
            return ([a * wr ** 2 / wn ** 2, 2 * zn * wr / wn, b * wr ** 2 / wd ** 2,
                     2 * zd * wr / wd], wn ** 2 / wd ** 2)
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

    def pairs(self, v, x):
        if self.second:
            a, zn, wn, b, zd, wd = self._full(v)
            x2 = x * x
            return (wn * wn - a * x2, 2 * zn * wn * x), (wd * wd - b * x2, 2 * zd * wd * x)
        a1, a0, b1, b0 = self._full(v)
        return (a0 + 0 * x, a1 * x), (b0 + 0 * x, b1 * x)

    def to_thesis(self, v, wr):
        if self.second:
            a, zn, wn, b, zd, wd = self._full(v)
            return [a, zn, wn * wr, b, zd, wd * wr], None
        a1, a0, b1, b0 = self._full(v)
        return [a1 / wr, a0, b1 / wr, b0], None

    def from_thesis(self, theta, wr, k):
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
