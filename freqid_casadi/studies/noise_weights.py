"""``weights="noise"`` judged on corpus systems: without weights, estimated, true weights.

Each in-class noisy case of :func:`freqid_casadi.systems.corpus.case` is given noise of a
known kind and fitted at its true order three ways: without weights, with
``weights="noise"`` (:mod:`freqid_casadi.fitting.noise_weights`) and with the true inverse
relative variances. Each fit is scored by its status and by its error against the true
system in units of the true noise, ``sqrt(mean |G_N / G - 1|^2 / sigma_i^2)`` (about 0.1
to 0.3 for a model at the noise floor). The kinds: ``"floor"``, complex Gaussian noise of
constant absolute level (0.3-3 % of the median ``|G|``, an analyser's noise floor);
``"mixed"``, that floor plus 0.1-1 % relative noise; ``"relative"``, the corpus's own
(flat or sloped up to 10-fold).
"""

import math
import multiprocessing
import time
import warnings

import numpy as np

from ..core.data import FrequencyData
from ..fitting.fit import fit
from ..systems.corpus import case

__all__ = ["KINDS", "WAYS", "noise_case", "score_case", "run_study", "summarise"]

#: Noise kinds (see the module docstring).
KINDS = ("floor", "mixed", "relative")
#: The three fits of each case.
WAYS = ("none", "noise", "true")


def noise_case(index, seed, max_points, kind):
    """``(data, truth, sigma, case)`` of a corpus case with noise of ``kind``, or None
    when the case is outside the class or noiseless.

    Parameters
    ----------
    index, seed, max_points : int
        The corpus case (:func:`freqid_casadi.systems.corpus.case`).
    kind : {"floor", "mixed", "relative"}
        The noise (:data:`KINDS`; the module docstring).

    Returns
    -------
    tuple or None
        ``data`` (FrequencyData without weights), ``truth`` (G at the data's omega),
        ``sigma`` (the relative noise RMS per point) and the :class:`CorpusCase`.
    """
    c = case(index, seed, max_points=max_points)
    if not c.in_class or c.noise == 0:
        return None
    w = c.data.omega
    g = c.truth(w)
    if kind == "relative":
        return FrequencyData(w, c.data.response, c.name), g, np.asarray(c.sigma), c
    rng = np.random.default_rng([seed, index, 7])
    z = (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)) / math.sqrt(2)
    sigma = 10 ** rng.uniform(-2.5, -1.5) * np.median(np.abs(g)) / np.abs(g)
    if kind == "mixed":
        sigma = np.sqrt(sigma ** 2 + (10 ** rng.uniform(-3, -2)) ** 2)
    return FrequencyData(w, g * (1 + sigma * z), c.name), g, sigma, c


def score_case(task):
    """The three fits of one case.

    Parameters
    ----------
    task : tuple
        ``(index, seed, max_points, kind)`` (:func:`noise_case`).

    Returns
    -------
    dict or None
        Case, kind, points, sections, the spread of sigma, and per way of :data:`WAYS`
        its status, noise ratio, error in noise units and CPU seconds; None when
        :func:`noise_case` gives none.
    """
    index, seed, max_points, kind = task
    made = noise_case(index, seed, max_points, kind)
    if made is None:
        return None
    data, g, sigma, c = made
    row = {"case": c.name, "kind": kind, "points": int(data.n_points),
           "sections": int(c.n_sections), "spread": float(sigma.max() / sigma.min())}
    for way, weights in zip(WAYS, (None, "noise", 1.0 / sigma ** 2)):
        t0 = time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit(data, n_sections=c.n_sections, weights=weights)
        e = res.model.frequency_response(data.omega) / g - 1.0
        row[way] = {"status": str(res.status), "ratio": float(res.details["noise"]["ratio"]),
                    "error": float(np.sqrt(np.mean(np.abs(e) ** 2 / sigma ** 2))),
                    "cpu": time.process_time() - t0}
    return row


def run_study(kinds, seed, n_cases, max_points, workers=2, progress=None):
    """:func:`score_case` of the first ``n_cases`` indices for every kind.

    Parameters
    ----------
    kinds : sequence of str
        Of :data:`KINDS`.
    seed, n_cases, max_points : int
        Corpus seed, indices ``0 .. n_cases - 1``, points per case at most.
    workers : int
        Worker processes.
    progress : callable, optional
        Receives each row as it ends.

    Returns
    -------
    list of dict
        The rows (cases outside the class or noiseless left out).
    """
    tasks = [(i, seed, max_points, k) for k in kinds for i in range(n_cases)]
    rows = []
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(workers) as pool:
        for row in pool.imap(score_case, tasks):
            if row is not None:
                rows.append(row)
                if progress is not None:
                    progress(row)
    return rows


def summarise(rows):
    """The numbers of the report, per kind and way.

    Parameters
    ----------
    rows : list of dict
        :func:`score_case` rows.

    Returns
    -------
    dict
        ``{kind: {way: {...}}}``: cases, the geometric mean of the error's ratio to the
        unweighted fit's, the median error, fits more than 1.5 times worse, counts of
        each status, the "ok" fits more than 2 noise units from the truth (their cases),
        CPU seconds.
    """
    out = {}
    for kind in dict.fromkeys(r["kind"] for r in rows):
        sub = [r for r in rows if r["kind"] == kind]
        base = np.array([r["none"]["error"] for r in sub])
        out[kind] = {}
        for way in WAYS:
            err = np.array([r[way]["error"] for r in sub])
            status = [r[way]["status"] for r in sub]
            far = [r["case"] for r in sub if r[way]["status"] == "ok" and r[way]["error"] > 2]
            out[kind][way] = {
                "cases": len(sub), "ratio_geomean": float(np.exp(np.mean(np.log(err / base)))),
                "median_error": float(np.median(err)),
                "worse": int(np.sum(err > 1.5 * base)),
                "ok": status.count("ok"), "poor_fit": status.count("poor-fit"),
                "not_converged": status.count("not-converged"), "ok_far": far,
                "cpu": float(sum(r[way]["cpu"] for r in sub))}
    return out
