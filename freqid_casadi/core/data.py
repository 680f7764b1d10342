"""Frequency-response data: validation and windows (layer L1; file readers in loaders.py).

:class:`FrequencyData` is the one container every fitter takes. It is frozen and its arrays
are read-only, so a window or a result can share them safely.
"""

import math
import re
import sys
from dataclasses import dataclass, field

import numpy as np

from ..errors import DataError, OptionError

__all__ = ["FrequencyData", "dense_grid", "frequency_grid", "FREQUENCY_UNITS", "TIME_UNITS",
           "as_frequency_data", "external_frequency_data", "DATA_TYPES"]

#: What :func:`as_frequency_data` accepts (for messages).
DATA_TYPES = ("FrequencyData", "control.FrequencyResponseData (SISO)",
              "skrf.Network (one-port)")

#: Units of :attr:`FrequencyData.omega`.
FREQUENCY_UNITS = ("rad/s", "rad/sample")
#: The unit of a delay (:attr:`FrequencyData.time_unit`) on each frequency axis.
TIME_UNITS = {"rad/s": "s", "rad/sample": "samples"}


def _first_bad(mask):
    return int(np.flatnonzero(mask)[0])


@dataclass(frozen=True, repr=False)
class FrequencyData:
    """Samples ``response[i] = G(j*omega[i])`` of a frequency response.

    Parameters
    ----------
    omega : array_like of float, shape (M,)
        Angular frequencies in rad/s: finite, > 0 and strictly increasing.
    response : array_like of complex, shape (M,)
        Complex frequency response at ``omega``: finite and nonzero.
    name : str, optional
        A label used in reports and plots.
    weights : array_like of float, shape (M,), optional
        Nonnegative weights of the squared relative residuals (default: all 1).
    unit : {"rad/s", "rad/sample"}
        Unit of ``omega``: "rad/sample" for a normalised frequency (an FRF estimated
        without a sampling rate), whose delays are then in samples (:attr:`time_unit`);
        used in messages and reports, the numbers are the same.

    Raises
    ------
    DataError
        Naming the offending index and value and the fix, for any violation above.

    Notes
    -----
    Use :meth:`sorted` to sort and de-duplicate raw data before construction.
    """

    omega: np.ndarray
    response: np.ndarray
    name: str = None
    weights: np.ndarray = field(default=None)
    unit: str = "rad/s"

    def __post_init__(self):
        if not isinstance(self.unit, str) or self.unit not in FREQUENCY_UNITS:
            hint = (": frequencies in Hz are omega = 2 * pi * f in rad/s (or read a file with "
                    "fc.load(path, freq_unit='Hz'))" if str(self.unit).lower() == "hz" else "")
            raise DataError(f"unit must be one of {FREQUENCY_UNITS}, got {self.unit!r}{hint}")
        omega = _as_float_vector(self.omega, "omega")
        response = _as_complex_vector(self.response, "response")
        if omega.size == 0:
            raise DataError("omega is empty: give at least a few frequency points")
        if response.size != omega.size:
            raise DataError(
                f"omega and response must have equal lengths: len(omega)={omega.size}, "
                f"len(response)={response.size}; pass one response value per frequency")
        bad = ~np.isfinite(omega)
        if bad.any():
            i = _first_bad(bad)
            raise DataError(
                f"omega must be finite: omega[{i}]={float(omega[i])}; remove that point")
        bad = omega <= 0
        if bad.any():
            i = _first_bad(bad)
            raise DataError(
                f"omega must be > 0 (rad/s): omega[{i}]={float(omega[i])}; drop the zero/negative "
                "frequencies (the DC value is not used, an integrator is a model option)")
        d = np.diff(omega)
        bad = d <= 0
        if bad.any():
            i = _first_bad(bad) + 1
            what = "duplicated" if d[i - 1] == 0 else "strictly increasing"
            raise DataError(
                f"omega must be strictly increasing ({what} value): omega[{i}]="
                f"{float(omega[i])!r} <= omega[{i - 1}]={float(omega[i - 1])!r}; use "
                "FrequencyData.sorted(omega, response)")
        bad = ~np.isfinite(response)
        if bad.any():
            i = _first_bad(bad)
            raise DataError(
                f"response must be finite: response[{i}]={response[i]} at omega={float(omega[i])}; "
                "remove or re-measure that point")
        bad = response == 0
        if bad.any():
            i = _first_bad(bad)
            raise DataError(
                f"response must be nonzero (the relative error divides by it): response[{i}]=0 "
                f"at omega={float(omega[i])}; remove that point")
        weights = self.weights
        if isinstance(weights, str):
            raise DataError(f"weights must be an array of one weight per frequency, got "
                            f"{weights!r} (weights='noise', estimated from the data, is "
                            "fc.fit's and freqid fit's)")
        if weights is not None:
            weights = _as_float_vector(weights, "weights")
            if weights.size != omega.size:
                raise DataError(
                    f"weights must have one value per frequency: len(weights)={weights.size}, "
                    f"len(omega)={omega.size}")
            bad = ~np.isfinite(weights) | (weights < 0)
            if bad.any():
                i = _first_bad(bad)
                raise DataError(
                    f"weights must be finite and >= 0: weights[{i}]={float(weights[i])}")
            if not np.any(weights > 0):
                raise DataError("weights are all zero: at least one point must count")
            weights.setflags(write=False)
        omega.setflags(write=False)
        response.setflags(write=False)
        object.__setattr__(self, "omega", omega)
        object.__setattr__(self, "response", response)
        object.__setattr__(self, "weights", weights)
        if self.name is not None and not isinstance(self.name, str):
            raise DataError(f"name must be a string or None, got {type(self.name).__name__}")

    def __len__(self):
        return self.omega.size

    def __repr__(self):
        # a summary, not every sample (print(fc.load(...)) had shown 400 complex numbers);
        # the arrays are .omega, .response and .weights
        size = np.abs(self.response)
        return (f"FrequencyData(name={self.name!r}, {self.n_points} "
                f"point{'' if self.n_points == 1 else 's'}, omega "
                f"{self.omega[0]:.4g} to {self.omega[-1]:.4g} {self.unit}, |response| "
                f"{size.min():.4g} to {size.max():.4g}"
                f"{', weighted' if self.weights is not None else ''})")

    @property
    def n_points(self):
        """Number of frequency points M."""
        return self.omega.size

    def window(self, n_points):
        """The first ``n_points`` samples (lowest frequencies) as a new FrequencyData."""
        if isinstance(n_points, (bool, np.bool_)) or not isinstance(n_points, (int, np.integer)):
            raise DataError(f"window length must be an integer, got {n_points!r}")
        n = int(n_points)
        if not 1 <= n <= self.n_points:
            raise DataError(f"window length must be in 1..{self.n_points}, got {n_points}")
        w = None if self.weights is None else self.weights[:n]
        return FrequencyData(self.omega[:n], self.response[:n], self.name, w, self.unit)

    def with_weights(self, weights):
        """A copy with other weights (``None`` for uniform)."""
        return FrequencyData(self.omega, self.response, self.name, weights, self.unit)

    @property
    def time_unit(self):
        """Unit of a delay on this frequency axis: "s" (rad/s) or "samples"."""
        return TIME_UNITS[self.unit]

    def to_frd(self):
        """The data as a python-control ``FrequencyResponseData`` (SISO).

        Returns
        -------
        control.FrequencyResponseData
            ``omega`` in the data's unit (rad/s, or rad/sample for normalised data: a
            python-control FRD has no sampling time) and the complex ``response``; its
            ``name`` is the data's name when it has one. The weights are not carried.
        """
        import control as ct

        kw = {"name": self.name} if self.name else {}
        return ct.frd(np.array(self.response), np.array(self.omega), **kw)

    @classmethod
    def sorted(cls, omega, response, name=None, weights=None):
        """Build from unsorted data: sort by omega and drop exact duplicate frequencies.

        Duplicates keep their first occurrence in the input order; where their responses
        differ by more than 1 % (two sweeps, or two channels, in one table) a
        :class:`~freqid_casadi.errors.DataWarning` says how many and by how much.
        """
        omega = _as_float_vector(omega, "omega")
        response = _as_complex_vector(response, "response")
        if omega.size != response.size:
            raise DataError(
                f"omega and response must have equal lengths: len(omega)={omega.size}, "
                f"len(response)={response.size}")
        order = np.argsort(omega, kind="stable")
        keep = np.ones(order.size, bool)
        keep[1:] = np.diff(omega[order]) != 0
        idx = order[keep]
        _warn_differing_duplicates(omega[order], response[order], keep)
        w = None if weights is None else _as_float_vector(weights, "weights")
        if w is not None and w.size != omega.size:
            raise DataError(f"weights must have one value per frequency: len(weights)={w.size}, "
                            f"len(omega)={omega.size}")
        w = None if w is None else w[idx]
        return cls(omega[idx], response[idx], name, w)


