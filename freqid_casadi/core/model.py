"""Model structure, parameter vector and the fitted model G_N (layer L1).

The model (SPEC §1)::

    G_N(s) = exp(-h s) * K * [1/s if integrator] * P_N(s)
    P_N(s) = prod_k (a_k s^2 + 2 zn_k wn_k s + wn_k^2) / (b_k s^2 + 2 zd_k wd_k s + wd_k^2)

or, with the first-order basis (thesis §2.6), ``P_N(s) = prod_k (a1_k s + a0_k)/(b1_k s + b0_k)``.

The parameter vector is the thesis's ``beta = [h, K, theta_1, ..., theta_N]`` (eq. 6 of the
paper) with ``theta_k = [a, zeta_num, omega_num, b, zeta_den, omega_den]`` (second order)
or ``[a1, a0, b1, b0]`` (first order). ``beta >= 0`` element-wise puts every pole and zero
of P_N in the closed left half plane.
"""

import json
import os
import stat
from dataclasses import dataclass

import numpy as np

from .. import _cplx
from . import _model_json
from ._model_json import MAX_MODEL_BYTES, MAX_MODEL_DEPTH
from .._textio import atomic_write_text
from ..errors import DataError, StructureError
from .metrics import DelayedResponse

__all__ = ["Structure", "RationalDelayModel", "section_response", "attach_delay", "BASES",
           "ZEROS", "FORMAT_VERSION", "MAX_MODEL_BYTES", "MAX_MODEL_DEPTH"]

BASES = ("second-order", "first-order")
ZEROS = ("minimum-phase", "free")
FORMAT_VERSION = 1

_SECOND_NAMES = ("a", "zeta_num", "omega_num", "b", "zeta_den", "omega_den")
_FIRST_NAMES = ("a1", "a0", "b1", "b0")


