"""Result types and section formulas of :mod:`freqid_casadi.uncertainty.weight` (layer L4).

The weight ``W(s) = k prod_i (1 + 2 zeta_z s/w_z + (s/w_z)^2)/(1 + 2 zeta_p s/w_p +
(s/w_p)^2)`` (first-order sections for odd orders), its sections and its fit record; see
:mod:`freqid_casadi.uncertainty.weight` for the method.
"""

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import _cplx
from ..core.model import balanced_ss
from ..errors import DataError
from ..solvers.common import Status

__all__ = ["WeightSection", "WeightResult", "Overbound", "MAX_DAMPING", "CORNER_DECADES",
           "E_FLOOR", "MAX_DECADES", "frequency_scale", "rescaled"]

MAX_DAMPING = 20.0
"""Upper bound of every damping: real roots up to a ratio of ~1600 (3.2 decades) apart."""

CORNER_DECADES = 2.0
"""Corner frequencies are bounded to the data range widened by this many decades each side."""

E_FLOOR = 1e-16
"""Relative floor of ``e`` before logs: ``e_i >= E_FLOOR * max(e)``."""

MAX_DECADES = 100
"""Widest omega band of a weight fit, decades (``|W|`` squares the frequency)."""

_LN10 = math.log(10.0)
_GRID_PER_DECADE = 3      # ladder grid search over corner frequencies


# ---------------------------------------------------------------------------- formulas
def _factor(y, zeta):
    """(re, im) of ``1 + 2 zeta (s/w) + (s/w)^2`` (or ``1 + s/w`` if zeta is None) at
    ``s = j w y``, i.e. at the normalised frequency ``y = omega / w``. numpy or CasADi."""
    if zeta is None:
        return (1.0 + 0 * y, y)
    return (1.0 - y * y, 2 * zeta * y)


def _section_log_abs2(y_num, zeta_num, y_den, zeta_den, log):
    """``ln|S(j omega)|^2`` of one section from its normalised frequencies (numpy or SX)."""
    return (log(_cplx.abs2(_factor(y_num, zeta_num)))
            - log(_cplx.abs2(_factor(y_den, zeta_den))))


def _section_pair(y_num, zeta_num, y_den, zeta_den):
    """``S(j omega)`` of one section as an (re, im) pair."""
    return _cplx.div(_factor(y_num, zeta_num), _factor(y_den, zeta_den))


def _quad_or_linear_roots(w, zeta):
    """Roots of ``1 + 2 zeta s/w + (s/w)^2`` (or ``1 + s/w``), complex list."""
    if zeta is None:
        return [complex(-w)]
    return list(np.roots([1.0, 2.0 * zeta * w, w * w]).astype(complex))


# ---------------------------------------------------------------------------- results
@dataclass(frozen=True)
class WeightSection:
    """One unit-DC section of the weight.

    Attributes
    ----------
    omega_num, omega_den : float
        Corner (natural) frequencies of numerator and denominator, rad/s, > 0.
    zeta_num, zeta_den : float or None
        Dampings (> 0) of a second-order section; None for a first-order section
        ``(1 + s/omega_num) / (1 + s/omega_den)``.
    """

    omega_num: float
    omega_den: float
    zeta_num: float = None
    zeta_den: float = None

    @property
    def order(self):
        """1 (first-order section) or 2."""
        return 1 if self.zeta_num is None else 2

    @property
    def num(self):
        """Numerator coefficients in descending powers of s (constant term 1)."""
        w, z = self.omega_num, self.zeta_num
        return (1.0 / w, 1.0) if z is None else (1.0 / (w * w), 2.0 * z / w, 1.0)

    @property
    def den(self):
        """Denominator coefficients in descending powers of s (constant term 1)."""
        w, z = self.omega_den, self.zeta_den
        return (1.0 / w, 1.0) if z is None else (1.0 / (w * w), 2.0 * z / w, 1.0)

    def frequency_response(self, omega):
        """``S(j omega)``; complex ndarray shaped like ``omega`` (rad/s)."""
        omega = np.asarray(omega, dtype=float)
        return _cplx.to_complex(_section_pair(omega / self.omega_num, self.zeta_num,
                                              omega / self.omega_den, self.zeta_den))

    def zeros(self):
        """Zeros of the section, complex ndarray (1 or 2 entries, real parts < 0)."""
        return np.array(_quad_or_linear_roots(self.omega_num, self.zeta_num), dtype=complex)

    def poles(self):
        """Poles of the section, complex ndarray (1 or 2 entries, real parts < 0)."""
        return np.array(_quad_or_linear_roots(self.omega_den, self.zeta_den), dtype=complex)


class Overbound(NamedTuple):
    """How far ``|W|`` lies above ``e`` at the data points, ``20 log10(|W(j w_i)| / e_i)``.

    Points where ``e`` was floored (zeros) are left out.

    Attributes
    ----------
    mean_db, max_db, min_db : float
        Mean, largest and smallest overbound in dB; ``min_db >= 20 log10(1 + margin)``.
    """

    mean_db: float
    max_db: float
    min_db: float


