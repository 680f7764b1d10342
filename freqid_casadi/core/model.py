"""Model structure, parameter vector and the fitted model G_N (layer L1).

The model (SPEC §1)::

    G_N(s) = exp(-h s) * K * s^(-k) * P_N(s)      (k = structure.origin_order)
    P_N(s) = prod_k (a_k s^2 + 2 zn_k wn_k s + wn_k^2) / (b_k s^2 + 2 zd_k wd_k s + wd_k^2)

or, with the first-order basis (thesis §2.6), ``P_N(s) = prod_k (a1_k s + a0_k)/(b1_k s + b0_k)``.

The parameter vector is the thesis's ``beta = [h, K, theta_1, ..., theta_N]`` (eq. 6 of the
paper) with ``theta_k = [a, zeta_num, omega_num, b, zeta_den, omega_den]`` (second order)
or ``[a1, a0, b1, b0]`` (first order). ``beta >= 0`` element-wise puts every pole and zero
of P_N in the closed left half plane.
"""

import json
import numbers
import os
import re
import stat
from dataclasses import dataclass

import numpy as np

from .. import _cplx
from .._cplx import jw_power, times_jw_power
from .._textio import atomic_write_text
from .._validate import check_choice, check_flag
from ..errors import DataError, OptionError, StructureError
from .metrics import DelayedResponse
from .realize import balanced_ss, check_pade, section_roots, state_space

__all__ = ["Structure", "RationalDelayModel", "section_response", "attach_delay",
           "balanced_ss", "BASES", "MAX_ORIGIN_ORDER", "check_origin_order", "jw_power",
           "times_jw_power",
           "ZEROS", "FORMAT_VERSION", "MAX_MODEL_BYTES", "MAX_MODEL_DEPTH"]

BASES = ("second-order", "first-order")
ZEROS = ("minimum-phase", "free")
FORMAT_VERSION = 1

_SECOND_NAMES = ("a", "zeta_num", "omega_num", "b", "zeta_den", "omega_den")
_FIRST_NAMES = ("a1", "a0", "b1", "b0")
#: Largest number of poles (or zeros) at the origin a model may have: ``|k| <= 3``.
MAX_ORIGIN_ORDER = 3
#: Largest model file :meth:`RationalDelayModel.load` reads (bytes).
MAX_MODEL_BYTES = 16 * 2**20
#: Deepest nesting of arrays/objects accepted in a model file (the schema needs 2).
MAX_MODEL_DEPTH = 16


