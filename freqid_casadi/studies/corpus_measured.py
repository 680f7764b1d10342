"""The measured part of the validation corpus: the default fit over every shipped measured FRF.

Each set of :func:`freqid_casadi.systems.measured_sets` is fitted by
``fit(data, n_sections=range(1, max_sections + 1))`` -- the automatic order up to the set's
``max_sections`` (the modes or resonances its SOURCE.md names, with margin), every other
option at its default -- and gives one :class:`MeasuredFit`. There is no truth to compare
with, so the verdict is the fit's own: its status, its RMS against the noise it estimates
from the residual (``details["noise"]``: the point-to-point roughness), and whether that
status is honest.

Definitions (used by the report and the tests):

noise estimate
    ``res.details["noise"]["noise_rms"]``: the RMS a white residual of the same roughness
    would have.
at the noise
    RMS relative error ``<= FLOOR_FACTOR *`` noise estimate (the synthetic corpus's factor).
honest
    Not (status "ok" with an RMS above ``DISHONEST_FACTOR *`` the noise estimate).
"""

import multiprocessing
import os
import time
import warnings
from dataclasses import asdict, dataclass

import numpy as np

from ..fitting.fit import fit
from ..report.formatting import markdown_table, number
from ..systems import MEASURED_SETS, measured
from .corpus import DISHONEST_FACTOR, FLOOR_FACTOR, _budget

__all__ = ["MeasuredFit", "fit_measured", "run_measured", "render_measured",
           "measured_dicts", "MEASURED_CPU_BUDGET"]

#: CPU seconds the automatic-order fit of one set may take (recorded as "time-limit").
MEASURED_CPU_BUDGET = 400.0


@dataclass(frozen=True)
class MeasuredFit:
    """The default fit of one measured set (see the module docstring for the definitions).

    Attributes
    ----------
    name : str
        The set (:data:`freqid_casadi.systems.MEASURED_SETS`).
    n_points : int
    f_min_hz, f_max_hz : float
        Its band, Hz.
    max_sections : int
        The largest order tried.
    n_sections : int
        The order chosen (0 when the fit raised).
    order_reason : str
        Why the order search stopped (``order-chosen`` diagnostic: "consistent",
        "free-zeros", "no-improvement", "max-sections", "data-limit"), "" if absent.
    status : str
        ``res.status`` ("ok", "poor-fit", "not-converged"), or "error".
    rms, max_rel_error : float
        Relative error against the data.
    noise, noise_ratio : float
        The noise estimate and RMS / roughness ratio of ``details["noise"]`` (NaN if absent).
    at_noise, honest : bool
    gain_sign : int
        The model's gain sign (+1 / -1; 0 when the fit raised).
    delay : float
        The model's delay, seconds.
    diagnostics : tuple of str
        The codes (``order-chosen`` left out).
    alternatives : tuple of str
        The better models the fit offers (``res.alternatives``), e.g.
        ``"zeros=free: RMS 0.0772 (poor-fit)"``.
    message : str
        ``res.message`` (first 300 characters).
    wall_time, cpu_time : float
        Seconds.
    error : str
        The exception (type: message) of a fit that raised, or "".
    """

    name: str
    n_points: int
    f_min_hz: float
    f_max_hz: float
    max_sections: int
    n_sections: int
    order_reason: str
    status: str
    rms: float
    max_rel_error: float
    noise: float
    noise_ratio: float
    at_noise: bool
    honest: bool
    gain_sign: int
    delay: float
    diagnostics: tuple
    alternatives: tuple
    message: str
    wall_time: float
    cpu_time: float
    error: str = ""