@dataclass(frozen=True, eq=False)
class WeightResult:
    """Result of :func:`fit_uncertainty_weight`.

    Attributes
    ----------
    omega : ndarray of float, shape (M,)
        Data frequencies, rad/s.
    rel_error : ndarray of float, shape (M,)
        The bounded relative error ``e_i`` (as given, not floored).
    magnitude : ndarray of float, shape (M,)
        ``|W(j omega_i)|``; ``>= (1 + margin) * rel_error`` at every point.
    gain : float
        ``k = W(0)`` (every section has unit DC gain), > 0.
    sections : tuple of WeightSection
        Second-order sections first, then the first-order one (odd order).
    order : int
        McMillan degree of ``W``.
    overbound : Overbound
        Mean / max / min of ``20 log10(|W|/e)`` dB over the data.
    margin : float
        The requested relative margin.
    gain_correction : float
        Factor (>= 1) by which the gain was raised after IPOPT so the bound holds exactly;
        1.0 when IPOPT's point was already feasible.
    objective : float
        Mean of ``ln|W(j w_i)| - ln((1 + margin) e_i)`` (nepers) at the returned weight.
    status : Status
        Of the IPOPT solve that produced the weight (CONVERGED for order 0, closed form).
    message : str
    success : bool
        ``status`` is a success status. The bound holds even when False.
    nit : int
        IPOPT iterations summed over all solves.

    Notes
    -----
    To plot: ``|W(j w)|`` from :meth:`frequency_response` on a dense grid against the
    markers ``rel_error`` (log-log), plus ``20 log10(magnitude / rel_error)`` in dB.
    """

    omega: np.ndarray
    rel_error: np.ndarray
    magnitude: np.ndarray
    gain: float
    sections: tuple
    order: int
    overbound: Overbound
    margin: float
    gain_correction: float
    objective: float
    status: Status
    message: str
    success: bool
    nit: int

    def frequency_response(self, omega):
        """``W(j omega)``.

        Parameters
        ----------
        omega : array_like of float, shape (K,)
            Frequencies in rad/s.

        Returns
        -------
        ndarray of complex, shape (K,)
        """
        return _response(self.gain, self.sections, omega)

    def poles(self):
        """Poles of ``W``, complex ndarray, shape (order,)."""
        p = [r for sec in self.sections for r in sec.poles()]
        return np.array(p, dtype=complex)

    def zeros(self):
        """Zeros of ``W``, complex ndarray, shape (order,)."""
        z = [r for sec in self.sections for r in sec.zeros()]
        return np.array(z, dtype=complex)

    def is_stable(self):
        """True if every pole has a negative real part (always, by the bounds)."""
        return bool(np.all(self.poles().real < 0))

    def is_minimum_phase(self):
        """True if every zero has a negative real part (always, by the bounds)."""
        return bool(np.all(self.zeros().real < 0))

    def to_control(self):
        """``W`` as a python-control ``StateSpace`` (sections realised and put in series).

        Returns
        -------
        control.StateSpace
            Proper, stable and minimum phase, with ``order`` states; pass it as a weight to
            ``control.mixsyn`` / ``control.augw`` (``control.tf(sys)`` gives the transfer
            function).
        """
        import control as ct

        sys = ct.ss([], [], [], [[self.gain]])
        for sec in self.sections:
            sys = ct.series(sys, ct.ss(ct.tf(list(sec.num), list(sec.den))))
        return balanced_ss(sys)


def _response(gain, sections, omega):
    """``W(j omega)`` as a complex ndarray (the one evaluation users see)."""
    omega = np.asarray(omega, dtype=float)
    z = (gain + 0 * omega, 0 * omega)
    for sec in sections:
        z = _cplx.mul(z, _section_pair(omega / sec.omega_num, sec.zeta_num,
                                       omega / sec.omega_den, sec.zeta_den))
    return _cplx.to_complex(z)


def _real_pair_section(r1, r2):
    """(omega, zeta) of ``(1 + s/r1)(1 + s/r2)``; zeta clipped to MAX_DAMPING."""
    w = np.sqrt(r1 * r2)
    return w, np.minimum((r1 + r2) / (2.0 * w), MAX_DAMPING)


# ---------------------------------------------------------------------------- scaling
def frequency_scale(omega):
    """Frequency (rad/s) to divide ``omega`` by before the fit: 1, or, far from 1 rad/s
    (where squares of omega over/underflow), the geometric mean of its ends (the problem
    is scale-free; :func:`rescaled` maps the sections back).

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s, > 0, increasing.

    Returns
    -------
    float

    Raises
    ------
    DataError
        If ``omega`` spans more than :data:`MAX_DECADES` decades.
    """
    decades = math.log10(omega[-1]) - math.log10(omega[0])
    if decades > MAX_DECADES:
        raise DataError(f"omega spans {decades:.0f} decades ({omega[0]:g} to {omega[-1]:g} "
                        f"rad/s), more than {MAX_DECADES}; fit the weight on a narrower band")
    if 1e-100 <= omega[0] and omega[-1] <= 1e100:
        return 1.0
    return math.exp(0.5 * (math.log(omega[0]) + math.log(omega[-1])))


def rescaled(sections, scale):
    """``sections`` (WeightSection) with corner frequencies multiplied by ``scale``.

    Parameters
    ----------
    sections : iterable of WeightSection
    scale : float

    Returns
    -------
    tuple of WeightSection
    """
    return tuple(dataclasses.replace(x, omega_num=x.omega_num * scale,
                                     omega_den=x.omega_den * scale) for x in sections)
