"""Several realisations of a periodic experiment, averaged (layer L1, SPEC §7).

A multisine test is often repeated with new random phases (a "realisation"), each
recorded over several periods: the spread over the periods of one realisation is the
noise, the spread over the realisations is the noise and the nonlinear distortions the
phases move about (the robust method of Pintelon and Schoukens, System Identification: A
Frequency Domain Approach, 2nd ed., sec. 3.8). :func:`frf_from_realisations` estimates
each realisation with :func:`~freqid_casadi.experiment.periodic.frf_from_periodic` and
averages them, bin by bin over the realisations that excite it.
"""

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError
from ._common import _REL_VAR_FLOOR, FrfEstimate
from .periodic import frf_from_periodic

__all__ = ["frf_from_realisations"]


def _rows(x, name):
    """``x`` as a list of 1-D float arrays (the rows of an (R, N) array, or a sequence of
    R vectors; a vector is one realisation)."""
    shape = np.shape(x) if isinstance(x, np.ndarray) else None
    if shape is not None and len(shape) == 1:
        return [np.asarray(x, float)]
    try:
        rows = [np.asarray(r, float) for r in x]
    except (TypeError, ValueError):
        raise DataError(f"{name} must be R records (an R x N array or a list of R "
                        f"vectors), got {type(x).__name__}") from None
    if not rows:
        raise DataError(f"{name} holds no realisation")
    bad = next((r.shape for r in rows if r.ndim != 1 and r.size != max(r.shape, default=0)),
               None)
    if bad is not None:
        shown = " x ".join(map(str, shape if shape is not None else (len(rows),) + bad))
        raise DataError(f"{name} must be R x N (one realisation of N samples a row), got "
                        f"{shown}: for realisation x period x sample arrays pass "
                        f"{name}.reshape(R, -1)")
    return [r.reshape(-1) for r in rows]