def fit_measured(name, *, max_sections=None):
    """The default fit of one measured set, up to its ``max_sections``.

    Parameters
    ----------
    name : str
        A name of :func:`freqid_casadi.systems.measured_sets`.
    max_sections : int, optional
        Override the set's ``max_sections`` (a quicker run).

    Returns
    -------
    MeasuredFit
        A fit that raises (or runs over :data:`MEASURED_CPU_BUDGET`) is recorded with
        status "error".
    """
    spec = MEASURED_SETS[name]
    top = int(max_sections or spec.max_sections)
    data = measured(name)
    base = dict(name=name, n_points=int(data.omega.size),
                f_min_hz=float(data.omega[0] / (2 * np.pi)),
                f_max_hz=float(data.omega[-1] / (2 * np.pi)), max_sections=top)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit(data, n_sections=range(1, top + 1),
                      progress=_budget(MEASURED_CPU_BUDGET))
    except Exception as exc:    # noqa: BLE001 -- a study records every failure, by type
        return MeasuredFit(**base, n_sections=0, order_reason="", status="error",
                           rms=np.nan, max_rel_error=np.nan, noise=np.nan,
                           noise_ratio=np.nan, at_noise=False, honest=True, gain_sign=0,
                           delay=np.nan, diagnostics=(), alternatives=(), message="",
                           wall_time=time.perf_counter() - t0,
                           cpu_time=time.process_time() - c0,
                           error=f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}")
    return _record(base, res, time.perf_counter() - t0, time.process_time() - c0)


def _record(base, res, wall, cpu):
    """:class:`MeasuredFit` of a finished fit."""
    noise = (res.details or {}).get("noise") or {}
    sigma = float(noise.get("noise_rms", np.nan))
    rms = float(res.rms_rel_error)
    order = next((d for d in res.diagnostics if d.code == "order-chosen"), None)
    dishonest = res.status == "ok" and not rms <= DISHONEST_FACTOR * sigma
    return MeasuredFit(**base, n_sections=int(res.model.n_sections),
                       order_reason=str(order.values.get("reason", "")) if order else "",
                       status=str(res.status), rms=rms,
                       max_rel_error=float(res.max_rel_error), noise=sigma,
                       noise_ratio=float(noise.get("ratio", np.nan)),
                       at_noise=bool(rms <= FLOOR_FACTOR * sigma), honest=not dishonest,
                       gain_sign=int(res.model.structure.gain_sign),
                       delay=float(res.model.delay),
                       diagnostics=tuple(d.code for d in res.diagnostics
                                         if d.code != "order-chosen"),
                       alternatives=_alternatives(res),
                       message=" ".join(str(res.message).split())[:300],
                       wall_time=wall, cpu_time=cpu)


def _alternatives(res):
    alts = getattr(res, "alternatives", None) or {}
    return tuple(f"{k}: RMS {number(getattr(a, 'rms_rel_error', None), 3)} "
                 f"({getattr(a, 'status', '?')})" for k, a in alts.items())


def _fit_task(task):
    name, max_sections = task
    return fit_measured(name, max_sections=max_sections)


def _quiet():
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    warnings.simplefilter("ignore")


def run_measured(names=None, *, workers=2, max_sections=None, progress=None):
    """Fit every measured set (or ``names``); returns the :class:`MeasuredFit` records.

    Parameters
    ----------
    names : sequence of str, optional
        Default: every set of :func:`freqid_casadi.systems.measured_sets`.
    workers : int
        Worker processes (1: in this process).
    max_sections : int, optional
        Cap every set's ``max_sections`` at this (a quicker run).
    progress : callable, optional
        Called with ``(done, total, MeasuredFit)`` after each fit.

    Returns
    -------
    list of MeasuredFit
        In the order of ``names``.
    """
    names = list(MEASURED_SETS) if names is None else list(names)
    unknown = [n for n in names if n not in MEASURED_SETS]
    if unknown:
        measured(unknown[0])                # raises the DataError naming the choices
    tasks = [(n, None if max_sections is None else
              min(int(max_sections), MEASURED_SETS[n].max_sections)) for n in names]
    # the largest first, so two workers end together
    tasks.sort(key=lambda t: -MEASURED_SETS[t[0]].n_points * MEASURED_SETS[t[0]].max_sections)
    out = []
    pool = None
    if workers <= 1:
        mapped = map(_fit_task, tasks)
    else:
        pool = multiprocessing.get_context("spawn").Pool(workers, initializer=_quiet)
        mapped = pool.imap_unordered(_fit_task, tasks)
    try:
        for rec in mapped:
            out.append(rec)
            if progress is not None:
                progress(len(out), len(tasks), rec)
    finally:
        if pool is not None:
            pool.terminate()
            pool.join()
    return sorted(out, key=lambda r: names.index(r.name))


