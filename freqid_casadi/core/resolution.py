"""Is a model resolved by its data's frequency grid? (layer L2)

A least-squares fit of noisy data can spend sections on near-cancelling pole/zero pairs
whose half-power bandwidth is far narrower than the spacing of the data (damping ratios
``zeta ~ 1e-7`` were measured on example A with 2 % noise). Such a pair bends the response
by up to a factor ``zeta_num / zeta_den`` in a band that falls between two samples: it
lowers the error *at* the samples and is wrong *between* them. :func:`check_resolution`
flags them (:func:`~freqid_casadi.fitting.fit.fit` runs it on every second-order model);
:mod:`freqid_casadi.fitting.validation` removes them. :func:`default_delay_max` and
:func:`resolution_damping` are the delay bound and the damping floor the grid implies.

Definitions (SPEC §1 sections ``(a s^2 + 2 zn wn s + wn^2) / (b s^2 + 2 zd wd s + wd^2)``):
a quadratic ``a s^2 + 2 zeta w s + w^2`` has the natural frequency ``w0 = w / sqrt(a)``,
the damping ratio ``zeta0 = zeta / sqrt(a)`` and the half-power bandwidth ``2 zeta0 w0 =
2 zeta w / a`` (rad/s). It is *resolved* by a grid ``omega`` if that bandwidth is at least
the local spacing ``delta omega`` of the grid at ``w0`` (the width of the grid interval that
contains ``w0``). A zero and a pole (of any sections) are *near-cancelling* when
``|w0_num - w0_den|`` is below the local spacing (or the smaller of the two
bandwidths). Features outside the data band are not flagged (the data says nothing there).
"""

import math
from dataclasses import dataclass

import numpy as np

from .data import frequency_grid
from ..errors import DataError, OptionError
from .model import RationalDelayModel

__all__ = ["Quadratic", "PairFlag", "ResolutionCheck", "check_resolution",
           "default_delay_max", "resolution_damping"]


@dataclass(frozen=True)
class Quadratic:
    """One quadratic factor ``c2 s^2 + 2 zeta w s + w^2`` of a model (a pole or zero pair).

    Attributes
    ----------
    kind : {"zero", "pole"}
    section : int
        Zero-based index of its section (row of ``model.sections()``).
    omega : float
        Natural frequency ``w0 = w / sqrt(c2)``, rad/s.
    zeta : float
        Damping ratio ``zeta0 = zeta / sqrt(c2)``.
    bandwidth : float
        Half-power bandwidth ``2 zeta0 w0``, rad/s.
    spacing : float
        Local spacing of the data grid at ``omega``, rad/s (nan outside the data band).
    """

    kind: str
    section: int
    omega: float
    zeta: float
    bandwidth: float
    spacing: float

    def as_dict(self):
        return dict(self.__dict__)


@dataclass(frozen=True)
class PairFlag:
    """A near-cancelling zero/pole pair the data cannot resolve.

    Attributes
    ----------
    zero, pole : Quadratic
        The two factors (possibly of different sections); at least one is narrower than
        the spacing, and their natural frequencies differ by less than the larger of the
        two bandwidths and the spacing.
    """

    zero: Quadratic
    pole: Quadratic

    @property
    def sections(self):
        """Sections involved, sorted tuple of int."""
        return tuple(sorted({self.zero.section, self.pole.section}))

    def as_dict(self):
        return {"zero": self.zero.as_dict(), "pole": self.pole.as_dict()}

    def text(self, unit="rad/s"):
        """One line: the zero and the pole (frequencies in ``unit``) and the spacing."""
        return (f"zero {self.zero.omega:.4g} {unit} zeta {self.zero.zeta:.2g} (section "
                f"{self.zero.section}) / pole {self.pole.omega:.4g} {unit} zeta "
                f"{self.pole.zeta:.2g} (section {self.pole.section}), spacing "
                f"{self.pole.spacing:.3g} {unit}")


