"""FRFs from periodic and stepped-sine experiments (layer L1, SPEC §7, thesis §2.4).

- **periodic** (multisine, periodic sweep): :func:`frf_from_periodic` cuts the records into
  whole periods, takes the DFT of each (thesis eq. 2.16 ff., ``X[k] = sum_n x[n]
  exp(-2j*pi*k*n/N)``) and averages ``G_p[k] = Y_p[k] / U_p[k]`` over the periods at the
  excited bins; the spread over the periods gives the variance of the estimate and the
  coherence.
- **stepped sine**: :func:`frf_stepped_sine` takes one record per frequency and projects
  input and output on the sine at that frequency (``G = Y / U``, thesis §2.4).
"""

import math
import numbers

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._common import (_REL_VAR_FLOOR, FrfEstimate, _as_count, _as_fraction, _as_fs, _as_pair,
                      _normalised, _rms)

__all__ = ["frf_from_periodic", "frf_stepped_sine", "excitation_gaps"]

# --------------------------------------------------------------------------- periodic

def frf_from_periodic(u, y, period, *, fs=None, bins=None, skip_periods=0, threshold=1e-2,
                      allow_partial=False, periodic_rtol=0.2, name=None, reference=None):
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
        DFT bins ``k`` (1 <= k <= period//2) to evaluate. Default: the excited lines,
        detected from the spectrum averaged over the periods of ``reference`` (if given)
        or of the input: ``|U[k]|^2 > threshold * max_k |U[k]|^2``, DC excluded, and (with
        two or more periods, from the input) ``|U[k]|^2`` above 10 times the variance of its
        mean over the periods, so a line that holds only the input's noise is not taken
        for an excited one.
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
    reference : array_like of float, shape (N,) or (period,), optional
        The excitation as generated (the multisine sent to the shaker or amplifier), whose
        nonzero lines are the excited bins; the measured input ``u`` may hold noise at the
        other lines. One period of it (a generator's table) is repeated.

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
    if np.all(u == u.flat[0]):
        raise DataError(
            f"input u is constant (every sample = {u[0]!r}): there is no excitation; check "
            "that the input channel was recorded")
    if np.all(u_used == u_used.flat[0]):
        raise DataError(
            "input u is constant over the periods kept after skip_periods: there is no "
            "excitation there; lower skip_periods")
    u_used, y_used, gain = _normalised(u_used, y_used)
    if n_periods >= 2:
        _check_periodic(u_used, period, skip_periods, periodic_rtol)
    n_half = period // 2
    with np.errstate(over="ignore", invalid="ignore"):
        U = np.fft.fft(u_used, axis=1)[:, :n_half + 1]
        Y = np.fft.fft(y_used, axis=1)[:, :n_half + 1]
    _check_finite_spectra(U, Y, u, y)
    if bins is None:
        bins = _excited_bins(U, _reference_spectrum(reference, u.size, period, skip_periods,
                                                    n_half), threshold, period)
    else:
        bins = _as_bins(bins, n_half)
    U_b, Y_b = U[:, bins], Y[:, bins]
    _check_excited(U, bins, skip_periods)
    H = Y_b / U_b                        # of the scaled records; times gain below
    G = H.mean(axis=0)
    _check_nonzero(G, lambda j: f"at bin {bins[j]}: the output has no component there; "
                                "check the output channel or remove that bin")
    variance = coherence = weights = None
    if n_periods >= 2:
        variance = np.sum(np.abs(H - G) ** 2, axis=0) / (n_periods * (n_periods - 1))
        cross = np.abs(np.sum(Y_b * np.conj(U_b), axis=0)) ** 2
        auto = np.sum(np.abs(U_b) ** 2, axis=0) * np.sum(np.abs(Y_b) ** 2, axis=0)
        coherence = np.minimum(cross / auto, 1.0)
        rel = np.maximum(variance / np.abs(G) ** 2, _REL_VAR_FLOOR)
        weights = 1.0 / rel
        weights = weights / weights.mean()
    G, variance = _unscale(G, variance, gain)
    omega = 2.0 * np.pi * bins / period * (1.0 if fs is None else fs)
    data = FrequencyData(omega, G, name, weights, "rad/s" if fs is not None else "rad/sample")
    return FrfEstimate(data, bins, variance, coherence, n_periods, period, fs,
                       estimator="periodic")


def _reference_spectrum(reference, n, period, skip_periods, n_half):
    """DFT of each kept period of ``reference`` (shape (P, n_half + 1)), or None."""
    if reference is None:
        return None
    r = np.asarray(reference, float).reshape(-1) if np.ndim(reference) else None
    if r is not None and r.size == period and n > period:   # a generator's one period
        r = np.tile(r, n // period + 1)[:n]
    if r is None or r.size != n:
        raise DataError(f"reference must be a record as long as u ({n} samples) or one "
                        f"period ({period}), got shape {np.shape(reference)}; pass the "
                        "generated excitation signal")
    if not np.all(np.isfinite(r)):
        raise DataError("reference holds non-finite samples; repair or cut out the bad "
                        "samples")
    n_whole = n // period
    return np.fft.fft(r[skip_periods * period:n_whole * period].reshape(-1, period),
                      axis=1)[:, :n_half + 1]


def _excited_bins(U, R, threshold, period):
    """Excited DFT bins: lines of the reference ``R`` (or of the input ``U``, each shape
    (P, n_half + 1)) above ``threshold`` of the strongest; from the input with P >= 2 also
    10 times above the variance of the mean over the periods (a line of noise only)."""
    X = U if R is None else R
    mean = X.mean(axis=0)
    power = np.abs(mean) ** 2
    power[0] = 0.0
    top = power.max()
    if top == 0:
        raise DataError(
            f"{'reference' if R is not None else 'input'} has no power at any nonzero DFT "
            f"bin over period {period}: there is no excitation; check the "
            f"{'reference' if R is not None else 'input channel'} and the period")
    keep = power > threshold * top
    if R is None and X.shape[0] >= 2:
        noise = np.sum(np.abs(X - mean) ** 2, axis=0) / (X.shape[0] * (X.shape[0] - 1))
        keep &= power > 10 * noise
    return np.flatnonzero(keep)


def excitation_gaps(u, period, bins, *, skip_periods=0):
    """Lines of the excitation's grid left out inside the band, with the input's level.

    The excited bins of a multisine usually lie on a grid (every odd bin, every 4th ...).
    A measured input (a force, a torque) dips at a resonance of the structure it drives,
    and a line there can fall below the detection threshold although it was excited;
    an odd-random multisine leaves lines out on purpose (to detect distortions). This
    lists the grid's lines between the first and the last bin kept that are not among
    ``bins``, so the caller can say which.

    Parameters
    ----------
    u : array_like of float, shape (N,)
        The input record (whole periods after ``skip_periods`` are used).
    period : int
        Samples per period.
    bins : array_like of int, shape (K,)
        The bins kept (increasing).
    skip_periods : int, optional
        Leading periods left out.

    Returns
    -------
    step : int
        The grid's step (the greatest common divisor of the kept bins' spacings; 0 when
        fewer than 3 bins are kept or the step is 1).
    gaps : list of (int, float)
        Each missing line's bin and the input's power there in dB relative to the
        strongest line (averaged over the periods).
    """
    bins = np.asarray(bins, int).reshape(-1)
    if bins.size < 3:
        return 0, []
    step = int(np.gcd.reduce(np.diff(bins)))
    if step < 2:
        return 0, []
    grid = np.arange(bins[0], bins[-1] + 1, step)
    missing = np.setdiff1d(grid, bins)
    if not missing.size:
        return step, []
    u = np.asarray(u, float).reshape(-1)
    n_whole = u.size // period
    periods = u[skip_periods * period:n_whole * period].reshape(-1, period)
    power = np.abs(np.fft.rfft(periods, axis=1).mean(axis=0)) ** 2
    top = float(np.max(power[1:]))
    with np.errstate(divide="ignore"):
        level = 10.0 * np.log10(power[missing] / top)
    return step, [(int(k), float(v)) for k, v in zip(missing, level)]


def _check_finite_spectra(U, Y, u, y):
    """DataError when the DFT of a period overflowed (not finite): it names the cause."""
    for what, s, x in (("input", U, u), ("output", Y, y)):
        if not np.all(np.isfinite(s)):
            raise DataError(f"the FFT of the {what} record overflows (max |u| = "
                            f"{float(np.max(np.abs(u))):.3g}, max |y| = "
                            f"{float(np.max(np.abs(y))):.3g}); rescale the records")


def _check_nonzero(response, where):
    """DataError at the first exact zero of ``response`` (complex, shape (M,)): the message
    is "estimated response is exactly zero " + ``where(index)``."""
    zero = np.flatnonzero(response == 0)
    if zero.size:
        raise DataError(f"estimated response is exactly zero {where(int(zero[0]))}")


def _unscale(G, variance, gain):
    """The estimate and its variance in the records' units (G * gain, variance * gain^2)."""
    with np.errstate(over="ignore"):
        G = G * gain
        variance = None if variance is None else variance * np.float64(gain) ** 2
    if not np.all(np.isfinite(G)) or (variance is not None
                                      and not np.all(np.isfinite(variance))):
        raise DataError("the estimated response (or its variance) overflows: output and input "
                        "differ by too many orders of magnitude; rescale the records")
    return G, variance


def _check_periodic(u_used, period, skip_periods, periodic_rtol):
    """DataError when consecutive periods (rows of ``u_used``) differ by > periodic_rtol."""
    scale = _rms(u_used - u_used.mean())
    jumps = np.sqrt(np.mean(np.diff(u_used, axis=0) ** 2, axis=1)) / scale
    worst = int(np.argmax(jumps))
    if jumps[worst] > periodic_rtol:
        # each period minus the one before (an odd multisine, x(t + N) = -x(t)): every
        # jump is 200 %, and the period is twice the one given
        sums = np.sqrt(np.mean((u_used[1:] + u_used[:-1]) ** 2, axis=1)) / scale
        hint = (f"; each period is minus the one before (an odd multisine, anti-periodic "
                f"at {period}): its period is {2 * period}, pass --period {2 * period}"
                if sums.size and np.max(sums) <= periodic_rtol else
                "; check --period (the samples per period of the excitation), or raise "
                "the tolerance for a noisy input (periodic_rtol= of frf_from_periodic)")
        raise DataError(
            f"input is not periodic with period {period}: period #{skip_periods + worst + 2}"
            f" differs from period #{skip_periods + worst + 1} by {100 * jumps[worst]:.3g}% "
            f"RMS (tolerance {100 * periodic_rtol:.3g}%){hint}")


#: Input power at a bin, relative to the strongest nonzero bin, below which the bin counts
#: as not excited (round-off of an unexcited bin is ~1e-30; a real excitation is far above).
_UNEXCITED = 1e-12


def _check_excited(U, bins, skip_periods):
    """DataError at a bin with no input power in some period (or round-off only)."""
    power = np.abs(U) ** 2
    top = power[:, 1:].max(axis=1, keepdims=True) if power.shape[1] > 1 else power
    low = power[:, bins] <= _UNEXCITED * top
    if low.any():
        p, j = (int(i[0]) for i in np.nonzero(low))
        rel = float(power[p, bins[j]] / top[p, 0]) if top[p, 0] > 0 else 0.0
        raise DataError(
            f"input has no power at bin {bins[j]} in period #{skip_periods + p + 1} (|U|^2 is "
            f"{rel:.3g} of the strongest bin, below {_UNEXCITED:g}): that bin is not "
            "excited; remove it from bins")


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
    _check_nonzero(response, lambda i: f"for records[{i}] ({freqs[i]} Hz): the output has no "
                                       "component at that frequency; check the output channel")
    data = FrequencyData(2.0 * np.pi * freqs[order], response[order], name)
    return FrfEstimate(data, None, None, None, None, None, fs, estimator="stepped-sine")


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
    u, y, gain = _normalised(u[idx], y[idx])
    idx = np.arange(length)
    coef, *_ = np.linalg.lstsq(basis, np.column_stack([u, y]), rcond=None)
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
    return Y / U * gain