def measured_dicts(records):
    """The records as plain dicts (for JSON).

    Parameters
    ----------
    records : sequence of MeasuredFit
        The measured part's records (:func:`run_measured`).

    Returns
    -------
    list of dict
    """
    return [asdict(r) for r in records]


def _sign(s):
    return {1: "+", -1: "−"}.get(s, "—")


def _hz(f):
    """A frequency with its SI prefix, e.g. ``"75 GHz"``."""
    for scale, unit in ((1e9, "GHz"), (1e6, "MHz"), (1e3, "kHz")):
        if abs(f) >= scale:
            return f"{f / scale:.4g} {unit}"
    return f"{f:.4g} Hz"


def _band(r):
    return f"{_hz(r['f_min_hz'])}–{_hz(r['f_max_hz'])}"


def render_measured(records):
    """The measured section of the corpus report (Markdown lines).

    Parameters
    ----------
    records : list of dict
        :class:`MeasuredFit` records as dicts (:func:`measured_dicts`).

    Returns
    -------
    list of str
    """
    rows = [[r["name"], r["n_points"], _band(r), r["max_sections"],
             r["status"] if not r["error"] else f"error ({r['error'][:60]})",
             f"{r['n_sections']} ({r['order_reason'] or '—'})", number(r["rms"], 3),
             number(r["noise"], 3),
             number(r["rms"] / r["noise"], 3) if r["noise"] and np.isfinite(r["noise"])
             else "—", _sign(r["gain_sign"]), number(r["delay"], 3),
             "yes" if r["honest"] else "**NO**", f"{r['wall_time']:.1f} / {r['cpu_time']:.1f}",
             ", ".join(r["diagnostics"]) or "—", "; ".join(r["alternatives"]) or "—"]
            for r in records]
    n_ok = sum(r["status"] == "ok" for r in records)
    n_noise = sum(r["at_noise"] for r in records)
    n_dis = sum(not r["honest"] for r in records)
    return ["## Measured FRFs (shipped in freqid_casadi/datasets)", "",
            "Every set of `freqid_casadi.systems.measured_sets()` (sources and licences in "
            "each folder's SOURCE.md), fitted by `fc.fit(data, n_sections=range(1, "
            "max_sections + 1))` -- the automatic order up to the set's `max_sections`, every "
            "other option at its default. No truth is known: the noise is the fit's own "
            "estimate (`details[\"noise\"][\"noise_rms\"]`, the residual's point-to-point "
            f"roughness); **at the noise**: RMS ≤ {FLOOR_FACTOR:g} × that; **honest**: not "
            f"status ok with an RMS above {DISHONEST_FACTOR:g} × that. A fit that explains "
            "nothing (RMS near 1, `no-better-than-trivial`) leaves a nearly constant "
            "residual, whose noise estimate is then meaninglessly small.", "",
            f"{len(records)} sets: {n_ok} ok, {n_noise} at the noise, {n_dis} dishonest.", "",
            markdown_table(rows, ["set", "points", "band", "max N", "status",
                                  "N chosen (why)", "RMS", "noise est.", "RMS / noise",
                                  "sign", "delay (s)", "honest", "time wall / CPU (s)",
                                  "diagnostics", "offered"]), ""]
