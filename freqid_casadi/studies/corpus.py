"""The validation corpus run: the default pipeline over seeded synthetic FRFs (issue 26).

Every case of :func:`freqid_casadi.systems.corpus.corpus` is fitted at its true order by
today's defaults and, on every :data:`COMPARE_EVERY`-th round of the families, by each
candidate of :data:`CONFIGS` (:data:`HALF_ONLY`: the previous defaults and the strict
termination test), in the same run, and a subset of the noisy cases once more with
``n_sections="auto"``. Each fit gives one
:class:`CaseFit` record; :func:`summarize` turns them into the per-family table of
:mod:`freqid_casadi.studies.corpus_report`.

Definitions (one place, used by the report and the tests):

noise level ``nu``
    The RMS of the case's relative noise, raised to :data:`EXACT_FLOOR` for exact data
    (the numerical floor a fit of exact data is held to).
at the floor (data)
    RMS relative error against the noisy data ``<= FLOOR_FACTOR * nu``.
at the floor (truth)
    RMS of ``|G_true / G_N - 1|`` on a log grid :data:`DENSE` times denser than the data
    (between the samples) ``<= FLOOR_FACTOR * nu``.
claims ok
    ``res.status == "ok"`` when the result has a status, else ``res.success``.
dishonest
    Claims ok with an RMS above ``DISHONEST_FACTOR * nu``.
sign right
    The model's gain sign is the system's (:attr:`CorpusCase.gain_sign`).
class right
    At the floor, or outside the class with a diagnostic naming the cause (an
    ``integrator`` in a message for undeclared poles at the origin, ``non-minimum-phase``
    for right-half-plane zeros).
order right (auto)
    The chosen order lies in ``[true, true + 1]``.
"""

import json
import multiprocessing
import os
import sys
import time
import warnings
from dataclasses import asdict, dataclass

import numpy as np

from ..core.data import dense_grid
from ..fitting.fit import fit
from ..options import IpoptOptions, LoopOptions
from ..report.folder import code_fingerprint
from ..systems.corpus import FAMILIES, case, corpus

__all__ = ["CONFIGS", "CaseFit", "run_corpus", "fit_case", "summarize", "EXACT_FLOOR",
           "FLOOR_FACTOR", "DISHONEST_FACTOR", "DENSE", "QUICK_CASES", "FULL_CASES",
           "FULL_MAX_POINTS", "AUTO", "NOISY_ONLY", "HALF_ONLY", "COMPARE_EVERY",
           "SUBSET_EVERY", "CPU_BUDGET", "TimeLimit", "json_lines"]

#: The configurations compared in one run: today's defaults, the defaults before the
#: corpus issue (start="sequential", integrator=False, no resolution guard; the gain sign
#: from the fits and the screened h = 0 candidate are today's in both), and today's with
#: the strict termination only (no stop of a final stage at the noise,
#: ``IpoptOptions(noise_stall=None)``).
CONFIGS = {
    "today": {},
    "previous defaults": {"start": "sequential", "integrator": False,
                          "loop": LoopOptions(resolution_guard=False)},
    "strict termination": {"method": IpoptOptions(noise_stall=None)},
}
#: Configurations run on the noisy subset only (:data:`SUBSET_EVERY`; none today).
NOISY_ONLY = ()
#: Configurations run on every :data:`COMPARE_EVERY`-th round of the nine families only
#: (exact and noisy cases alike: the comparison with today's fits of the same cases; the
#: run's time budget on a shared 2-core machine).
HALF_ONLY = ("previous defaults", "strict termination")
COMPARE_EVERY = 2
#: The subset of the automatic order and of :data:`NOISY_ONLY`: the noisy cases of every
#: this-many-th round of the nine families (``(index // 9) % SUBSET_EVERY == 0``: every
#: family in it; the run's time budget).
SUBSET_EVERY = 8
#: CPU seconds a fit may take (three times that with ``n_sections="auto"``); a fit over
#: it is recorded as an error "time-limit" (CPU time: fair on a loaded machine).
CPU_BUDGET = 40.0
#: Name of the automatic-order run (today's other defaults, noisy cases only).
AUTO = "n_sections=auto"
EXACT_FLOOR = 1e-4
FLOOR_FACTOR = 1.5
DISHONEST_FACTOR = 10.0
DENSE = 4
QUICK_CASES = 60
FULL_CASES = 300
#: Cap on the points of a case in the full run (the corpus draws up to 5000).
FULL_MAX_POINTS = 5000