@dataclass(frozen=True)
class Structure:
    """The shape of a model: how many sections, which basis, integrator and delay.

    Parameters
    ----------
    n_sections : int
        Number of sections N >= 0 (second-order: order 2N of P_N; first-order: N).
    integrator : bool
        Whether G_N has the factor K0/s.
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
        _model_json.choice("basis", self.basis, BASES)
        object.__setattr__(self, "integrator", _model_json.flag("integrator", self.integrator))
        object.__setattr__(self, "delay", _model_json.flag("delay", self.delay))
        _model_json.choice("zeros", self.zeros, ZEROS)
        if isinstance(self.gain_sign, (bool, np.bool_)) or \
                not isinstance(self.gain_sign, (int, np.integer)) or self.gain_sign not in (1, -1):
            raise StructureError(f"gain_sign must be 1 or -1, got {self.gain_sign!r}")
        object.__setattr__(self, "gain_sign", int(self.gain_sign))

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
        """Order of the rational part including the integrator (2N+1 with integrator...)."""
        per = 2 if self.basis == "second-order" else 1
        return per * self.n_sections + int(self.integrator)

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


def _quad_roots(c2, c1, c0):
    """Roots of c2 s^2 + c1 s + c0 (c2 may be 0); returns a list of complex.

    For the coefficients of a model (all >= 0) the closed form keeps the sign of every real
    part exact: 0 for c1 = 0 (an undamped pair on the imaginary axis), else < 0.
    """
    if c2 == 0:
        return [complex(-c0 / c1)] if c1 != 0 else []
    if min(c2, c1, c0) >= 0:
        with np.errstate(all="ignore"):
            p, q = c1 / (2.0 * c2), c0 / c2            # s^2 + 2 p s + q
        if not (np.isfinite(p) and np.isfinite(q)):     # c2 negligible: one finite root
            return [complex(-c0 / c1)] if c1 != 0 else []
        if p < 1e150:
            disc = p * p - q
            if disc < 0:
                im = float(np.sqrt(-disc))
                return [complex(-p, im), complex(-p, -im)]
            sd = float(np.sqrt(disc))
        else:
            r = q / p / p                               # disc = p^2 (1 - r), no overflow
            if r > 1:
                im = p * float(np.sqrt(r - 1.0))
                return [complex(-p, im), complex(-p, -im)]
            sd = p * float(np.sqrt(1.0 - r))
        big = -(p + sd)                                 # no cancellation
        return [complex(big), complex(q / big if big != 0 else 0.0)]
    return list(np.roots([c2, c1, c0]).astype(complex))


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
        order = _model_json.pade_order(pade_order)
        if delay > 0:
            pn, pd = _model_json.pade(ct, delay, order)
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
        beta = _model_json.real_vector(self.beta)
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
        bad = _model_json.all_zero_factor(self.structure.basis, self.sections())
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
        return self.structure.integrator

    @property
    def order(self):
        """Order of the rational part, integrator included."""
        return self.structure.order

    def sections(self):
        """Section parameters, shape (N, section_size), in thesis order."""
        return self.beta[2:].reshape(self.n_sections, self.structure.section_size)

    # ------------------------------------------------------------------ evaluation
    def rational_response(self, omega):
        """K [1/(j omega)] P_N(j omega), without the delay; complex ndarray like omega."""
        omega = np.asarray(omega, dtype=float)
        z = self.gain + 0j * omega
        if self.integrator:
            with np.errstate(divide="ignore", invalid="ignore"):
                z = z / (1j * omega)
        for theta in self.sections():
            z = z * _section_ratio(self.structure.basis, omega, theta)
        return z

    # ------------------------------------------------------------------ poles / zeros
    def _factor_roots(self, which):
        roots = []
        for theta in self.sections():
            if self.structure.basis == "second-order":
                a, zn, wn, b, zd, wd = theta
                c = (a, 2 * zn * wn, wn * wn) if which == "num" else (b, 2 * zd * wd, wd * wd)
                roots += _quad_roots(*c)
            else:
                a1, a0, b1, b0 = theta
                c = (a1, a0) if which == "num" else (b1, b0)
                if c[0] != 0:
                    roots.append(complex(-c[1] / c[0]))
        return roots

    def poles(self):
        """Poles of the rational part (the integrator's pole at 0 included), complex (n,)."""
        p = self._factor_roots("den")
        if self.integrator:
            p = [0j] + p
        return np.array(p, dtype=complex)

    def zeros(self):
        """Finite zeros of the rational part, complex ndarray."""
        return np.array(self._factor_roots("num"), dtype=complex)

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
    def to_control(self, pade_order=None):
        """The rational part as a python-control ``StateSpace`` (series of sections).

        Parameters
        ----------
        pade_order : int, optional
            If given, the delay is included as a Padé approximation of that order;
            otherwise it is left out of the system and stored as the attribute ``delay`` (s).

        Returns
        -------
        control.StateSpace
            With attribute ``delay`` (s); sections are realised one by one and connected in
            series, which is better conditioned than expanding one polynomial.
        """
        import control as ct

        sys = ct.ss([], [], [], [[self.gain]])
        if self.integrator:
            sys = ct.series(sys, ct.ss(ct.tf([1.0], [1.0, 0.0])))
        for theta in self.sections():
            if self.structure.basis == "second-order":
                a, zn, wn, b, zd, wd = theta
                num, den = [a, 2 * zn * wn, wn * wn], [b, 2 * zd * wd, wd * wd]
            else:
                a1, a0, b1, b0 = theta
                num, den = [a1, a0], [b1, b0]
            num, den = np.trim_zeros(num, "f"), np.trim_zeros(den, "f")
            if len(num) > len(den):
                raise StructureError("section is improper (numerator degree > denominator's); "
                                     "cannot export to a state-space model")
            sys = ct.series(sys, ct.ss(ct.tf(num, den)))
        return attach_delay(sys, self.delay, pade_order)

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
        n, integrator, delay, basis, beta, zeros, sign = _model_json.checked_fields(
            d, BASES, FORMAT_VERSION)
        return cls(Structure(n, integrator, delay, basis, zeros, sign), beta)

    @classmethod
    def from_json(cls, text):
        """The model in the JSON ``text`` (str or bytes; see :meth:`load` for the checks)."""
        if isinstance(text, (bytes, bytearray)):
            if len(text) > MAX_MODEL_BYTES:
                raise DataError(_model_json.too_big(len(text)))
            try:
                text = bytes(text).decode("utf-8-sig")       # a BOM is tolerated
            except UnicodeDecodeError:
                raise DataError("model file is not UTF-8 JSON text") from None
        if not isinstance(text, str):
            raise DataError(f"model JSON must be text, got {type(text).__name__}")
        if len(text) > MAX_MODEL_BYTES:
            raise DataError(_model_json.too_big(len(text)))
        _model_json.check_nesting(text)
        try:
            d = json.loads(text, parse_constant=_model_json.no_constant)
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
        ``n_sections`` (integer >= 0) and optional ``integrator`` and ``delay`` (JSON
        booleans, default false and true) and ``basis`` (default second-order), optional
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
                                + _model_json.too_big(st.st_size))
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
