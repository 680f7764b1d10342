"""The zeros of a shared fit's channels on random modal tests: minimum phase or free.

A modal test drives a structure at one point and measures several: the driving point's
FRF (collocated) is minimum phase, the others mostly are not (a mode whose modal
constant changes sign between two modes leaves no zero between them on the axis, and
right-half-plane zeros appear). Each case here is such a test, drawn at random
(:func:`modal_case`): 2-5 modes, 3-6 sensors, the first collocated, shapes drawn
uniformly, 0.3-2 % complex Gaussian relative noise. :func:`score_case` fits it with
:func:`~freqid_casadi.modal.shared.fit_shared` at the true order, once per zeros choice in
:data:`CHOICES`, and scores each fit against the truth: its status, the worst relative
error of the modes' natural frequencies and damping ratios, the least MAC of the modes'
residue vectors against the true ones, and whether a minimum-phase fit that is not "ok"
offers the fit with free zeros (``details["free_zeros"]``).
"""

import math
import multiprocessing
import time
import warnings

import numpy as np

from ..core.data import FrequencyData
from ..modal.shared import fit_shared

__all__ = ["CHOICES", "modal_case", "score_case", "run_study", "summarise"]

#: The zeros choices compared.
CHOICES = ("minimum-phase", "free")


def modal_case(index, seed=0, n_points=300):
    """One random modal test.

    Parameters
    ----------
    index, seed : int
        The case is drawn from ``numpy.random.default_rng((seed, index))``.
    n_points : int
        Log-spaced frequencies from a third of the lowest mode to three times the highest.

    Returns
    -------
    dict
        ``datas`` (list of FrequencyData, omega in rad/s, the first channel collocated),
        ``omega_n`` (rad/s) and ``zeta`` of the modes, ``shapes`` (channels x modes: the
        true residue vectors up to a factor per mode), ``noise`` (relative RMS).
    """
    rng = np.random.default_rng((seed, index))
    n_modes, n_channels = int(rng.integers(2, 6)), int(rng.integers(3, 7))
    gaps = rng.uniform(np.log(1.3), np.log(3.0), n_modes - 1)
    omega_n = 10.0 * np.exp(np.concatenate([[0.0], np.cumsum(gaps)]))
    zeta = rng.uniform(0.005, 0.03, n_modes)
    phi = rng.uniform(-1.0, 1.0, (n_channels, n_modes))
    phi[0] = np.sign(phi[0]) * np.maximum(np.abs(phi[0]), 0.2)    # the drive sees each mode
    shapes = phi * phi[0]
    omega = np.geomspace(omega_n[0] / 3.0, 3.0 * omega_n[-1], n_points)
    s = 1j * omega
    noise = float(rng.uniform(0.003, 0.02))
    datas = []
    for c in range(n_channels):
        g = sum(shapes[c, k] / (s * s + 2 * zeta[k] * omega_n[k] * s + omega_n[k] ** 2)
                for k in range(n_modes))
        e = noise * (rng.standard_normal(n_points) + 1j * rng.standard_normal(n_points))
        datas.append(FrequencyData(omega, g * (1.0 + e / math.sqrt(2.0)), f"ch{c + 1}"))
    return {"datas": datas, "omega_n": omega_n, "zeta": zeta, "shapes": shapes,
            "noise": noise}


def _mac(a, b):
    return float(abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


def _score(res, case):
    """The fit's numbers against the truth."""
    modes = list(res.modes)
    f_err = d_err = 0.0
    macs = []
    for k, (wn, z) in enumerate(zip(case["omega_n"], case["zeta"])):
        if not modes:
            f_err = d_err = math.inf
            macs.append(0.0)
            continue
        m = min(modes, key=lambda m: abs(m.omega_n - wn))
        f_err = max(f_err, abs(m.omega_n / wn - 1.0))
        d_err = max(d_err, abs(m.zeta / z - 1.0))
        macs.append(_mac(np.asarray(m.residues, complex), case["shapes"][:, k]))
    offer = res.details.get("free_zeros")
    return {"status": str(res.status), "freq_error": f_err, "damping_error": d_err,
            "min_mac": min(macs), "worst_rms": float(np.max(res.rms_rel_errors)),
            "offered": offer is not None,
            "offer_rhp": list(offer["non_minimum_phase"]) if offer else []}


def score_case(task):
    """Fit one case with every choice of :data:`CHOICES`.

    Parameters
    ----------
    task : tuple
        ``(index, seed, n_points)`` of :func:`modal_case`.

    Returns
    -------
    dict
        The case's size and noise, and each choice's scores (with its CPU seconds).
    """
    index, seed, n_points = task
    case = modal_case(index, seed, n_points)
    row = {"case": index, "modes": len(case["omega_n"]), "channels": len(case["datas"]),
           "noise": case["noise"]}
    for choice in CHOICES:
        t0 = time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit_shared(case["datas"], len(case["omega_n"]), delay=False, zeros=choice)
        row[choice] = dict(_score(res, case), cpu=time.process_time() - t0)
    return row


def run_study(n_cases, seed=0, n_points=300, workers=2, progress=None):
    """Score cases ``0 .. n_cases - 1`` in ``workers`` processes (in order).

    Parameters
    ----------
    n_cases, seed, n_points : int
        As :func:`modal_case`.
    workers : int
        Processes (1: this one).
    progress : callable, optional
        Receives each row.

    Returns
    -------
    list of dict
        :func:`score_case`'s rows.
    """
    tasks = [(i, seed, n_points) for i in range(n_cases)]
    rows = []
    if workers <= 1:
        for t in tasks:
            rows.append(score_case(t))
            if progress:
                progress(rows[-1])
        return rows
    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        for row in pool.imap(score_case, tasks):
            rows.append(row)
            if progress:
                progress(row)
    return rows


#: A fit "finds the modes" when every natural frequency is within this relative error,
#: every damping ratio within :data:`DAMPING_TOL` and every residue vector's MAC above
#: :data:`MAC_TOL`.
FREQ_TOL, DAMPING_TOL, MAC_TOL = 0.005, 0.10, 0.99


def summarise(rows):
    """Per choice: cases, "ok" statuses, modes found (:data:`FREQ_TOL`), "ok" on a fit
    that did not find them, median errors, fits not "ok" that offered free zeros (and
    offers naming the collocated channel 0), CPU seconds.

    Parameters
    ----------
    rows : list of dict
        :func:`run_study`'s rows.

    Returns
    -------
    dict of str to dict
    """
    out = {}
    for choice in CHOICES:
        fits = [r[choice] for r in rows]
        found = [f["freq_error"] <= FREQ_TOL and f["damping_error"] <= DAMPING_TOL
                 and f["min_mac"] >= MAC_TOL for f in fits]
        out[choice] = {
            "cases": len(fits), "ok": sum(f["status"] == "ok" for f in fits),
            "found": int(sum(found)),
            "ok_not_found": [r["case"] for r, f, y in zip(rows, fits, found)
                             if f["status"] == "ok" and not y],
            "median_freq_error": float(np.median([f["freq_error"] for f in fits])),
            "median_damping_error": float(np.median([f["damping_error"] for f in fits])),
            "median_min_mac": float(np.median([f["min_mac"] for f in fits])),
            "not_ok": sum(f["status"] != "ok" for f in fits),
            "offered": sum(f["offered"] for f in fits),
            "offer_names_collocated": sum(0 in f["offer_rhp"] for f in fits),
            "cpu": float(sum(f["cpu"] for f in fits))}
    return out
