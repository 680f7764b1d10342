"""From time-domain experiments to frequency-response data (layer L1, SPEC §7, thesis §2.4).

Two excitations are supported:

- **periodic** (multisine, periodic sweep): :func:`frf_from_periodic` cuts the records into
  whole periods, takes the DFT of each (thesis eq. 2.16 ff., ``X[k] = sum_n x[n]
  exp(-2j*pi*k*n/N)``) and averages ``G_p[k] = Y_p[k] / U_p[k]`` over the periods at the
  excited bins; the spread over the periods gives the variance of the estimate and the
  coherence.
- **stepped sine**: :func:`frf_stepped_sine` takes one record per frequency and projects
  input and output on the sine at that frequency (``G = Y / U``, thesis §2.4).

Both return a frozen :class:`FrfEstimate` whose ``data`` is a :class:`FrequencyData` ready
for the fitters. :func:`robot_arm` loads the DaISy flexible-robot-arm data set 96-009
(B. De Moor et al., DaISy: Database for the Identification of Systems, data set 96-009).
"""

import csv
import math
import numbers
import os
from dataclasses import dataclass

import numpy as np

from .data import FrequencyData, _check_file
from .errors import DataError, OptionError

__all__ = [
    "FrfEstimate",
    "frf_from_periodic",
    "frf_stepped_sine",
    "load_records_csv",
    "load_daisy",
    "robot_arm",
    "ROBOT_ARM_FILE",
    "SHARED_ENV",
]

#: Environment variable naming the shared directory that holds ``data/robot_arm.dat``.
SHARED_ENV = "FREQID_SHARED"
#: File name of the DaISy 96-009 data set inside ``shared/data``.
ROBOT_ARM_FILE = "robot_arm.dat"

