"""Shared pieces of the FRF estimators: the result object and the input checks (layer L1)."""

import math
import numbers
from dataclasses import dataclass

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, OptionError

__all__ = ["FrfEstimate"]

# Relative variance floor (machine precision squared): a noise-free estimate has a spread
# of ~eps*|G|, and the weights 1/var must stay finite.
_REL_VAR_FLOOR = np.finfo(float).eps ** 2


@dataclass(frozen=True)
class FrfEstimate:
    """A nonparametric frequency-response estimate from time-domain records.

    Attributes
    ----------
    data : FrequencyData
        ``omega`` in rad/s (rad/sample, i.e. normalised frequency, when ``fs`` is None),
        ``response`` the estimate ``G(j*omega)``, and ``weights`` ``|G|^2 / variance``
        (inverse variance of the relative estimate) normalised to mean 1 when at least two
        periods were averaged, else None.
    bins : ndarray of int, shape (M,) or None
        DFT bin indices ``k`` of the excited frequencies, ``omega = 2*pi*k/period * fs``
        (periodic excitation), or of the Welch segments' DFT, ``omega = 2*pi*k/nperseg *
        fs`` (:func:`frf_from_records`); None for a stepped sine.
    variance : ndarray of float, shape (M,) or None
        Estimated variance ``E|G_hat - G|^2`` of the complex estimate (variance of the mean
        over periods, or Bendat & Piersol's random error for Welch averages); None when
        there was only one period or for a stepped sine.
    coherence : ndarray of float, shape (M,) or None
        Magnitude-squared coherence ``|sum_p Y_p conj(U_p)|^2 / (sum_p |U_p|^2 sum_p
        |Y_p|^2)`` in [0, 1]; None with one period or for a stepped sine.
    n_periods : int or None
        Number of periods averaged (after the skipped transient periods); None for a
        stepped sine.
    period : int or None
        Samples per period; None for a stepped sine.
    fs : float or None
        Sampling frequency in Hz; None means normalised frequency (rad/sample).
    n_averages : int or None
        Welch segments averaged (:func:`frf_from_records`); None otherwise.
    nperseg : int or None
        Samples per Welch segment; None otherwise.
    estimator : str or None
        "h1" or "h2" for a Welch estimate, "periodic" or "stepped-sine" otherwise (None
        when built by hand).
    n_realisations : int or None
        Realisations averaged (:func:`frf_from_realisations`, two or more); None
        otherwise.
    noise_variance : ndarray of float, shape (M,) or None
        With realisations: the noise's share of ``variance`` (from the spread over the
        periods of each realisation; ``variance`` minus it is the nonlinear distortions'
        share, up to the estimates' scatter); None otherwise or with one period each.
    """

    data: FrequencyData
    bins: np.ndarray = None
    variance: np.ndarray = None
    coherence: np.ndarray = None
    n_periods: int = None
    period: int = None
    fs: float = None
    n_averages: int = None
    nperseg: int = None
    estimator: str = None
    n_realisations: int = None
    noise_variance: np.ndarray = None

    def __post_init__(self):
        for name in ("bins", "variance", "coherence", "noise_variance"):
            value = getattr(self, name)
            if value is not None:
                value = np.array(value, copy=True)
                value.setflags(write=False)
                object.__setattr__(self, name, value)

    def subset(self, keep):
        """The estimate at the frequencies ``keep`` selects (weights renormalised to mean 1).

        Parameters
        ----------
        keep : array_like of bool, shape (M,)

        Returns
        -------
        FrfEstimate

        Raises
        ------
        DataError
            ``keep`` selects no frequency.
        """
        import dataclasses

        keep = np.asarray(keep, bool)
        if not keep.any():
            raise DataError("no frequency of the estimate is left (the band or the "
                            "excitation selects none); widen the band or check the reference")
        d = self.data
        w = None if d.weights is None else d.weights[keep] / d.weights[keep].mean()
        data = FrequencyData(d.omega[keep], d.response[keep], d.name, w, d.unit)
        pick = {n: None if getattr(self, n) is None else getattr(self, n)[keep]
                for n in ("bins", "variance", "coherence", "noise_variance")}
        return dataclasses.replace(self, data=data, **pick)


