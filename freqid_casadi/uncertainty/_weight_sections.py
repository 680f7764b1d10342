"""The sections of the uncertainty weight W(s) and their responses (layer L2): unit-DC
first- and second-order factors, evaluated in numpy or CasADi from the normalised frequency
(:mod:`~freqid_casadi.uncertainty.weight` fits them).
"""

from dataclasses import dataclass

import numpy as np

from .. import _cplx

__all__ = ["WeightSection", "MAX_DAMPING"]


MAX_DAMPING = 20.0
"""Upper bound of every damping: real roots up to a ratio of ~1600 (3.2 decades) apart."""


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


# ---------------------------------------------------------------------------- sections
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
