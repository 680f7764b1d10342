"""FRFs from any excitation: Welch cross-spectral H1/H2 estimates (layer L1).

A chirp, a random or an impulse test is not periodic, so its FRF is estimated from averaged
auto- and cross-spectra (Bendat & Piersol, *Random Data*, 4th ed., 2010, §9.2-9.3):
``H1 = S_uy / S_uu`` (unbiased by output noise), ``H2 = S_yy / S_yu`` (unbiased by input
noise), with the coherence ``gamma^2 = |S_uy|^2 / (S_uu S_yy)`` and the random error of the
estimate at every frequency.
"""

import numbers

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._common import (_REL_VAR_FLOOR, FrfEstimate, _as_count, _as_fraction, _as_fs, _as_pair,
                      _normalised, _rms)

__all__ = ["frf_from_records", "ESTIMATORS"]

#: Names of the cross-spectral estimators.
ESTIMATORS = ("h1", "h2")
_DETRENDS = ("constant", "linear", False)


def _check_options(n, fs, estimator, nperseg, noverlap, window, detrend, min_coherence):
    fs = _as_fs(fs, required=False)
    if estimator not in ESTIMATORS:
        raise OptionError(f"unknown estimator {estimator!r}; choose one of "
                          f"{', '.join(ESTIMATORS)} (h1: noise on the output, h2: on the input)")
    if nperseg is None:
        nperseg = 1 << max(3, int(np.log2(max(n // 8, 8))))
        nperseg = min(nperseg, n)
    nperseg = _as_count(nperseg, "nperseg", 8, OptionError)
    if nperseg > n:
        raise OptionError(f"nperseg={nperseg} is longer than the records ({n} samples); "
                          "give nperseg <= the record length (several segments to average)")
    noverlap = nperseg // 2 if noverlap is None else _as_count(noverlap, "noverlap", 0,
                                                                OptionError)
    if noverlap >= nperseg:
        raise OptionError(f"noverlap={noverlap} must be < nperseg={nperseg}")
    if detrend not in _DETRENDS:
        raise OptionError(f"detrend must be 'constant', 'linear' or False, got {detrend!r}")
    if min_coherence is not None and (isinstance(min_coherence, bool) or not isinstance(
            min_coherence, numbers.Real) or not 0 <= min_coherence < 1):
        raise OptionError(f"min_coherence must be a number in [0, 1), got {min_coherence!r}")
    try:
        import scipy.signal
        win = scipy.signal.get_window(window, nperseg)
    except (ValueError, TypeError) as exc:
        raise OptionError(f"window={window!r} is not a scipy.signal window ({exc}); use e.g. "
                          "'hann' or 'boxcar'") from None
    return fs, nperseg, noverlap, win


def _spectra(u, y, fs, win, nperseg, noverlap, detrend):
    import scipy.signal

    kw = dict(fs=fs, window=win, nperseg=nperseg, noverlap=noverlap, detrend=detrend,
              return_onesided=True, scaling="density")
    with np.errstate(all="ignore"):
        f, s_uu = scipy.signal.welch(u, **kw)
        _, s_yy = scipy.signal.welch(y, **kw)
        _, s_uy = scipy.signal.csd(u, y, **kw)          # E[conj(U) Y]
    for what, s in (("input", s_uu), ("output", s_yy), ("cross", s_uy)):
        if not np.all(np.isfinite(s)):
            raise DataError(f"the {what} spectrum overflows (samples too large to square, "
                            "max |u| = %.3g, max |y| = %.3g); rescale the records"
                            % (np.max(np.abs(u)), np.max(np.abs(y))))
    return f, s_uu.real, s_yy.real, s_uy


def frf_from_records(u, y, *, fs=None, estimator="h1", nperseg=None, noverlap=None,
                     window="hann", detrend="constant", min_coherence=None, name=None,
                     reference=None, threshold=1e-2):
    """Frequency response from input/output records of any excitation (Welch H1/H2).

    Parameters
    ----------
    u, y : array_like of float, shape (N,)
        Input and output records, equally long, finite, sampled at ``fs``.
    fs : float, optional
        Sampling frequency in Hz; None: the frequency axis is normalised, in rad/sample
        (``data.unit == "rad/sample"``, as :func:`frf_from_periodic` without ``fs``).
    estimator : {"h1", "h2"}, default "h1"
        ``H1 = S_uy / S_uu`` (noise on the output biases nothing), or ``H2 = S_yy / S_yu``
        (noise on the input biases nothing).
    nperseg : int, optional
        Samples per Welch segment (>= 8, <= N): the frequency resolution is ``fs/nperseg``
        Hz. Default: the largest power of two <= N/8 (about 15 averages with 50% overlap).
    noverlap : int, optional
        Overlap of the segments in samples (default ``nperseg // 2``).
    window : str or tuple, default "hann"
        A ``scipy.signal.get_window`` window.
    detrend : {"constant", "linear", False}, default "constant"
        Per-segment detrending.
    min_coherence : float in [0, 1), optional
        Keep only the frequencies where the coherence ``gamma^2 >= min_coherence`` (the
        band where the estimate is trustworthy).
    name : str, optional
        Name of the resulting :class:`FrequencyData`.
    reference : array_like of float, shape (N,), optional
        The excitation as generated: only the frequencies where its Welch spectrum is
        above ``threshold`` of its peak and at least half its stronger neighbour are kept
        (the lines a multisine excites, not the window's leakage beside them; the others
        hold noise only).
    threshold : float in (0, 1], default 1e-2
        Relative power of ``reference`` (-20 dB) above which a frequency counts as excited.

    Returns
    -------
    FrfEstimate
        ``data.omega`` in rad/s, or rad/sample without ``fs`` (the zero-frequency bin is
        dropped), ``data.response`` the
        estimate, ``data.weights`` ``|H|^2 / variance`` normalised to mean 1 (feed it to
        ``fit(weights=...)``); ``coherence``, ``variance``, ``bins`` (segment DFT bins),
        ``n_averages`` (segments), ``nperseg`` and ``estimator``.

    Raises
    ------
    DataError
        Bad records (unequal lengths, non-finite samples), a constant input, spectra that
        overflow, no frequency left above ``min_coherence``.
    OptionError
        Invalid ``fs``, ``estimator``, ``nperseg``, ``noverlap``, ``window``, ``detrend`` or
        ``min_coherence``.

    Notes
    -----
    Bendat & Piersol (2010), eq. 9.90 and Table 9.6: with ``n_d`` averages the normalised
    random error of ``|H|`` is ``eps = sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_d))``, i.e. the
    relative variance of ``|H|`` is ``(1 - gamma^2) / (2 n_d gamma^2)``; the phase has the
    same standard deviation in radians. ``variance`` is that of the complex estimate,
    ``E|H_hat - H|^2 = (1 - gamma^2) / (n_d gamma^2) |H|^2`` (magnitude plus phase part).
    ``n_d`` is the number of Welch segments; with overlapping segments they are not fully
    independent, so the variance is somewhat optimistic (about 10% with Hann and 50%).
    Frequencies where the input or output has no power (the estimate is undefined) are
    left out.
    """
    u, y = _as_pair(u, y)
    fs, nperseg, noverlap, win = _check_options(u.size, fs, estimator, nperseg, noverlap,
                                                window, detrend, min_coherence)
    if np.all(u == u.flat[0]):
        raise DataError(f"input u is constant (every sample = {u[0]!r}): there is no "
                        "excitation; check that the input channel was recorded")
    u, y, gain = _normalised(u, y)       # spectra of the scaled records; H times gain
    unit = "rad/s" if fs is not None else "rad/sample"
    fs_given, fs = fs, (1.0 if fs is None else fs)
    # the densities are scaled by 1/fs, which under- or overflows at an extreme fs: then
    # they are computed per sample (fs = 1; h and the coherence are ratios) and f scaled
    per_sample = not 1e-100 < fs < 1e100
    f, s_uu, s_yy, s_uy = _spectra(u, y, 1.0 if per_sample else fs, win, nperseg, noverlap,
                                   detrend)
    if per_sample:
        f = f * fs
    n_avg = 1 + (u.size - nperseg) // (nperseg - noverlap)
    bins = np.arange(f.size)
    with np.errstate(all="ignore"):
        h = s_uy / s_uu if estimator == "h1" else s_yy / np.conj(s_uy)
        coh = np.minimum(np.abs(s_uy) ** 2 / (s_uu * s_yy), 1.0)
        omega = 2 * np.pi * f
    keep = (bins > 0) & np.isfinite(h) & (h != 0) & np.isfinite(coh) & np.isfinite(omega)
    if min_coherence is not None:
        keep &= coh >= min_coherence
    if not keep.any():
        ok = (bins > 0) & np.isfinite(coh)
        best = float(coh[ok].max()) if ok.any() else 0.0
        if min_coherence is None:
            raise DataError("no frequency has a finite, nonzero response estimate (the output "
                            "does not follow the input, or the records' scales are extreme); "
                            "check the channels and rescale the records")
        raise DataError(
            f"no frequency has coherence >= {min_coherence} (highest {best:.8g}): the output "
            "does not follow the input; check the channels, lower --min-coherence or use "
            "longer segments")
    h, coh, omega, bins = h[keep], coh[keep], omega[keep], bins[keep]
    rel = np.maximum((1 - coh) / (n_avg * np.maximum(coh, 1e-300)), _REL_VAR_FLOOR)
    with np.errstate(over="ignore"):
        h = h * gain
        variance = rel * np.abs(h) ** 2
    if not (np.all(np.isfinite(h)) and np.all(np.isfinite(variance))):
        raise DataError("the estimated response (or its variance) overflows: output and input "
                        "differ by too many orders of magnitude; rescale the records")
    weights = 1.0 / rel
    weights = weights / weights.mean()
    data = FrequencyData(omega, h, name, weights, unit)
    est = FrfEstimate(data, bins, variance, coh, None, None, fs_given, n_avg, nperseg,
                      estimator)
    if reference is None:
        return est
    s_rr = _reference_power(reference, u.size, win, nperseg, noverlap, detrend)
    return est.subset(_excited(s_rr, _as_fraction(threshold, "threshold"))[bins])


def _excited(s_rr, threshold):
    """Frequencies a reference of Welch spectrum ``s_rr`` excites: above ``threshold`` of
    its peak and at least half as strong as its stronger neighbour (the window's leakage
    beside a multisine line, a quarter of it for Hann, is not a line)."""
    side = np.maximum(np.r_[0.0, s_rr[:-1]], np.r_[s_rr[1:], 0.0])
    return (s_rr > threshold * s_rr[1:].max()) & (s_rr >= 0.5 * side)


def _reference_power(reference, n, win, nperseg, noverlap, detrend):
    """Welch spectrum (per sample) of the reference, on the segments of the records."""
    r = np.asarray(reference, float).reshape(-1) if np.ndim(reference) else None
    if r is None or r.size != n or not np.all(np.isfinite(r)) or np.ptp(r) == 0:
        raise DataError(f"reference must be a finite, non-constant record as long as u ({n} "
                        f"samples), got shape {np.shape(reference)}; pass the generated "
                        "excitation signal")
    f, s_rr, _, _ = _spectra(r / _rms(r), r / _rms(r), 1.0, win, nperseg, noverlap, detrend)
    return np.real(s_rr)