def _warn_differing_duplicates(omega, response, keep):
    """A DataWarning when a dropped duplicate's response (``omega``, ``response`` sorted;
    ``keep`` False at each dropped row) differs from the kept one by more than 1 %."""
    first = np.maximum.accumulate(np.where(keep, np.arange(keep.size), 0))[~keep]
    if not first.size:
        return
    with np.errstate(all="ignore"):
        diff = np.abs(response[~keep] / response[first] - 1.0)
    diff[response[~keep] == response[first]] = 0.0          # (0 and 0: the same)
    bad = diff > 0.01                                       # (nan: the constructor says)
    if bad.any():
        import warnings

        from ..errors import DataWarning

        j = int(np.argmax(np.where(bad, diff, -1.0)))
        warnings.warn(
            f"{int(np.count_nonzero(~keep))} duplicated frequencies dropped, {int(bad.sum())} "
            f"of them with a response that differs from the one kept by more than 1 % (up to "
            f"{100 * diff[j]:.3g} %, at omega {omega[~keep][j]:.6g}): the data may hold two "
            "sweeps or two channels; the first of each was kept", DataWarning, stacklevel=3)


# --------------------------------------------------------------------------- conversion
def external_frequency_data(obj, name="data"):
    """``obj`` as FrequencyData if it is a python-control FRD or a scikit-rf Network, else
    None (a FrequencyData is returned as it is).

    Neither library is imported here: an object can only be one of theirs if its module
    is already loaded (``sys.modules``).

    Parameters
    ----------
    obj : object
    name : str
        The argument's name, for messages.

    Returns
    -------
    FrequencyData or None

    Raises
    ------
    DataError
        A MIMO FRD, a Network with more than one port, or values FrequencyData refuses
        (a frequency <= 0, a NaN, ...), naming ``name``.
    """
    if isinstance(obj, FrequencyData):
        return obj
    ct = sys.modules.get("control")
    frd_type = getattr(ct, "FrequencyResponseData", None) if ct is not None else None
    if frd_type is not None and isinstance(obj, frd_type):
        resp = np.asarray(obj.frdata if hasattr(obj, "frdata") else obj.fresp)
        if resp.ndim != 3 or resp.shape[:2] != (1, 1):
            raise DataError(f"{name} is a FrequencyResponseData with {obj.noutputs} outputs "
                            f"and {obj.ninputs} inputs; pass one SISO channel, e.g. "
                            f"{name}[0, 0]")
        label = getattr(obj, "name", None)
        return _converted(np.asarray(obj.omega, float), resp[0, 0], label, name,
                          "FrequencyResponseData")
    skrf = sys.modules.get("skrf")
    net_type = getattr(skrf, "Network", None) if skrf is not None else None
    if net_type is not None and isinstance(obj, net_type):
        s = np.asarray(obj.s)
        if s.ndim != 3 or s.shape[1:] != (1, 1):
            raise DataError(f"{name} is a {s.shape[1]}-port skrf.Network; pass a one-port "
                            f"(e.g. {name}.s11)")
        return _converted(2.0 * np.pi * np.asarray(obj.f, float), s[:, 0, 0],
                          getattr(obj, "name", None), name, "skrf.Network")
    return None