@dataclass(frozen=True)
class ResolutionCheck:
    """Result of :func:`check_resolution`.

    Attributes
    ----------
    ok : bool
        True when no section is flagged.
    flags : tuple of PairFlag
        Near-cancelling zero/pole pairs of which the pole or the zero is narrower than the
        spacing: features between the samples that the data does not support.
    narrow : tuple of Quadratic
        Other poles or zeros narrower than the spacing, with no zero/pole nearby (a lightly
        damped true resonance or antiresonance, fixed by the samples on its skirts).
        Reported, not flagged unless also in ``unresolved``.
    n_sections : int
        Sections of the checked model.
    factor : float
        A quadratic counts as resolved when its bandwidth is >= ``factor`` x spacing.
    unresolved : tuple of Quadratic
        The members of ``narrow`` whose bandwidth is below ``severe`` x spacing (default
        1 %): their damping is not determined by the data at all (e.g. zeta ~ 1e-11, an
        undamped peak between two samples). They make ``ok`` False; pruning cannot remove
        them (they do not cancel), so refit with fewer sections or other weights.
    """

    ok: bool
    flags: tuple
    narrow: tuple
    n_sections: int
    factor: float
    unresolved: tuple = ()

    @property
    def flagged(self):
        """Sections holding a flagged pole or zero, sorted tuple of int."""
        return tuple(sorted({k for f in self.flags for k in f.sections}))

    def message(self):
        if self.ok:
            return f"the {self.n_sections} sections are resolved by the data"
        parts = []
        if self.flags:
            parts.append(f"{len(self.flags)} near-cancelling zero/pole pair(s) narrower than "
                         "the data spacing: " + "; ".join(f.text() for f in self.flags))
        if self.unresolved:
            parts.append(f"{len(self.unresolved)} pole(s)/zero(s) over 100x narrower than the "
                         "spacing: " + "; ".join(
                             f"{q.kind} {q.omega:.4g} rad/s zeta {q.zeta:.2g} (section "
                             f"{q.section})" for q in self.unresolved))
        return "; ".join(parts)


def _quadratic(c2, zeta, w):
    """(w0, zeta0, bandwidth) of ``c2 s^2 + 2 zeta w s + w^2``; a first-order or constant
    factor (c2 = 0) has no resonance: (inf, inf, inf)."""
    if c2 <= 0 or w <= 0:
        return math.inf, math.inf, math.inf
    sa = math.sqrt(c2)
    return w / sa, zeta / sa, 2.0 * zeta * w / c2


def _local_spacing(omega, w0):
    """Width of the grid interval holding w0 (nan outside the data band)."""
    if not (omega[0] <= w0 <= omega[-1]):
        return math.nan
    i = int(np.clip(np.searchsorted(omega, w0) - 1, 0, omega.size - 2))
    return float(omega[i + 1] - omega[i])


def check_resolution(model, omega, *, factor=1.0, severe=1e-2):
    """Flag sections whose poles or zeros are narrower than the data spacing.

    Parameters
    ----------
    model : RationalDelayModel or FitResult
    omega : array_like of float, shape (M,) or FrequencyData
        The data frequencies (rad/s) the model was fitted to.
    factor : float
        A quadratic is resolved when its half-power bandwidth ``2 zeta0 w0`` is at least
        ``factor`` times the local spacing (default 1).
    severe : float
        A pole or zero (not in a flagged pair) narrower than ``severe`` x spacing is
        ``unresolved`` and fails the check (default 0.01).

    Returns
    -------
    ResolutionCheck

    Raises
    ------
    DataError
        Bad ``omega``.
    OptionError
        Bad ``factor`` or a model that is not a second-order-basis RationalDelayModel.

    Notes
    -----
    See the module docstring. A zero and a pole (of any sections, both inside the data
    band) are flagged as a pair if one of them has a bandwidth below ``factor`` x spacing
    and their natural frequencies differ by less than the larger of ``factor`` x spacing
    and the smaller of the two bandwidths; pairs are matched greedily, closest first, each
    factor used once. A narrow pole or zero that is not part of such a pair goes to ``narrow``: a
    lightly damped true resonance can be narrower than a coarse grid (example A on the
    thesis's grid: zeta 0.008 at 15 rad/s, bandwidth 0.24 rad/s, spacing 0.52 rad/s) and is
    still fixed by the samples around it.
    """
    model = model_of(model)
    omega = frequency_grid(omega)
    if isinstance(factor, bool) or not isinstance(factor, (int, float)) \
            or not math.isfinite(factor) or factor <= 0:
        raise OptionError(f"factor must be a finite number > 0, got {factor!r}")
    quads = []
    for k, (a, zn, wn, b, zd, wd) in enumerate(model.sections()):
        for kind, c2, zeta, w in (("zero", a, zn, wn), ("pole", b, zd, wd)):
            w0, z0, bw = _quadratic(c2, zeta, w)
            quads.append(Quadratic(kind, k, w0, z0, bw, _local_spacing(omega, w0)))
    inband = [q for q in quads if math.isfinite(q.spacing)]
    narrow = {id(q) for q in inband if q.bandwidth < factor * q.spacing}
    candidates = []
    for z in (q for q in inband if q.kind == "zero"):
        for p in (q for q in inband if q.kind == "pole"):
            if id(z) not in narrow and id(p) not in narrow:
                continue
            dist = abs(z.omega - p.omega)
            if dist < max(min(z.bandwidth, p.bandwidth), factor * max(z.spacing, p.spacing)):
                candidates.append((dist / max(z.spacing, p.spacing), z, p))
    flags, used = [], set()
    for _, z, p in sorted(candidates, key=lambda c: c[0]):
        if id(z) in used or id(p) in used:
            continue
        used |= {id(z), id(p)}
        flags.append(PairFlag(z, p))
    flags.sort(key=lambda f: f.pole.omega)
    narrow = [q for q in inband if id(q) in narrow and id(q) not in used]
    unresolved = tuple(q for q in narrow if q.bandwidth < severe * q.spacing)
    return ResolutionCheck(not flags and not unresolved, tuple(flags), tuple(narrow),
                           model.n_sections, float(factor), unresolved)