@dataclass(frozen=True)
class CaseFit:
    """One fit of one case (see the module docstring for the definitions).

    Attributes
    ----------
    case, index, family : str, int, str
        The case (:class:`~freqid_casadi.systems.corpus.CorpusCase`).
    config : str
        A key of :data:`CONFIGS`, or :data:`AUTO`.
    n_points, true_sections, n_sections : int
        The case's points, its true sections and the fitted model's.
    noise, nu : float
        The noise RMS and the noise level (at least :data:`EXACT_FLOOR`).
    in_class, variance_given : bool
    delay : float
        The true delay, seconds.
    rms, rms_truth, max_rel_error : float
        RMS against the data, RMS against the truth between the samples, max against the
        data.
    success : bool
    status : str
        ``res.status``, or "converged" / "not-converged" from ``res.success``; "error".
    claims_ok, at_floor, at_floor_truth, dishonest, sign_right, class_right : bool
    diagnostics : tuple of str
        The codes.
    wall_time : float
        Seconds.
    error : str
        The exception (type: message) of a fit that raised, or "".
    task : tuple
        ``(index, seed, max_points, config)``.
    """

    case: str
    index: int
    family: str
    config: str
    n_points: int
    true_sections: int
    n_sections: int
    noise: float
    nu: float
    in_class: bool
    variance_given: bool
    delay: float
    rms: float
    rms_truth: float
    max_rel_error: float
    success: bool
    status: str
    claims_ok: bool
    at_floor: bool
    at_floor_truth: bool
    dishonest: bool
    sign_right: bool
    class_right: bool
    diagnostics: tuple
    wall_time: float
    error: str = ""
    task: tuple = ()


class TimeLimit(Exception):
    """A fit of the corpus run took more than its CPU budget."""


def _budget(seconds):
    """A progress callback that raises :class:`TimeLimit` once this process has used
    ``seconds`` more CPU time."""
    end = time.process_time() + seconds

    def check(_record):
        if time.process_time() > end:
            raise TimeLimit(f"time-limit: over {seconds:g} CPU seconds")

    return check


def _class_flagged(c, res):
    text = " ".join(f"{d.code} {d.message}" for d in res.diagnostics).lower()
    if c.integrators and "integrator" not in text:
        return False
    if c.nmp_zeros and "non-minimum-phase" not in text:
        return False
    return not c.in_class


def fit_case(task):
    """Fit one case with one configuration.

    Parameters
    ----------
    task : tuple
        ``(index, seed, max_points, config)``.

    Returns
    -------
    CaseFit
    """
    index, seed, max_points, config = task
    c = case(index, seed, max_points=max_points)
    options = {"n_sections": "auto"} if config == AUTO else dict(
        CONFIGS[config], n_sections=c.n_sections)
    nu = max(c.noise, EXACT_FLOOR)
    t0 = time.perf_counter()
    base = dict(task=tuple(task), case=c.name, index=c.index, family=c.family, config=config,
                n_points=c.n_points, true_sections=c.n_sections, noise=c.noise, nu=nu,
                in_class=c.in_class, variance_given=c.variance_given, delay=c.delay)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit(c.data, progress=_budget(CPU_BUDGET * (3 if config == AUTO else 1)),
                      **options)
    except Exception as exc:    # noqa: BLE001 -- a study records every failure, by type
        return CaseFit(**base, n_sections=0, rms=np.nan, rms_truth=np.nan,
                       max_rel_error=np.nan, success=False, status="error", claims_ok=False,
                       at_floor=False, at_floor_truth=False, dishonest=False,
                       sign_right=False, class_right=False, diagnostics=(),
                       wall_time=time.perf_counter() - t0,
                       error=f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}")
    wall = time.perf_counter() - t0
    dense = dense_grid(c.data.omega, DENSE)
    with np.errstate(all="ignore"):
        truth_err = np.abs(c.truth(dense) / res.model.frequency_response(dense) - 1)
    rms_truth = float(np.sqrt(np.mean(truth_err ** 2)))
    status = getattr(res, "status", None)
    claims = (status == "ok") if status is not None else bool(res.success)
    rms = float(res.rms_rel_error)
    floor = rms <= FLOOR_FACTOR * nu
    return CaseFit(**base, n_sections=res.model.n_sections, rms=rms,
                   rms_truth=rms_truth if np.isfinite(rms_truth) else np.inf,
                   max_rel_error=float(res.max_rel_error), success=bool(res.success),
                   status=status if status is not None else
                   ("converged" if res.success else "not-converged"),
                   claims_ok=claims, at_floor=floor,
                   at_floor_truth=bool(rms_truth <= FLOOR_FACTOR * nu),
                   dishonest=bool(claims and rms > DISHONEST_FACTOR * nu),
                   sign_right=res.model.structure.gain_sign == c.gain_sign,
                   class_right=bool(floor or _class_flagged(c, res)),
                   diagnostics=tuple(d.code for d in res.diagnostics), wall_time=wall)


