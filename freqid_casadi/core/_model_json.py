"""Schema of model files (layer L0): the checks of ``RationalDelayModel.from_dict`` and
``from_json``, field by field, and a nesting-depth check of the raw JSON text made before
``json.loads`` (whose recursion fails on deeply nested input)."""

import re

import numpy as np

from .._validate import check_choice, check_flag
from ..errors import DataError, OptionError, StructureError

__all__ = ["all_zero_factor", "checked_fields", "check_nesting", "too_big", "no_constant",
           "MAX_MODEL_BYTES", "MAX_MODEL_DEPTH", "flag", "choice", "real_vector", "pade_order",
           "pade"]

_SECOND = ("a", "zeta_num", "omega_num", "b", "zeta_den", "omega_den")
_FIRST = ("a1", "a0", "b1", "b0")


class _Shape:
    """n_sections, delay and basis of a model dict (what the checks need of Structure)."""

    def __init__(self, n_sections, delay, basis, zeros="minimum-phase"):
        self.n_sections, self.delay, self.basis, self.zeros = n_sections, delay, basis, zeros
        self.section_size = 6 if basis == "second-order" else 4
        self.n_params = 2 + self.section_size * n_sections

    def param_names(self):
        names = ["delay", "gain"]
        per = _SECOND if self.basis == "second-order" else _FIRST
        for k in range(1, self.n_sections + 1):
            names += [f"{p}[{k}]" for p in per]
        return names


#: Largest model file :meth:`RationalDelayModel.load` reads (bytes).
MAX_MODEL_BYTES = 16 * 2**20
#: Deepest nesting of arrays/objects accepted in a model file (the schema needs 2).
MAX_MODEL_DEPTH = 16

_FORMAT = "freqid_casadi.RationalDelayModel"
_TOP_KEYS = {"format", "version", "structure", "param_names", "beta"}
_STRUCTURE_KEYS = {"n_sections", "integrator", "delay", "basis", "zeros", "gain_sign"}
_ZEROS = ("minimum-phase", "free")
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


def too_big(n):
    return (f"model JSON has {n} bytes, more than the limit of {MAX_MODEL_BYTES}; "
            "is it really a model file?")


def no_constant(name):
    raise DataError(f"model JSON contains {name}; every number must be finite")


def check_nesting(text):
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


def checked_fields(d, bases, version_read):
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
    flags = [_field(sd, k, (bool,), "true or false (a JSON boolean, not a string)")
             for k in ("integrator", "delay")]
    basis = _field(sd, "basis", (str,), f"one of {', '.join(bases)}")
    if n < 0 or basis not in bases:
        raise DataError(f"malformed model JSON: n_sections must be >= 0 and basis one of "
                        f"{', '.join(bases)}; got {n} and {basis!r:.40}")
    zeros = _field(sd, "zeros", (str,), f"one of {', '.join(_ZEROS)}") if "zeros" in sd \
        else _ZEROS[0]
    sign = _field(sd, "gain_sign", (int,), "1 or -1") if "gain_sign" in sd else 1
    if zeros not in _ZEROS or sign not in (1, -1):
        raise DataError(f"malformed model JSON: zeros must be one of {', '.join(_ZEROS)} and "
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
    bad = all_zero_factor(st.basis, b[2:].reshape(st.n_sections, st.section_size))
    if bad is not None:
        raise DataError(f"malformed model JSON: {bad}")


def all_zero_factor(basis, theta):
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
def flag(name, value):
    """``bool(value)`` by :func:`freqid_casadi._validate.check_flag`, a StructureError."""
    return check_flag(name, value, StructureError)


def choice(name, value, choices):
    """:func:`freqid_casadi._validate.check_choice` with a StructureError."""
    check_choice(name, value, choices, StructureError)


def real_vector(beta):
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


def pade_order(order):
    """``order`` of a Pade approximation as an int >= 0, else an OptionError."""
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)) \
            or order < 0:
        raise OptionError(f"pade_order must be an integer >= 0 (or None: the delay kept "
                          f"as the attribute sys.delay), got {order!r}")
    return int(order)


def pade(ct, delay, order):
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