def as_frequency_data(obj, name="data"):
    """``obj`` as FrequencyData: a FrequencyData itself, a SISO python-control
    ``FrequencyResponseData`` (omega in rad/s, its ``name``) or a one-port scikit-rf
    ``Network`` (omega = 2 pi f, the response S11, its ``name``).

    Parameters
    ----------
    obj : FrequencyData, control.FrequencyResponseData or skrf.Network
    name : str
        The argument's name, for messages.

    Returns
    -------
    FrequencyData

    Raises
    ------
    DataError
        Any other type, a MIMO system or a multi-port network, or bad values.
    """
    data = external_frequency_data(obj, name)
    if data is None:
        raise DataError(f"{name} must be one of {', '.join(DATA_TYPES)}, got "
                        f"{type(obj).__name__}; build FrequencyData(omega, response) from "
                        "arrays or read a file with freqid_casadi.load")
    return data


def _converted(omega, response, label, name, kind):
    if not isinstance(label, str) or not label or re.fullmatch(r"sys\[\d+\]", label):
        label = None                                  # python-control's automatic names
    try:
        return FrequencyData(omega, response, label)
    except DataError as exc:
        raise DataError(f"{name} ({kind}): {exc}") from None


def _as_float_vector(x, name):
    try:
        is_complex = np.iscomplexobj(np.asarray(x))
    except (TypeError, ValueError):
        is_complex = False
    if is_complex:
        raise DataError(f"{name} must be real, got complex values; pass the magnitude or "
                        "real part, or the complex data as 'response'")
    return _as_vector(x, name, float, "numbers")