def tasks(n, seed=0, max_points=FULL_MAX_POINTS, configs=None, auto=True):
    """The fits of a run: every case with every configuration (those of :data:`NOISY_ONLY`
    on the noisy subset, those of :data:`HALF_ONLY` on every :data:`COMPARE_EVERY`-th
    round), and the noisy subset (:data:`SUBSET_EVERY`) with ``n_sections="auto"``; the
    largest cases first (so two workers end together)."""
    configs = list(CONFIGS) if configs is None else list(configs)
    cases = corpus(n, seed, max_points=max_points)
    sub = {c.index for c in cases
           if c.noise > 0 and (c.index // len(FAMILIES)) % SUBSET_EVERY == 0}
    half = {c.index for c in cases if (c.index // len(FAMILIES)) % COMPARE_EVERY == 0}
    out = [(c.index, seed, max_points, k) for c in cases for k in configs
           if (c.index in sub or k not in NOISY_ONLY) and (c.index in half
                                                           or k not in HALF_ONLY)]
    if auto:
        out += [(c.index, seed, max_points, AUTO) for c in cases if c.index in sub]
    size = {c.index: c.n_points * c.n_sections for c in cases}
    return sorted(out, key=lambda t: (-size[t[0]] * (3 if t[3] == AUTO else 1), t))


def run_corpus(n=FULL_CASES, seed=0, *, max_points=FULL_MAX_POINTS, workers=2,
               configs=None, auto=True, progress=None, checkpoint=None):
    """Fit the corpus; returns the list of :class:`CaseFit` (in task order).

    Parameters
    ----------
    n, seed, max_points
        Passed to :func:`~freqid_casadi.systems.corpus.corpus`.
    workers : int
        Worker processes (1: in this process).
    configs : sequence of str, optional
        Keys of :data:`CONFIGS` (default all).
    auto : bool
        Also fit the noisy cases with ``n_sections="auto"``.
    progress : callable, optional
        Called with ``(done, total, CaseFit)`` after each fit.
    checkpoint : str or os.PathLike, optional
        A JSON-lines file: each fit is appended as it is done, and the fits it already
        holds (same case, seed and configuration, made by the same code:
        :func:`~freqid_casadi.report.folder.code_fingerprint`) are not run again (a run that was
        stopped resumes).
    """
    todo = tasks(n, seed, max_points, configs, auto)
    out = _read_checkpoint(checkpoint, todo)
    done = {(r.index, r.config) for r in out}
    todo = [t for t in todo if (t[0], t[3]) not in done]
    total = len(todo) + len(out)
    if workers <= 1:
        mapped = map(fit_case, todo)
        pool = None
    else:
        pool = multiprocessing.get_context("spawn").Pool(workers, initializer=_quiet)
        mapped = pool.imap_unordered(fit_case, todo)
    try:
        for rec in mapped:
            out.append(rec)
            if checkpoint is not None:
                with open(checkpoint, "a", encoding="utf-8") as f:
                    f.write(json.dumps(dict(asdict(rec), code=code_fingerprint()),
                                       default=_plain) + "\n")
            if progress is not None:
                progress(len(out), total, rec)
    finally:
        if pool is not None:
            pool.terminate()
            pool.join()
    return sorted(out, key=lambda r: (r.index, r.config))


def _plain(x):
    return x.item() if hasattr(x, "item") else str(x)


def json_lines(path, code=None):
    """The records of the JSON-lines checkpoint ``path`` (appended to record by record), each
    a decoded line; a line that does not decode (cut when a run was killed) is skipped, and
    a missing file (or None) has none.

    Parameters
    ----------
    path : str or os.PathLike or None
    code : str, optional
        Keep only the records whose ``"code"`` is this
        (:func:`~freqid_casadi.report.folder.code_fingerprint`): records made by another
        version of the package are set aside, to be made again, and stderr says how many.

    Returns
    -------
    list
    """
    if path is None or not os.path.exists(path):
        return []
    out = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            try:
                out.append(json.loads(line))
            except ValueError:
                continue
    if code is None:
        return out
    mine = [d for d in out if isinstance(d, dict) and d.get("code") == code]
    if len(mine) < len(out):
        print(f"{path}: {len(out) - len(mine)} of its {len(out)} records were made by other "
              f"code (not {code}); set aside, to be made again", file=sys.stderr, flush=True)
    return mine


def _read_checkpoint(path, todo):
    """The :class:`CaseFit` records of a checkpoint file that belong to ``todo`` (seed and
    point cap included: the key is the task)."""
    keys = {(t[0], t[3]): t for t in todo}
    out = []
    for d in json_lines(path, code_fingerprint()):   # (a line cut by the stop is skipped)
        d.pop("code")
        task = keys.get((d.get("index"), d.get("config")))
        if task is not None and d.get("task") == list(task):
            d["diagnostics"] = tuple(d["diagnostics"])
            out.append(CaseFit(**d))
    return out


def _quiet():
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    warnings.simplefilter("ignore")


def _fraction(recs, key):
    return float(np.mean([getattr(r, key) for r in recs])) if recs else float("nan")


def summarize(records):
    """Per configuration and family (and ``"all"``): counts, fractions at the floor (data,
    truth), sign and class right, dishonest, median and max time; for the automatic order
    the fraction of orders in [true, true + 1] and of orders below / above.

    Parameters
    ----------
    records : sequence of CaseFit

    Returns
    -------
    dict
        ``{config: {family: {...}}}``.
    """
    out = {}
    for config in sorted({r.config for r in records}, key=_config_key):
        recs = [r for r in records if r.config == config]
        fams = {}
        for fam in list(FAMILIES) + ["all", "in-class cases",
                                                    "outside the class"]:
            sel = [r for r in recs if r.family == fam or fam == "all"
                   or (fam == "in-class cases" and r.in_class)
                   or (fam == "outside the class" and not r.in_class)]
            if sel:
                fams[fam] = _stats(sel)
        out[config] = fams
    return out


def _config_key(name):
    order = list(CONFIGS) + [AUTO]
    return order.index(name) if name in order else len(order)


def _stats(sel):
    times = [r.wall_time for r in sel]
    s = {"n": len(sel), "at_floor": _fraction(sel, "at_floor"),
         "at_floor_truth": _fraction(sel, "at_floor_truth"),
         "sign_right": _fraction(sel, "sign_right"),
         "class_right": _fraction(sel, "class_right"),
         "claims_ok": _fraction(sel, "claims_ok"),
         "dishonest": int(sum(r.dishonest for r in sel)),
         "errors": int(sum(bool(r.error) for r in sel)),
         "time_median": float(np.median(times)), "time_max": float(np.max(times)),
         "time_total": float(np.sum(times))}
    diff = [r.n_sections - r.true_sections for r in sel if not r.error]
    s["order_right"] = float(np.mean([0 <= d <= 1 for d in diff])) if diff else float("nan")
    s["order_below"] = int(sum(d < 0 for d in diff))
    s["order_above"] = int(sum(d > 1 for d in diff))
    return s


def record_dicts(records):
    """The records as plain dicts (for JSON)."""
    return [asdict(r) for r in records]