def model_of(obj):
    if hasattr(obj, "model") and hasattr(obj, "data"):          # a FitResult
        obj = obj.model
    if not isinstance(obj, RationalDelayModel):
        raise OptionError(f"expected a RationalDelayModel or FitResult, got {type(obj).__name__}")
    if obj.structure.basis != "second-order":
        raise OptionError("check_resolution needs the second-order basis (first-order "
                          "sections have real roots, which are never narrow)")
    return obj


def default_delay_max(omega):
    """Largest delay the data can resolve: ``pi / max(diff(omega))`` seconds.

    Beyond it the phase ``-h w`` changes by more than pi between neighbouring samples and
    the delay is ambiguous (phase-wrapped minima).

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        rad/s, increasing.

    Returns
    -------
    float
        Seconds.
    """
    omega = np.asarray(omega, float).reshape(-1)
    if omega.size == 1 and math.isfinite(omega[0]) and omega[0] > 0:
        return math.pi / omega[0]
    omega = frequency_grid(omega)               # DataError: not finite, > 0, increasing
    return math.pi / float(np.max(np.diff(omega)))


def resolution_damping(omega, fraction=1.0):
    """Damping floor from the frequency resolution: a quadratic's half-power bandwidth
    ``2 zeta w0`` is at least ``fraction`` times the local spacing ``dw``.

    With the relative spacing ``dw/w`` (its median over the data; constant on a log grid)
    this is ``zeta_min = fraction/2 * median(dw/w)``; with ``fraction = 1`` no pole or zero
    of the fit is narrower than the spacing, the criterion of
    :func:`~freqid_casadi.fitting.validation.check_resolution`. On the thesis's grid (500 points
    over 5 decades, ``dw/w = 0.0233``) it is 0.0117, above the lightest damping of
    example A (0.0075 at 15 rad/s): on clean data of A the floor costs accuracy (17
    sections: max relative error 2.2e-4 instead of 5e-6), on noisy data it keeps the fit
    from hiding narrow pole/zero pairs between the samples.

    Parameters
    ----------
    omega : array_like of float, shape (M,), rad/s, strictly increasing
    fraction : float > 0

    Returns
    -------
    float
    """
    omega = np.asarray(omega, float).reshape(-1)
    if omega.size < 2:
        raise DataError("a damping floor from the resolution needs at least 2 frequencies")
    omega = frequency_grid(omega)               # DataError: not finite, > 0, increasing
    if isinstance(fraction, (bool, np.bool_)) or not isinstance(fraction, (int, float,
                                                                       np.floating)) \
            or not 0 < fraction < math.inf:
        raise OptionError(f"fraction must be a finite number > 0, got {fraction!r}")
    rel = np.diff(omega) / omega[:-1]
    return 0.5 * float(fraction) * float(np.median(rel))