def _whole_length(ref, n, period):
    """A reference of one period repeated to ``n`` samples (a generator's one-period
    signal beside records of several periods); any other reference as it is."""
    if ref is None:
        return None
    r = np.asarray(ref, float).reshape(-1)
    return np.tile(r, n // period + 1)[:n] if r.size == period and n > period else r


def _period_means(x, period, skip):
    """The DFT (first ``period // 2 + 1`` bins) of the mean of the whole periods of ``x``
    kept after ``skip``."""
    n = (x.size // period) * period
    return np.fft.fft(x[skip * period:n].reshape(-1, period).mean(axis=0))[:period // 2 + 1]


def frf_from_realisations(us, ys, period, *, fs=None, bins=None, skip_periods=0,
                          threshold=1e-2, allow_partial=False, periodic_rtol=0.2, name=None,
                          references=None):
    """Frequency response from several realisations of a periodic (multisine) experiment.

    Parameters
    ----------
    us, ys : array_like of float, shape (R, N), or sequences of R records of N samples
        Input and output of each realisation (row r of ``us`` with row r of ``ys``), every
        record whole periods of the excitation sampled at ``fs``.
    period : int
        Samples per period (the same in every realisation).
    fs, bins, skip_periods, threshold, allow_partial, periodic_rtol, name
        As :func:`~freqid_casadi.experiment.periodic.frf_from_periodic`, for each
        realisation.
    references : sequence of R array_like, optional
        Each realisation's generated excitation (``reference`` of ``frf_from_periodic``),
        as long as its records or one period (repeated).

    Returns
    -------
    FrfEstimate
        At every bin some realisation excites (each realisation's excited bins, or
        ``bins``): ``G`` the mean over the realisations that excite it of their estimates
        (each averaged over its periods); ``variance`` the variance of that mean from their
        spread (the noise and the nonlinear distortions; where one realisation excites a
        bin, its noise variance over the periods; None, and no weights, when one
        realisation of one period excites a bin); ``noise_variance`` the noise's share
        (the mean of the realisations' variances over their periods, over the
        realisations' count; None with one period each); ``coherence`` over the
        realisations' period-averaged spectra; ``n_realisations`` R, ``n_periods`` the
        periods averaged in each.

    Raises
    ------
    DataError
        Realisations of different counts in ``us`` and ``ys`` or none, and whatever
        ``frf_from_periodic`` raises for a realisation (the message says which).
    """
    us, ys = _rows(us, "us"), _rows(ys, "ys")
    if len(us) != len(ys):
        raise DataError(f"us holds {len(us)} realisations and ys {len(ys)}: pass the input "
                        "and the output of the same realisations")
    refs = [None] * len(us) if references is None else list(references)
    if len(refs) != len(us):
        raise DataError(f"references holds {len(refs)} records for {len(us)} realisations")
    ests = []
    for r, (u, y, ref) in enumerate(zip(us, ys, refs)):
        try:
            ests.append(frf_from_periodic(u, y, period, fs=fs, bins=bins,
                                          skip_periods=skip_periods, threshold=threshold,
                                          allow_partial=allow_partial,
                                          periodic_rtol=periodic_rtol, name=name,
                                          reference=_whole_length(ref, u.size, period)))
        except DataError as exc:
            raise DataError(f"realisation {r + 1} of {len(us)}: {exc}") from None
    if len(ests) == 1:
        return ests[0]
    return _combined(ests, us, ys, period, skip_periods, fs, name)


def _combined(ests, us, ys, period, skip, fs, name):
    """The realisations' estimates ``ests`` averaged bin by bin (see
    :func:`frf_from_realisations`)."""
    k_all = np.unique(np.concatenate([e.bins for e in ests]))
    n_real = len(ests)
    g = np.zeros((n_real, k_all.size), complex)     # each realisation's estimate, 0 where
    var = np.zeros((n_real, k_all.size))            # it does not excite the bin
    excites = np.zeros((n_real, k_all.size), bool)
    no_var = np.zeros(k_all.size, bool)             # a realisation of one period excites it
    cross = np.zeros(k_all.size, complex)
    auto_u, auto_y = np.zeros(k_all.size), np.zeros(k_all.size)
    for r, (e, u, y) in enumerate(zip(ests, us, ys)):
        at = np.searchsorted(k_all, e.bins)
        g[r, at], excites[r, at] = e.data.response, True
        if e.variance is None:
            no_var[at] = True
        else:
            var[r, at] = e.variance
        U, Y = _period_means(u, period, skip)[e.bins], _period_means(y, period, skip)[e.bins]
        cross[at] += Y * np.conj(U)
        auto_u[at] += np.abs(U) ** 2
        auto_y[at] += np.abs(Y) ** 2
    count = excites.sum(axis=0)
    G = g.sum(axis=0) / count
    with np.errstate(invalid="ignore", divide="ignore"):
        total = np.where(count >= 2, np.sum(np.abs(g - G) ** 2 * excites, axis=0)
                         / (count * (count - 1)), np.nan)
    noise = np.where(no_var, np.nan, var.sum(axis=0) / count ** 2)
    total = np.where(count == 1, noise, total)
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.minimum(np.abs(cross) ** 2 / (auto_u * auto_y), 1.0)
    coherence = np.where(np.isfinite(coherence), coherence, 0.0)
    weights = None
    if np.any(np.isnan(total)):     # a bin one realisation of one period excites
        total = None
    else:
        weights = 1.0 / np.maximum(total / np.abs(G) ** 2, _REL_VAR_FLOOR)
        weights = weights / weights.mean()
    omega = 2.0 * np.pi * k_all / period * (1.0 if fs is None else fs)
    data = FrequencyData(omega, G, name, weights, "rad/s" if fs is not None else "rad/sample")
    return FrfEstimate(data, k_all, total, coherence, ests[0].n_periods, period, fs,
                       estimator="periodic", n_realisations=n_real,
                       noise_variance=None if np.any(np.isnan(noise)) else noise)