def _as_complex_vector(x, name):
    return _as_vector(x, name, complex, "complex numbers")


def _as_vector(x, name, dtype, what):
    """A one-dimensional copy of ``x`` as ``dtype`` (a scalar or a row/column counts as a
    vector); DataError naming ``name`` otherwise (``what``: the expected elements)."""
    try:
        arr = np.array(x, dtype=dtype, copy=True)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{name} must be an array of {what}: {exc}") from None
    if arr.ndim != 1:
        arr = arr.reshape(-1) if arr.ndim == 0 or max(arr.shape) == arr.size else arr
    if arr.ndim != 1:
        raise DataError(f"{name} must be one-dimensional, got shape {np.shape(x)}")
    return arr


# --------------------------------------------------------------------------- grids
def frequency_grid(omega):
    """The frequencies of ``omega`` (FrequencyData or array) as a checked float array.

    Parameters
    ----------
    omega : FrequencyData or array_like of float, shape (M,)

    Returns
    -------
    ndarray of float, shape (M,)

    Raises
    ------
    DataError
        Fewer than 2 values, a value not finite or <= 0, or not strictly increasing.
    """
    if isinstance(omega, FrequencyData):
        return omega.omega
    w = np.asarray(omega, float).reshape(-1)
    if w.size < 2 or not np.all(np.isfinite(w)) or np.any(w <= 0) or np.any(np.diff(w) <= 0):
        raise DataError("omega must hold >= 2 finite frequencies > 0 (rad/s), strictly "
                        "increasing; use FrequencyData.sorted()")
    return w


def dense_grid(omega, factor=10):
    """A log-spaced grid with ``factor`` x as many points over the range of ``omega``.

    Parameters
    ----------
    omega : FrequencyData or array_like of float, shape (M,)
        rad/s, >= 2 finite values > 0, strictly increasing.
    factor : int
        >= 1.

    Returns
    -------
    ndarray of float, shape (factor * M,)

    Raises
    ------
    DataError
        Bad ``omega``.
    OptionError
        Bad ``factor``.
    """
    w = frequency_grid(omega)
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
        raise OptionError(f"factor must be an integer >= 1, got {factor!r}")
    return np.logspace(math.log10(w[0]), math.log10(w[-1]), int(factor) * w.size)