def check_origin_order(value, error=StructureError, name="integrator"):
    """The poles at the origin ``value`` as stored by :class:`Structure`.

    Parameters
    ----------
    value : bool or int
        True/False, or an integer k (k poles at the origin; negative: -k zeros).
    error : type
        The exception raised for anything else (e.g. OptionError for fit's keyword).
    name : str
        The argument named in the message.

    Returns
    -------
    bool or int
        False/True for False/True/0/1 (numpy's too), an int k for another integer with
        ``|k| <= MAX_ORIGIN_ORDER``.
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral):
        if value in (0, 1):
            return bool(value)
        if abs(int(value)) <= MAX_ORIGIN_ORDER:
            return int(value)
    raise error(f"{name} must be True, False or an integer k with |k| <= {MAX_ORIGIN_ORDER} "
                f"(k poles at the origin; -k zeros), got {value!r}; e.g. {name}=2 for a "
                f"double integrator, {name}=-2 for an accelerance")


@dataclass(frozen=True)
class Structure:
    """The shape of a model: how many sections, which basis, integrator and delay.

    Parameters
    ----------
    n_sections : int
        Number of sections N >= 0 (second-order: order 2N of P_N; first-order: N).
    integrator : bool or int
        Poles at the origin: False (none), True (the factor K0/s), or an integer k with
        ``|k| <= MAX_ORIGIN_ORDER`` for the factor ``s^(-k)`` (k poles at the origin; a
        negative k is -k zeros at the origin: an accelerance ``s^2`` is k = -2). The
        integers 0 and 1 are stored as False and True (so models and their files are the
        same as with the bools); :attr:`origin_order` is k as an int.
    delay : bool
        Whether the delay h is a free parameter (else h = 0).
    basis : {"second-order", "first-order"}
    zeros : {"minimum-phase", "free"}
        "minimum-phase" (the thesis's class): every parameter of beta is >= 0, so the
        zeros are in the closed left half plane. "free": the numerator parameters of each
        section (``a``, ``zeta_num``; ``a1``, ``a0`` in the first-order basis) may be
        negative, so zeros may lie anywhere; the poles stay in the closed left half plane.
    gain_sign : {1, -1}
        Sign of the gain: ``G_N = gain_sign * beta[1] * ...``; ``beta[1] >= 0`` is its
        magnitude (a sign-inverted system, phase near +-180 deg at low frequency).
    """

    n_sections: int
    integrator: bool = False
    delay: bool = True
    basis: str = "second-order"
    zeros: str = "minimum-phase"
    gain_sign: int = 1

    def __post_init__(self):
        n = self.n_sections
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise StructureError(f"n_sections must be an integer, got {n!r}")
        if n < 0:
            raise StructureError(f"n_sections must be >= 0, got {n}")
        object.__setattr__(self, "n_sections", int(n))
        check_choice("basis", self.basis, BASES, StructureError)
        object.__setattr__(self, "integrator", check_origin_order(self.integrator))
        object.__setattr__(self, "delay", check_flag("delay", self.delay, StructureError))
        check_choice("zeros", self.zeros, ZEROS, StructureError)
        if isinstance(self.gain_sign, (bool, np.bool_)) or \
                not isinstance(self.gain_sign, (int, np.integer)) or self.gain_sign not in (1, -1):
            raise StructureError(f"gain_sign must be 1 or -1, got {self.gain_sign!r}")
        object.__setattr__(self, "gain_sign", int(self.gain_sign))

    @property
    def origin_order(self):
        """k, the number of poles at the origin (negative: -k zeros at the origin), int."""
        return int(self.integrator)

    @property
    def section_size(self):
        """Parameters per section: 6 (second-order) or 4 (first-order)."""
        return 6 if self.basis == "second-order" else 4

    @property
    def section_names(self):
        return _SECOND_NAMES if self.basis == "second-order" else _FIRST_NAMES

    @property
    def n_params(self):
        """Length of beta: 2 + section_size * n_sections."""
        return 2 + self.section_size * self.n_sections

    @property
    def order(self):
        """Order of the rational part including the poles at the origin (2N + k for k >= 0
        poles at the origin, 2N for zeros there)."""
        per = 2 if self.basis == "second-order" else 1
        return per * self.n_sections + max(int(self.integrator), 0)

    def with_sections(self, n_sections):
        """The same structure with another number of sections."""
        return Structure(n_sections, self.integrator, self.delay, self.basis, self.zeros,
                         self.gain_sign)

    def free_mask(self):
        """Boolean mask of beta's entries that may be negative (numerator parameters
        ``a``, ``zeta_num`` / ``a1``, ``a0`` with ``zeros="free"``), shape (n_params,)."""
        mask = np.zeros(self.n_params, bool)
        if self.zeros == "free":
            for k in range(self.n_sections):        # (a, zeta_num) or (a1, a0): the first two
                mask[2 + self.section_size * k: 4 + self.section_size * k] = True
        return mask

    def param_names(self):
        """Names of the entries of beta, e.g. ``["delay", "gain", "a[1]", ...]``."""
        names = ["delay", "gain"]
        for k in range(1, self.n_sections + 1):
            names += [f"{p}[{k}]" for p in self.section_names]
        return names


def section_response(basis, omega, theta):
    """Value of the sections at s = j*omega as (re, im) pairs of numerator and denominator.

    Works on numpy arrays and on CasADi SX/MX (docs/style.md §1.2).

    Parameters
    ----------
    basis : str
        "second-order" or "first-order".
    omega : float, ndarray or CasADi expression
        Frequency in rad/s.
    theta : sequence
        The section's parameters in the order of :attr:`Structure.section_names`.

    Returns
    -------
    num, den : (re, im) pairs
    """
    if basis == "second-order":
        a, zn, wn, b, zd, wd = theta
        w2 = omega * omega
        num = (wn * wn - a * w2, 2 * zn * wn * omega)
        den = (wd * wd - b * w2, 2 * zd * wd * omega)
    else:
        a1, a0, b1, b0 = theta
        num = (a0 + 0 * omega, a1 * omega)
        den = (b0 + 0 * omega, b1 * omega)
    return num, den


def _section_ratio(basis, omega, theta):
    """num/den of one section at s = j omega (complex ndarray like omega), free of overflow
    at extreme frequency scales: a second-order section is evaluated at omega / c with its
    natural frequencies divided by c = max(wn, wd) (the ratio is invariant), and numpy's
    complex division scales its operands (|den|^2 is never formed)."""
    theta = np.asarray(theta, dtype=float)
    if basis == "second-order":
        c = float(max(theta[2], theta[5]))
        if np.isfinite(c) and c > 0:
            theta = theta * np.array([1.0, 1.0, 1 / c, 1.0, 1.0, 1 / c])
            omega = omega / c
    num, den = section_response(basis, omega, theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _cplx.to_complex(num) / _cplx.to_complex(den)


DELAY_EXPORTS = (None, "pade", "attribute")


def _export_pade_order(delay, pade_order):
    """The Padé order :meth:`RationalDelayModel.to_control` uses (None: the attribute)."""
    if delay not in DELAY_EXPORTS or isinstance(delay, bool):
        raise OptionError(f"delay must be one of {DELAY_EXPORTS} (how the delay is exported), "
                          f"got {delay!r}; e.g. to_control(delay='pade', pade_order=3)")
    if delay == "pade" and pade_order is None:
        raise OptionError("delay='pade' needs pade_order: to_control(delay='pade', "
                          "pade_order=3) (higher orders follow the delay's phase further)")
    if delay == "attribute" and pade_order is not None:
        raise OptionError(f"delay='attribute' keeps the delay out of the dynamics; drop "
                          f"pade_order={pade_order!r} or use delay='pade'")
    return pade_order


def _structure_dict(s):
    d = {"n_sections": s.n_sections, "integrator": s.integrator, "delay": s.delay,
         "basis": s.basis}
    if s.zeros != "minimum-phase":           # written only when not the default, so the
        d["zeros"] = s.zeros                 # files of minimum-phase models are unchanged
    if s.gain_sign != 1:
        d["gain_sign"] = s.gain_sign
    return d


def attach_delay(sys, delay, pade_order=None):
    """A python-control system with the delay ``delay`` (s): as a Pade approximation of
    order ``pade_order`` in series, or (None) in the system's ``delay`` attribute.

    Parameters
    ----------
    sys : control.StateSpace
    delay : float
    pade_order : int or None

    Returns
    -------
    control.StateSpace
    """
    import control as ct

    if pade_order is not None:
        order = _pade_order(pade_order)
        if delay > 0:
            pn, pd = _pade(ct, delay, order)
            sys = ct.series(sys, ct.ss(ct.tf(pn, pd)))
        sys.delay = 0.0
    else:
        sys.delay = delay
    return sys


@dataclass(frozen=True, eq=False)
class RationalDelayModel(DelayedResponse):
    """A fitted model ``G_N(s) = exp(-h s) K [1/s] P_N(s)`` (SPEC §1).

    Parameters
    ----------
    structure : Structure
    beta : ndarray of float, shape (structure.n_params,)
        ``[h (s), K (gain), theta_1, ..., theta_N]``; must be finite and >= 0.

    Notes
    -----
    Frozen: ``beta`` is stored read-only. Two models are equal when their structures and
    beta are identical bit for bit.
    """

    structure: Structure
    beta: np.ndarray

    def __post_init__(self):
        if not isinstance(self.structure, Structure):
            raise StructureError("structure must be a Structure")
        beta = _real_vector(self.beta)
        if beta.size != self.structure.n_params:
            raise StructureError(
                f"beta has {beta.size} entries, the structure needs {self.structure.n_params} "
                f"(2 + {self.structure.section_size} x {self.structure.n_sections})")
        if not np.all(np.isfinite(beta)):
            i = int(np.flatnonzero(~np.isfinite(beta))[0])
            raise StructureError(f"beta must be finite: beta[{i}] "
                                 f"({self.structure.param_names()[i]}) = {beta[i]}")
        negative = (beta < 0) & ~self.structure.free_mask()
        if np.any(negative):
            i = int(np.flatnonzero(negative)[0])
            raise StructureError(
                f"beta must be >= 0 (poles and zeros in the left half plane): "
                f"beta[{i}] ({self.structure.param_names()[i]}) = {beta[i]}")
        if not self.structure.delay and beta[0] != 0:
            raise StructureError(f"the structure has no delay but beta[0] = {beta[0]}")
        beta.setflags(write=False)
        object.__setattr__(self, "beta", beta)
        bad = _all_zero_factor(self.structure.basis, self.sections())
        if bad is not None:
            raise StructureError(bad)

    def __eq__(self, other):
        return (isinstance(other, RationalDelayModel) and self.structure == other.structure
                and np.array_equal(self.beta, other.beta))

    __hash__ = None

    # ------------------------------------------------------------------ parameters
    @property
    def delay(self):
        """Delay h in seconds."""
        return float(self.beta[0])

    @property
    def gain(self):
        """Gain K (K0 with an integrator), signed: ``structure.gain_sign * beta[1]``."""
        return float(self.structure.gain_sign * self.beta[1])

    @property
    def n_sections(self):
        return self.structure.n_sections

    @property
    def integrator(self):
        """The structure's poles at the origin (False, True or an int k)."""
        return self.structure.integrator

    @property
    def origin_order(self):
        """k, the poles at the origin (negative: zeros there), int."""
        return self.structure.origin_order

    @property
    def order(self):
        """Order of the rational part, poles at the origin included."""
        return self.structure.order

    def sections(self):
        """Section parameters, shape (N, section_size), in thesis order."""
        return self.beta[2:].reshape(self.n_sections, self.structure.section_size)

    def low_frequency_gain(self):
        """The gain at low frequency, signed: ``lim s^k G(s)`` as ``s -> 0`` (``G(0)``
        without poles or zeros at the origin, ``K0`` of ``K0 / s^k`` with them): ``gain``
        times every section's DC value, what ``fit(..., fixed={"dc_gain": K})`` holds and
        python-control's ``dcgain`` gives for k = 0. ``gain`` alone is K, in front of
        sections whose DC values are not 1 (``omega_n^2 / omega_d^2``).

        Returns
        -------
        float
            inf or nan when a section has a pole at 0 exactly (a root at its floor is
            finite: its value shows what the data leave undetermined below the band).
        """
        zero = np.zeros(1)
        value = self.gain
        with np.errstate(divide="ignore", invalid="ignore"):
            for theta in self.sections():
                num, den = section_response(self.structure.basis, zero, theta)
                value = value * float(num[0][0]) / float(den[0][0])
        return float(value)

    # ------------------------------------------------------------------ evaluation
    def rational_response(self, omega):
        """K (j omega)^(-k) P_N(j omega), without the delay; complex ndarray like omega.

        The (re, im) formula of the spec, the one the fit's objective uses; only where it
        overflows (a frequency axis near 1e150 rad/s) is each section evaluated again free
        of overflow (:func:`_section_ratio`), so ordinary data get the fit's own rounding.
        """
        omega = np.asarray(omega, dtype=float)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            z = (self.gain + 0 * omega, 0 * omega)
            k = self.origin_order
            for _ in range(abs(k)):          # k = 1: the integrator's one division
                z = (_cplx.div if k > 0 else _cplx.mul)(z, (0 * omega, omega))
            for theta in self.sections():
                num, den = section_response(self.structure.basis, omega, theta)
                z = _cplx.mul(z, _cplx.div(num, den))
            z = np.asarray(_cplx.to_complex(z))
        bad = ~np.isfinite(z) & np.isfinite(omega) & (omega != 0)
        if np.any(bad):
            z = np.array(z, dtype=complex, copy=True)
            z[bad] = self._scaled_response(omega[bad])
        return z

    def _scaled_response(self, omega):
        """:meth:`rational_response` at ``omega`` (1-D) with every section scaled to its
        own natural frequency, free of overflow at extreme frequency scales."""
        z = self.gain + 0j * omega
        k = self.origin_order
        if k == 1:
            with np.errstate(divide="ignore", invalid="ignore"):
                z = z / (1j * omega)
        elif k:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                z = z / jw_power(omega, k)
        for theta in self.sections():
            z = z * _section_ratio(self.structure.basis, omega, theta)
        return z

    # ------------------------------------------------------------------ poles / zeros
    def _factor_roots(self, which):
        roots = []
        for theta in self.sections():
            zeros, poles = section_roots(self.structure.basis, theta)
            roots += poles if which == "den" else zeros
        return roots

    def poles(self):
        """Poles of the rational part (the k poles at the origin first), complex (n,)."""
        p = self._factor_roots("den")
        if self.origin_order > 0:
            p = [0j] * self.origin_order + p
        return np.array(p, dtype=complex)

    def zeros(self):
        """Finite zeros of the rational part (the -k zeros at the origin first, k < 0),
        complex ndarray."""
        z = self._factor_roots("num")
        if self.origin_order < 0:
            z = [0j] * -self.origin_order + z
        return np.array(z, dtype=complex)

    def is_stable(self, strict=False):
        """Whether P_N is stable (the integrator's pole at 0, if any, is not counted).

        Parameters
        ----------
        strict : bool
            False (default): no pole in the open right half plane (every real part <= 0),
            the sense in which every model with beta >= 0 is stable; an undamped pair
            (zeta_den = 0) on the imaginary axis is allowed, see :meth:`poles_on_axis`.
            True: every pole has a negative real part (asymptotic stability).
        """
        p = np.array(self._factor_roots("den"), dtype=complex)
        return bool(np.all(p.real < 0)) if strict else bool(np.all(p.real <= 0))

    def is_minimum_phase(self, strict=False):
        """Whether every finite zero of P_N lies in the closed (``strict``: open) left half
        plane; see :meth:`is_stable` for the two senses."""
        z = self.zeros()
        return bool(np.all(z.real < 0)) if strict else bool(np.all(z.real <= 0))

    def poles_on_axis(self):
        """Poles of P_N on the imaginary axis (undamped pairs, zeta_den = 0, or a pole at 0;
        the integrator's pole is not counted), complex ndarray."""
        p = np.array(self._factor_roots("den"), dtype=complex)
        return p[p.real == 0]

    # ------------------------------------------------------------------ export
    def to_control(self, pade_order=None, *, delay=None):
        """The rational part as a python-control ``StateSpace`` (series of sections).

        Parameters
        ----------
        pade_order : int, optional
            If given, the delay is included as a Padé approximation of that order;
            otherwise it is left out of the system and stored as the attribute ``delay`` (s).
        delay : {None, "pade", "attribute"}
            How the delay is exported, stated explicitly: "pade" puts the Padé
            approximation of order ``pade_order`` (required) in series, so the system is
            rational and ``control.mixsyn`` / ``hinfsyn`` see the delay's phase (its
            ``delay`` attribute is then 0); "attribute" leaves the delay out of the
            dynamics and stores it as ``sys.delay`` (``pade_order`` must be None). None
            (default): "pade" if ``pade_order`` is given, else "attribute".

        Returns
        -------
        control.StateSpace
            With attribute ``delay`` (s; samples for rad/sample data); realised block by
            block from the poles and zeros, each block on its own frequency scale
            (:mod:`freqid_casadi.core.realize`), connected in series and balanced by an
            exact diagonal similarity (:func:`balanced_ss`).

        Raises
        ------
        OptionError
            An unknown ``delay``, "pade" without ``pade_order``, or "attribute" with one.

        Warns
        -----
        ExportWarning
            The export's response misses the model's (:func:`~freqid_casadi.core.realize.
            state_space`), or the Pade approximation misses the delay by more than 1 %
            where the model's dynamics reach (:func:`~freqid_casadi.core.realize.
            check_pade`, with the order that would not).
        """
        pade_order = _export_pade_order(delay, pade_order)
        sys, balance = state_space(self)
        sys = attach_delay(sys, self.delay, pade_order)
        if pade_order is not None:
            check_pade(self, pade_order)
        return balanced_ss(sys) if balance else sys

    # ------------------------------------------------------------------ JSON
    def to_dict(self):
        s = self.structure
        return {
            "format": "freqid_casadi.RationalDelayModel",
            "version": FORMAT_VERSION,
            "structure": _structure_dict(s),
            "param_names": s.param_names(),
            "beta": [float(v) for v in self.beta],
        }

    def to_json(self):
        """JSON text; floats are written with repr so the round trip is bit-identical."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, d):
        """The model described by ``d`` (as written by :meth:`to_dict`), checked field by
        field against the schema of :data:`FORMAT_VERSION` (see :meth:`load`).

        Raises
        ------
        DataError
            If a field is missing, unknown, of the wrong type or length, not finite,
            negative, or if a section's numerator or denominator is identically zero.
        """
        n, integrator, delay, basis, beta, zeros, sign = _checked_fields(
            d, BASES, FORMAT_VERSION)
        return cls(Structure(n, integrator, delay, basis, zeros, sign), beta)

    @classmethod
    def from_json(cls, text):
        """The model in the JSON ``text`` (str or bytes; see :meth:`load` for the checks)."""
        if isinstance(text, (bytes, bytearray)):
            if len(text) > MAX_MODEL_BYTES:
                raise DataError(_too_big(len(text)))
            try:
                text = bytes(text).decode("utf-8-sig")       # a BOM is tolerated
            except UnicodeDecodeError:
                raise DataError("model file is not UTF-8 JSON text") from None
        if not isinstance(text, str):
            raise DataError(f"model JSON must be text, got {type(text).__name__}")
        if len(text) > MAX_MODEL_BYTES:
            raise DataError(_too_big(len(text)))
        _check_nesting(text)
        try:
            d = json.loads(text, parse_constant=_no_constant)
        except (ValueError, RecursionError) as exc:   # JSONDecodeError, 5000-digit ints
            if isinstance(exc, DataError):
                raise
            raise DataError(f"model file is not valid JSON: {exc}") from None
        return cls.from_dict(d)

    def save(self, path):
        """Write the model as JSON (atomically)."""
        atomic_write_text(path, self.to_json() + "\n")

    @classmethod
    def load(cls, path):
        """Read a model written by :meth:`save`.

        Only a regular file of at most :data:`MAX_MODEL_BYTES` bytes is read (a FIFO or a
        device is refused before it is opened); its JSON may nest at most
        :data:`MAX_MODEL_DEPTH` levels and must follow the schema: ``format``
        ``"freqid_casadi.RationalDelayModel"``, ``version`` 1, ``structure`` with
        ``n_sections`` (integer >= 0) and optional ``integrator`` (JSON boolean, or an
        integer k with ``|k| <= MAX_ORIGIN_ORDER`` poles at the origin, negative for
        zeros, as written for ``|k| >= 2``; default false) and ``delay`` (JSON boolean, default
        true) and ``basis`` (default second-order), optional
        ``param_names`` (as written), and ``beta``: finite numbers >= 0, one per parameter,
        no section with an all-zero numerator or denominator.

        Raises
        ------
        DataError
            If the file cannot be read or breaks the schema.
        """
        try:
            st = os.stat(path)
            if not stat.S_ISREG(st.st_mode):
                raise DataError(f"cannot read model file {os.fspath(path)!r}: not a regular "
                                "file (a folder, FIFO or device); give a .json file")
            if st.st_size > MAX_MODEL_BYTES:
                raise DataError(f"model file {os.fspath(path)!r}: "
                                + _too_big(st.st_size))
            with open(path, "rb") as fh:
                payload = fh.read(MAX_MODEL_BYTES + 1)
        except OSError as exc:
            raise DataError(f"cannot read model file {path!r}: {exc.strerror}") from None
        except (TypeError, ValueError) as exc:
            raise DataError(f"model path must be a file name, got {path!r}: {exc}") from None
        try:
            return cls.from_json(payload)
        except DataError as exc:
            raise DataError(f"model file {os.fspath(path)!r}: {exc}") from None

    def __repr__(self):
        s = self.structure
        return (f"RationalDelayModel(n_sections={s.n_sections}, basis={s.basis!r}, "
                f"integrator={s.integrator}, delay={self.delay:.6g}, gain={self.gain:.6g})")


# ----------------------------------------------------------------------------------------
# The model-file schema (the checks of from_dict and from_json, field by field, and a
# nesting-depth check of the raw JSON text made before json.loads, whose recursion fails
# on deeply nested input) and the validators of Structure and RationalDelayModel.



class _Shape:
    """n_sections, delay and basis of a model dict (what the checks need of Structure)."""

    def __init__(self, n_sections, delay, basis, zeros="minimum-phase"):
        self.n_sections, self.delay, self.basis, self.zeros = n_sections, delay, basis, zeros
        self.section_size = 6 if basis == "second-order" else 4
        self.n_params = 2 + self.section_size * n_sections

    def param_names(self):
        names = ["delay", "gain"]
        per = _SECOND_NAMES if self.basis == "second-order" else _FIRST_NAMES
        for k in range(1, self.n_sections + 1):
            names += [f"{p}[{k}]" for p in per]
        return names



_FORMAT = "freqid_casadi.RationalDelayModel"
_TOP_KEYS = {"format", "version", "structure", "param_names", "beta"}
_STRUCTURE_KEYS = {"n_sections", "integrator", "delay", "basis", "zeros", "gain_sign"}
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


def _too_big(n):
    return (f"model JSON has {n} bytes, more than the limit of {MAX_MODEL_BYTES}; "
            "is it really a model file?")


def _no_constant(name):
    raise DataError(f"model JSON contains {name}; every number must be finite")


def _check_nesting(text):
    """Raise DataError if arrays/objects nest deeper than MAX_MODEL_DEPTH (before json.loads,
    whose recursion would fail on deeply nested input)."""
    bare = _STRING.sub('""', text)
    code = np.frombuffer(bare.encode("utf-8", "replace"), dtype=np.uint8)
    step = np.zeros(code.size, dtype=np.int64)
    step[(code == ord("[")) | (code == ord("{"))] = 1
    step[(code == ord("]")) | (code == ord("}"))] = -1
    depth = int(np.max(np.cumsum(step), initial=0))
    if depth > MAX_MODEL_DEPTH:
        raise DataError(f"model JSON nests {depth} levels deep (at most {MAX_MODEL_DEPTH}); "
                        "not a model file")


def _field(d, key, types, what):
    if key not in d:
        raise DataError(f"malformed model JSON: missing field {key!r} ({what})")
    v = d[key]
    if isinstance(v, bool) and bool not in types or not isinstance(v, types):
        raise DataError(f"malformed model JSON: field {key!r} must be {what}, got {v!r:.80}")
    return v


def _checked_fields(d, bases, version_read):
    """``(n_sections, integrator, delay, basis, beta, zeros, gain_sign)`` of a model dict,
    checked against the schema (see ``RationalDelayModel.load``); ``beta`` is a float
    ndarray. ``zeros`` and ``gain_sign`` are optional structure fields (written only when
    not "minimum-phase" / 1)."""
    if not isinstance(d, dict):
        raise DataError(f"malformed model JSON: it must be an object, got {type(d).__name__}")
    if d.get("format") != _FORMAT:
        raise DataError(f"not a freqid_casadi model ('format' must be {_FORMAT!r})")
    version = _field(d, "version", (int,), "an integer")
    if version != version_read:
        raise DataError(f"malformed model JSON: version {version!r} is not supported (this "
                        f"freqid_casadi reads version {version_read}); upgrade freqid_casadi")
    unknown = sorted(map(str, set(d) - _TOP_KEYS))
    if unknown:
        raise DataError("malformed model JSON: unknown field(s) "
                        f"{', '.join(map(repr, unknown))}")
    sd = _field(d, "structure", (dict,), "an object")
    unknown = sorted(map(str, set(sd) - _STRUCTURE_KEYS))
    if unknown:
        raise DataError("malformed model JSON: unknown structure field(s) "
                        f"{', '.join(map(repr, unknown))}")
    n = _field(sd, "n_sections", (int,), "an integer >= 0")
    sd = {"integrator": False, "delay": True, "basis": bases[0], **sd}   # defaults
    flags = [_field(sd, "integrator", (bool, int), "true, false or an integer k with "
                    f"|k| <= {MAX_ORIGIN_ORDER} (poles at the origin)"),
             _field(sd, "delay", (bool,), "true or false (a JSON boolean, not a string)")]
    if not isinstance(flags[0], bool) and abs(flags[0]) > MAX_ORIGIN_ORDER:
        raise DataError(f"malformed model JSON: integrator {flags[0]!r} must be true, false "
                        f"or an integer k with |k| <= {MAX_ORIGIN_ORDER} (poles at the origin)")
    basis = _field(sd, "basis", (str,), f"one of {', '.join(bases)}")
    if n < 0 or basis not in bases:
        raise DataError(f"malformed model JSON: n_sections must be >= 0 and basis one of "
                        f"{', '.join(bases)}; got {n} and {basis!r:.40}")
    zeros = _field(sd, "zeros", (str,), f"one of {', '.join(ZEROS)}") if "zeros" in sd \
        else ZEROS[0]
    sign = _field(sd, "gain_sign", (int,), "1 or -1") if "gain_sign" in sd else 1
    if zeros not in ZEROS or sign not in (1, -1):
        raise DataError(f"malformed model JSON: zeros must be one of {', '.join(ZEROS)} and "
                        f"gain_sign 1 or -1; got {zeros!r:.40} and {sign!r}")
    st = _Shape(n, flags[1], basis, zeros)
    beta = _field(d, "beta", (list,), "a list of numbers")
    if len(beta) != st.n_params:
        raise DataError(f"malformed model JSON: beta has {len(beta)} entries, the structure needs "
                        f"{st.n_params}")
    if "param_names" in d and d["param_names"] != st.param_names():
        raise DataError("malformed model JSON: param_names do not match the structure")
    bad = [k for k, v in enumerate(beta)
           if isinstance(v, bool) or not isinstance(v, (int, float))]
    if bad:
        raise DataError(f"malformed model JSON: beta[{bad[0]}] must be a number, got "
                        f"{beta[bad[0]]!r:.40}")
    with np.errstate(all="ignore"):
        b = np.array([float(v) for v in beta], dtype=float)
    _check_beta(st, b)
    return n, flags[0], flags[1], basis, b, zeros, sign


def _check_beta(st, b):
    free = np.zeros(b.size, bool)
    if st.zeros == "free":              # numerators (a, zeta_num / a1, a0) may be negative
        for k in range(st.n_sections):
            free[2 + st.section_size * k: 4 + st.section_size * k] = True
    bad = np.flatnonzero(~np.isfinite(b) | ((b < 0) & ~free))
    if bad.size:
        k = int(bad[0])
        raise DataError(f"malformed model JSON: beta[{k}] ({st.param_names()[k]}) = "
                        f"{float(b[k])!r} must be finite and >= 0")
    if not st.delay and b[0] != 0:
        raise DataError("malformed model JSON: the structure has no delay but beta[0] = "
                        f"{float(b[0])!r}")
    bad = _all_zero_factor(st.basis, b[2:].reshape(st.n_sections, st.section_size))
    if bad is not None:
        raise DataError(f"malformed model JSON: {bad}")


def _all_zero_factor(basis, theta):
    """None, or a text naming the first section whose numerator or denominator has only
    zero coefficients (the model would be 0 or infinite at every frequency).

    Parameters
    ----------
    basis : {"second-order", "first-order"}
    theta : ndarray of float, shape (n_sections, section_size)
        The sections' parameters in thesis order.
    """
    with np.errstate(all="ignore"):
        if basis == "second-order":
            num = np.stack([theta[:, 0], 2 * theta[:, 1] * theta[:, 2], theta[:, 2] ** 2], 1)
            den = np.stack([theta[:, 3], 2 * theta[:, 4] * theta[:, 5], theta[:, 5] ** 2], 1)
        else:
            num, den = theta[:, :2], theta[:, 2:]
    for what, c in (("numerator", num), ("denominator", den)):
        zero = np.flatnonzero(~np.any(c != 0, axis=1))
        if zero.size:
            return (f"section {int(zero[0]) + 1} has an all-zero {what} (0/0 or a pole/zero "
                    "at every frequency)")
    return None


# ------------------------------------------------- checks of Structure / RationalDelayModel
def _real_vector(beta):
    """``beta`` as a new one-dimensional float array; StructureError for complex values,
    text or a 2-D array (rather than a silent real part or flattening)."""
    try:
        arr = np.asarray(beta)
        out = np.array(arr, dtype=float, copy=True).reshape(-1) \
            if not np.iscomplexobj(arr) else None
    except (TypeError, ValueError) as exc:
        raise StructureError(f"beta must be an array of real numbers: {exc}") from None
    if out is None or arr.ndim > 1:
        raise StructureError(f"beta must be a one-dimensional array of real numbers, got "
                             f"{'complex values' if out is None else f'shape {arr.shape}'}")
    return out


def _pade_order(order):
    """``order`` of a Pade approximation as an int >= 1, else an OptionError (order 0 would
    drop the delay: its Pade approximation is 1)."""
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)) \
            or order < 1:
        raise OptionError(f"pade_order must be an integer >= 1 (the order of the delay's "
                          f"Pade approximation; 0 would drop the delay; None keeps it as the "
                          f"attribute sys.delay), got {order!r}")
    return int(order)


def _pade(ct, delay, order):
    """``ct.pade(delay, order)`` with finite coefficients, else an OptionError (python-control
    divides by zero above a few hundred)."""
    try:
        with np.errstate(all="raise"):
            num, den = ct.pade(delay, order)
        ok = np.all(np.isfinite(num)) and np.all(np.isfinite(den))
    except (ArithmeticError, FloatingPointError, ValueError):
        ok = False
    if not ok:
        raise OptionError(f"pade_order={order} is too high for a finite Pade approximation "
                          f"of the delay {delay:g} s; use an order below about 20")
    return num, den