# Relative variance floor (machine precision squared): a noise-free period average has a
# spread of ~eps*|G|, and the weights 1/var must stay finite.
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
        (periodic excitation); None for a stepped sine.
    variance : ndarray of float, shape (M,) or None
        Estimated variance ``E|G_hat - G|^2`` of the complex estimate (variance of the mean
        over periods); None when there was only one period or for a stepped sine.
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
    """

    data: FrequencyData
    bins: np.ndarray = None
    variance: np.ndarray = None
    coherence: np.ndarray = None
    n_periods: int = None
    period: int = None
    fs: float = None

    def __post_init__(self):
        for name in ("bins", "variance", "coherence"):
            value = getattr(self, name)
            if value is not None:
                value = np.array(value, copy=True)
                value.setflags(write=False)
                object.__setattr__(self, name, value)


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
    return float(fs)


def _as_fraction(value, name, low_open=0.0, high=1.0):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not (low_open < value <= high):
        raise OptionError(f"{name} must be a number in ({low_open:g}, {high:g}], got {value!r}")
    return float(value)


def _rms(x):
    return float(np.sqrt(np.mean(np.abs(x) ** 2)))


# --------------------------------------------------------------------------- periodic

def frf_from_periodic(u, y, period, *, fs=None, bins=None, skip_periods=0, threshold=1e-2,
                      allow_partial=False, periodic_rtol=0.2, name=None):
    """Frequency response from a periodic (multisine) experiment, averaged over periods.

    Parameters
    ----------
    u, y : array_like of float, shape (N,)
        Input and output records, equally long, finite, sampled at ``fs``.
    period : int
        Samples per period of the excitation (>= 2).
    fs : float, optional
        Sampling frequency in Hz. None (default): normalised frequency, ``omega`` in
        rad/sample.
    bins : array_like of int, optional
        DFT bins ``k`` (1 <= k <= period//2) to evaluate. Default: detected from the input
        spectrum averaged over the periods, ``|U[k]|^2 > threshold * max_k |U[k]|^2``, DC
        excluded.
    skip_periods : int, default 0
        Leading periods to discard as transient.
    threshold : float in (0, 1], default 1e-2
        Relative input power (-20 dB) above which a bin counts as excited.
    allow_partial : bool, default False
        Drop a trailing partial period instead of raising.
    periodic_rtol : float in (0, inf), default 0.2
        Largest allowed RMS difference between consecutive input periods, relative to the
        RMS of the (mean-removed) input; measurement noise on ``u`` must stay below it.
    name : str, optional
        Name of the resulting :class:`FrequencyData`.

    Returns
    -------
    FrfEstimate
        With ``n_periods = P`` periods averaged.

    Raises
    ------
    DataError
        Unequal lengths, non-finite samples, a non-integer or too small ``period``, records
        shorter than a period, a trailing partial period (unless ``allow_partial``), an
        input that is not periodic over ``period``, a constant input (no excitation), bins
        out of range or not excited, a zero estimate.
    OptionError
        Invalid ``fs``, ``skip_periods``, ``threshold`` or ``periodic_rtol``.

    Notes
    -----
    SPEC §7, thesis §2.4. With ``X_p[k] = sum_{n<N} x[pN+n] exp(-2j pi k n / N)``::

        G_hat[k] = (1/P) sum_p Y_p[k] / U_p[k]
        var[k]   = sum_p |Y_p/U_p - G_hat|^2 / (P (P - 1))     (variance of the mean)

    With white output noise of variance s^2 and a noise-free periodic input,
    ``E var[k] = N s^2 / (P |U[k]|^2)``. ``omega = 2 pi k / N * fs`` (rad/s) or
    ``2 pi k / N`` (rad/sample).
    """
    u, y = _as_pair(u, y)
    period = _as_count(period, "period", 2)
    fs = _as_fs(fs, required=False)
    skip_periods = _as_count(skip_periods, "skip_periods", 0, OptionError)
    threshold = _as_fraction(threshold, "threshold")
    if isinstance(periodic_rtol, bool) or not isinstance(periodic_rtol, numbers.Real) \
            or not periodic_rtol > 0:
        raise OptionError(f"periodic_rtol must be a number > 0, got {periodic_rtol!r}")
    n = u.size
    if n < period:
        raise DataError(
            f"records are too short: {n} samples < one period of {period} samples; record "
            "at least one whole period (several, to average and estimate the noise), or "
            "check the period")
    n_whole, leftover = divmod(n, period)
    if leftover and not allow_partial:
        raise DataError(
            f"record length {n} is not a multiple of period {period}: {leftover} samples are "
            f"left over after {n_whole} whole period(s); trim the records to "
            f"{n_whole * period} samples, give the right period, or pass allow_partial=True "
            "to drop the trailing partial period")
    if n_whole <= skip_periods:
        raise DataError(
            f"skip_periods={skip_periods} leaves no period to average: the records hold "
            f"only {n_whole} whole period(s) of {period} samples; lower skip_periods or "
            "record longer")
    u_used = u[skip_periods * period:n_whole * period].reshape(-1, period)
    y_used = y[skip_periods * period:n_whole * period].reshape(-1, period)
    n_periods = u_used.shape[0]
    if np.ptp(u) == 0:
        raise DataError(
            f"input u is constant (every sample = {u[0]!r}): there is no excitation; check "
            "that the input channel was recorded")
    if np.ptp(u_used) == 0:
        raise DataError(
            "input u is constant over the periods kept after skip_periods: there is no "
            "excitation there; lower skip_periods")
    if n_periods >= 2:
        scale = _rms(u_used - u_used.mean())
        jumps = np.sqrt(np.mean(np.diff(u_used, axis=0) ** 2, axis=1)) / scale
        worst = int(np.argmax(jumps))
        if jumps[worst] > periodic_rtol:
            raise DataError(
                f"input is not periodic with period {period}: period #{skip_periods + worst + 2}"
                f" differs from period #{skip_periods + worst + 1} by {100 * jumps[worst]:.3g}% "
                f"RMS (tolerance {100 * periodic_rtol:.3g}%); check --period (the samples per "
                "period of the excitation) or raise periodic_rtol for a noisy input")
    n_half = period // 2
    U = np.fft.fft(u_used, axis=1)[:, :n_half + 1]
    Y = np.fft.fft(y_used, axis=1)[:, :n_half + 1]
    if bins is None:
        power = np.abs(U.mean(axis=0)) ** 2
        power[0] = 0.0
        top = power.max()
        if top == 0:
            raise DataError(
                f"input has no power at any nonzero DFT bin over period {period}: there is "
                "no excitation; check the input channel and the period")
        bins = np.flatnonzero(power > threshold * top)
    else:
        bins = _as_bins(bins, n_half)
    U_b, Y_b = U[:, bins], Y[:, bins]
    zero = U_b == 0
    if zero.any():
        p, j = (int(i[0]) for i in np.nonzero(zero))
        raise DataError(
            f"input has no power at bin {bins[j]} in period #{skip_periods + p + 1}: that bin is "
            "not excited; remove it from bins")
    H = Y_b / U_b
    G = H.mean(axis=0)
    zero = G == 0
    if zero.any():
        j = int(np.flatnonzero(zero)[0])
        raise DataError(
            f"estimated response is exactly zero at bin {bins[j]}: the output has no "
            "component there; check the output channel or remove that bin")
    variance = coherence = weights = None
    if n_periods >= 2:
        variance = np.sum(np.abs(H - G) ** 2, axis=0) / (n_periods * (n_periods - 1))
        cross = np.abs(np.sum(Y_b * np.conj(U_b), axis=0)) ** 2
        auto = np.sum(np.abs(U_b) ** 2, axis=0) * np.sum(np.abs(Y_b) ** 2, axis=0)
        coherence = np.minimum(cross / auto, 1.0)
        rel = np.maximum(variance / np.abs(G) ** 2, _REL_VAR_FLOOR)
        weights = 1.0 / rel
        weights = weights / weights.mean()
    omega = 2.0 * np.pi * bins / period * (1.0 if fs is None else fs)
    data = FrequencyData(omega, G, name, weights)
    return FrfEstimate(data, bins, variance, coherence, n_periods, period, fs)


def _as_bins(bins, n_half):
    raw = np.asarray(bins)
    if raw.ndim == 0:
        raw = raw.reshape(1)
    if raw.ndim != 1 or raw.size == 0:
        raise DataError(f"bins must be a non-empty 1-D list of DFT bin indices, got {bins!r}")
    if raw.dtype.kind not in "iu":
        if raw.dtype.kind != "f" or not np.all(np.isfinite(raw)) \
                or np.any(raw != np.floor(raw)):
            raise DataError(f"bins must be integer DFT bin indices, got {bins!r}")
    k = raw.astype(np.int64)
    bad = (k < 1) | (k > n_half)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(
            f"bins[{i}]={k[i]} is out of range: bins must be in 1..{n_half} (period//2; DC "
            "is not used)")
    k = np.unique(k)
    if k.size != raw.size:
        raise DataError("bins contains duplicates; list each DFT bin once")
    return k


def _detect_period(u, rtol):
    """Shortest divisor d of len(u) over which u repeats (relative RMS difference between
    consecutive blocks <= rtol); len(u) itself when none does."""
    n = u.size
    scale = _rms(u - u.mean())
    for d in range(2, n // 2 + 1):
        if n % d:
            continue
        blocks = u.reshape(-1, d)
        jumps = np.sqrt(np.mean(np.diff(blocks, axis=0) ** 2, axis=1)) / scale
        if jumps.max() <= rtol:
            return d
    return n


# --------------------------------------------------------------------------- stepped sine

def frf_stepped_sine(records, *, fs, frequencies, n_skip=0, sine_rtol=0.5, name=None):
    """Frequency response from a stepped-sine experiment, one record per frequency.

    Parameters
    ----------
    records : sequence of (u, y) pairs of array_like of float
        Input and output records (equal lengths within a pair), one pair per frequency;
        the input is a sine at that frequency.
    fs : float
        Sampling frequency in Hz.
    frequencies : array_like of float, shape (M,)
        Excitation frequency of each record in Hz, 0 < f < fs/2, distinct (any order; the
        result is sorted).
    n_skip : int or sequence of int, default 0
        Leading samples of each record (or per record) to discard as transient.
    sine_rtol : float in (0, 1], default 0.5
        Largest RMS residual of the input after removing the fitted sine and offset,
        relative to the input's RMS; above it the input is not a sine at that frequency.
    name : str, optional
        Name of the resulting :class:`FrequencyData`.

    Returns
    -------
    FrfEstimate
        ``omega = 2 pi f`` in rad/s; ``bins``, ``variance``, ``coherence``, ``n_periods``
        and ``period`` are None.

    Raises
    ------
    DataError
        Bad records (as in :func:`frf_from_periodic`), fewer than one whole cycle after
        ``n_skip``, a frequency not in (0, fs/2) or repeated, an input that is not a sine
        at its frequency.
    OptionError
        Invalid ``fs``, ``n_skip`` or ``sine_rtol``.

    Notes
    -----
    Thesis §2.4: ``G(j omega) = Y / U``. After ``n_skip`` samples the longest whole number
    of cycles ``c = floor(L f / fs)`` is kept (``floor(c fs / f)`` samples) and each signal
    is fitted by least squares as ``x[n] = Re(X exp(j omega n / fs)) + d`` (the
    three-parameter sine fit). Over an integer number of cycles in samples this is the
    projection ``X = (2/L) sum_n x[n] exp(-j omega n / fs)``; otherwise it also removes the
    leakage of the negative-frequency term and of the offset.
    """
    fs = _as_fs(fs, required=True)
    sine_rtol = _as_fraction(sine_rtol, "sine_rtol")
    try:
        records = list(records)
    except TypeError:
        raise DataError("records must be a sequence of (u, y) pairs, one per frequency") \
            from None
    freqs = np.asarray(frequencies)
    if np.iscomplexobj(freqs) or freqs.dtype.kind not in "iuf":
        raise DataError(f"frequencies must be real numbers in Hz, got {frequencies!r}")
    freqs = freqs.astype(float).reshape(-1)
    if not records:
        raise DataError("records is empty: give one (u, y) pair per frequency")
    if freqs.size != len(records):
        raise DataError(
            f"one frequency per record: len(frequencies)={freqs.size}, "
            f"len(records)={len(records)}")
    bad = ~np.isfinite(freqs) | (freqs <= 0) | (freqs >= fs / 2)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(
            f"frequencies[{i}]={freqs[i]} Hz must be in (0, fs/2) = (0, {fs / 2:g}) Hz; "
            "give frequencies in Hz below the Nyquist frequency")
    order = np.argsort(freqs, kind="stable")
    dup = np.diff(freqs[order]) == 0
    if dup.any():
        i = int(order[np.flatnonzero(dup)[0] + 1])
        raise DataError(
            f"frequencies[{i}]={freqs[i]} Hz is repeated; average those records first or "
            "drop one")
    if isinstance(n_skip, numbers.Real) and not isinstance(n_skip, bool):
        skips = [_as_count(n_skip, "n_skip", 0, OptionError)] * len(records)
    else:
        try:
            skips = [_as_count(s, f"n_skip[{i}]", 0, OptionError) for i, s in enumerate(n_skip)]
        except TypeError:
            raise OptionError(f"n_skip must be an int or one int per record, got {n_skip!r}") \
                from None
        if len(skips) != len(records):
            raise OptionError(
                f"n_skip must have one value per record: len(n_skip)={len(skips)}, "
                f"len(records)={len(records)}")
    response = np.empty(len(records), complex)
    for i, rec in enumerate(records):
        try:
            u, y = rec
        except (TypeError, ValueError):
            raise DataError(f"records[{i}] must be a (u, y) pair") from None
        u, y = _as_pair(u, y, f"[{i}]")
        response[i] = _sine_ratio(u, y, freqs[i], fs, skips[i], i, sine_rtol)
    zero = response == 0
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        raise DataError(
            f"estimated response is exactly zero for records[{i}] ({freqs[i]} Hz): the output "
            "has no component at that frequency; check the output channel")
    data = FrequencyData(2.0 * np.pi * freqs[order], response[order], name)
    return FrfEstimate(data, None, None, None, None, None, fs)


def _sine_ratio(u, y, f, fs, n_skip, i, sine_rtol):
    """Y/U from the least-squares sine fit over the longest whole number of cycles."""
    n = u.size
    samples_per_cycle = fs / f
    avail = n - n_skip
    cycles = math.floor(avail / samples_per_cycle * (1 + 1e-12))
    if cycles < 1:
        raise DataError(
            f"records[{i}] at {f:g} Hz: {avail} samples remain after n_skip={n_skip}, fewer "
            f"than one cycle ({samples_per_cycle:.6g} samples); record longer or lower n_skip")
    length = min(avail, math.floor(cycles * samples_per_cycle * (1 + 1e-12)))
    idx = np.arange(n_skip, n_skip + length)
    phase = 2.0 * np.pi * f / fs * idx
    basis = np.column_stack([np.cos(phase), np.sin(phase), np.ones(length)])
    coef, *_ = np.linalg.lstsq(basis, np.column_stack([u[idx], y[idx]]), rcond=None)
    ua, ub = coef[0, 0], coef[1, 0]
    ya, yb = coef[0, 1], coef[1, 1]
    U = ua - 1j * ub   # x = a cos + b sin = Re((a - j b) exp(j phase))
    Y = ya - 1j * yb
    u_win = u[idx]
    scale = _rms(u_win - u_win.mean())
    if U == 0 or scale == 0:
        raise DataError(
            f"records[{i}]: the input has no component at {f:g} Hz (no excitation); check "
            "the input channel and the frequency")
    resid = _rms(u_win - basis @ coef[:, 0]) / scale
    if resid > sine_rtol:
        raise DataError(
            f"records[{i}]: the input is not a sine at {f:g} Hz ({100 * resid:.3g}% of its RMS "
            f"is left after removing that sine; tolerance {100 * sine_rtol:.3g}%); check "
            "frequencies (in Hz) and fs")
    return Y / U


# --------------------------------------------------------------------------- loaders

def _read_lines(path):
    path = _check_file(path)
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            return path, fh.read().splitlines()
    except UnicodeDecodeError:
        raise DataError(f"{path!r} is not a text file (not UTF-8)") from None
    except OSError as exc:
        raise DataError(f"cannot read {path!r}: {exc.strerror}") from None


def _parse_cell(path, line, column, cell):
    try:
        value = float(cell)
    except ValueError:
        raise DataError(
            f"{path!r} line {line}, column {column!r}: {cell.strip()!r} is not a number") \
            from None
    if not math.isfinite(value):
        raise DataError(
            f"{path!r} line {line}, column {column!r}: {cell.strip()!r} is not finite; "
            "repair or cut out the bad samples")
    return value


def load_records_csv(path):
    """Read an input/output record from a CSV file with the header ``u,y``.

    Lines starting with ``#`` are comments; the header is case-insensitive.

    Returns
    -------
    u, y : ndarray of float, shape (N,)
        Input and output samples.

    Raises
    ------
    DataError
        Missing file, directory, not UTF-8, bad header, wrong column count, non-numeric or
        non-finite cells, no data rows.
    """
    path, lines = _read_lines(path)
    rows = [r for r in csv.reader(lines) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise DataError(f"{path!r} is empty: expected a header 'u,y' and data rows")
    header = [h.strip().lower() for h in rows[0]]
    if header != ["u", "y"]:
        raise DataError(
            f"{path!r}: unrecognised header {','.join(rows[0])!r}; the first line must be "
            "'u,y' (input, output)")
    if len(rows) < 2:
        raise DataError(f"{path!r} has a header but no data rows")
    values = np.empty((len(rows) - 1, 2))
    for k, row in enumerate(rows[1:]):
        line = k + 2
        if len(row) != 2:
            raise DataError(f"{path!r} line {line}: expected 2 columns (u,y), got {len(row)}")
        for j, cell in enumerate(row):
            values[k, j] = _parse_cell(path, line, header[j], cell)
    return values[:, 0].copy(), values[:, 1].copy()


def load_daisy(path, columns=(0, 1)):
    """Read a DaISy-style whitespace-separated data file (one sample per line).

    Parameters
    ----------
    path : str or path-like
        The ``.dat`` file; blank lines and lines starting with ``#`` or ``%`` are skipped.
    columns : (int, int), default (0, 1)
        Zero-based columns of the input and the output.

    Returns
    -------
    u, y : ndarray of float, shape (N,)

    Raises
    ------
    DataError
        Missing or unreadable file, no data, ragged rows, too few columns, non-numeric or
        non-finite values.
    """
    try:
        cu, cy = (_index(c) for c in columns)
    except (TypeError, ValueError):
        raise OptionError(f"columns must be two column indices, got {columns!r}") from None
    if cu < 0 or cy < 0:
        raise OptionError(f"columns must be >= 0, got {columns!r}")
    path, lines = _read_lines(path)
    data, width = [], None
    for k, text in enumerate(lines):
        cells = text.split()
        if not cells or cells[0].startswith(("#", "%")):
            continue
        line = k + 1
        if width is None:
            width = len(cells)
            if width <= max(cu, cy):
                raise DataError(
                    f"{path!r} line {line}: {width} column(s), but columns={tuple(columns)} "
                    "needs the input and output columns; check the file or columns")
        elif len(cells) != width:
            raise DataError(
                f"{path!r} line {line}: {len(cells)} columns, expected {width} as on the first "
                "data line")
        data.append([_parse_cell(path, line, f"column {j}", c) for j, c in enumerate(cells)])
    if not data:
        raise DataError(f"{path!r} holds no data lines: expected columns input output")
    values = np.array(data)
    return values[:, cu].copy(), values[:, cy].copy()


def _index(value):
    """operator.index that rejects bools."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(value)
    return int(value)


# --------------------------------------------------------------------------- robot arm

def _find_robot_arm():
    env = os.environ.get(SHARED_ENV)
    if env:
        candidates = [os.path.join(env, "data", ROBOT_ARM_FILE), os.path.join(env, ROBOT_ARM_FILE)]
        for c in candidates:
            if os.path.isfile(c):
                return c
        raise DataError(
            f"{SHARED_ENV}={env!r} holds neither data/{ROBOT_ARM_FILE} nor {ROBOT_ARM_FILE}; "
            f"set {SHARED_ENV} to the shared directory (the one containing data/) or pass "
            "path=")
    tried = []
    for start in (os.getcwd(), os.path.dirname(os.path.abspath(__file__))):
        folder = os.path.abspath(start)
        while True:
            c = os.path.join(folder, "shared", "data", ROBOT_ARM_FILE)
            if os.path.isfile(c):
                return c
            tried.append(c)
            parent = os.path.dirname(folder)
            if parent == folder:
                break
            folder = parent
    raise DataError(
        f"cannot find shared/data/{ROBOT_ARM_FILE} above the working directory or the "
        f"package (first tried {tried[0]!r}); set the environment variable {SHARED_ENV} to "
        "the shared directory or pass path= to robot_arm()")


def robot_arm(path=None):
    """Frequency response of the DaISy flexible robot arm (data set 96-009).

    Input: measured reaction torque (column 1); output: arm acceleration (column 2); 1024
    samples of a periodic excitation on the odd DFT bins. The sampling time is not given,
    so ``omega`` is normalised (rad/sample).

    Parameters
    ----------
    path : str or path-like, optional
        The ``robot_arm.dat`` file. Default: ``$FREQID_SHARED/data/robot_arm.dat``, else
        ``shared/data/robot_arm.dat`` in the first ancestor of the working directory or of
        this package that has one.

    Returns
    -------
    FrfEstimate
        One period of 1024 samples (``n_periods = 1``, so ``variance``, ``coherence`` and
        the weights are None) at the odd bins ``1, 3, ..., K``.

    Raises
    ------
    DataError
        The file cannot be found or read, or is malformed.

    Notes
    -----
    The period is taken from the data: the shortest divisor of the record length over which
    the input repeats (within 20% RMS). No shorter period than 1024 does: the input is
    *anti*-periodic over 512 samples (``u[n + 512] ~ -u[n]``, 6% RMS residual), the
    signature of an odd-bin excitation. The band ``K`` is the highest odd bin whose input
    power is within 20 dB of the maximum (K = 201); every odd bin below it is kept,
    including the dip of the measured torque near bins 57-61 at the arm's first resonance,
    where the FRF stays smooth. The even bins carry only noise and distortion (< -22 dB).
    Cite: B. De Moor et al., DaISy: Database for the Identification of Systems, 96-009.
    """
    path = _find_robot_arm() if path is None else path
    u, y = load_daisy(path)
    period = _detect_period(u, 0.2)
    probe = frf_from_periodic(u, y, period)
    top = int(probe.bins.max())
    bins = np.arange(1, top + 1, 2) if np.all(probe.bins % 2 == 1) else probe.bins
    return frf_from_periodic(u, y, period, bins=bins,
                             name="robot_arm (DaISy 96-009)")