# --------------------------------------------------------------------------- validation

def _as_signal(x, name):
    """A 1-D float copy of a time series; (N, 1) and (1, N) are flattened."""
    if isinstance(x, (str, bytes)):
        raise DataError(f"{name} must be an array of samples, got a {type(x).__name__}")
    raw = np.asarray(x)
    if np.iscomplexobj(raw):
        raise DataError(f"{name} must be a real time series, got complex values")
    try:
        arr = np.array(raw, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{name} must be an array of numbers: {exc}") from None
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise DataError(
            f"{name} must be one-dimensional (one channel), got shape {raw.shape}; pass one "
            "input and one output column (single-input single-output)")
    if arr.size == 0:
        raise DataError(f"{name} is empty: give the measured samples")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(
            f"{name} must be finite: {name}[{i}]={arr[i]} ({int(bad.sum())} non-finite "
            "sample(s)); repair or cut out the bad part of the record")
    return arr


def _as_pair(u, y, label=""):
    u = _as_signal(u, f"u{label}")
    y = _as_signal(y, f"y{label}")
    if u.size != y.size:
        raise DataError(
            f"input and output records must have equal lengths: len(u{label})={u.size}, "
            f"len(y{label})={y.size}; trim both to the common sampled span")
    return u, y


def _as_count(value, name, minimum, error=DataError):
    """An integer >= minimum; integral floats (e.g. 1024.0) are accepted."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f"{name} must be an integer, got {value!r}")
    if isinstance(value, numbers.Integral):
        n = int(value)
    else:
        if not math.isfinite(value) or value != math.floor(value):
            raise error(f"{name} must be an integer number of samples, got {value!r}")
        n = int(value)
    if n < minimum:
        raise error(f"{name} must be >= {minimum}, got {value!r}")
    return n


def _as_fs(fs, required):
    if fs is None:
        if required:
            raise OptionError("fs (sampling frequency, Hz) is required for a stepped sine")
        return None
    if isinstance(fs, bool) or not isinstance(fs, numbers.Real) or not math.isfinite(fs) \
            or fs <= 0:
        raise OptionError(f"fs must be a finite sampling frequency > 0 in Hz, got {fs!r}")
    if not math.isfinite(math.pi * fs):
        raise OptionError(f"fs={fs!r} Hz is too large: omega up to pi*fs rad/s overflows; give "
                          "the sampling frequency in Hz")
    return float(fs)


def _as_fraction(value, name, low_open=0.0, high=1.0):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not (low_open < value <= high):
        raise OptionError(f"{name} must be a number in ({low_open:g}, {high:g}], got {value!r}")
    return float(value)


def _pow2_scale(x):
    """A power of two near max|x| (1.0 for all zeros): dividing by it is exact. At most
    2^1023 (the largest power of two a float holds), so samples near the largest float
    (1.8e308) scale to at most 2 instead of overflowing the scale itself."""
    top = float(np.max(np.abs(x))) if np.size(x) else 0.0
    return 1.0 if top == 0 else math.ldexp(1.0, min(math.frexp(top)[1], 1023))


def _normalised(u, y):
    """``u / s_u``, ``y / s_y`` (powers of two near their max) and the gain ``s_y / s_u``
    that turns a ratio Y/U of the scaled records into that of the originals: the spectra
    never overflow or underflow, whatever the units of the records.

    Raises
    ------
    DataError
        The gain itself is outside the floating-point range.
    """
    su, sy = _pow2_scale(u), _pow2_scale(y)
    ku, ky = math.frexp(su)[1], math.frexp(sy)[1]
    if abs(ky - ku) > 1000:
        raise DataError(f"output and input differ by a factor 2^{ky - ku}: the response is "
                        "outside the floating-point range; rescale the records (same units)")
    return u / su, y / sy, math.ldexp(1.0, ky - ku)


def _rms(x):
    """Root mean square, safe from overflow and underflow of the squares."""
    s = _pow2_scale(x)
    return s * float(np.sqrt(np.mean(np.abs(x / s) ** 2)))


