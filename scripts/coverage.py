"""Monte Carlo coverage of the 95 % parameter intervals over a family of systems (issue 26.8).

Usage::

    python scripts/coverage.py [--systems 20] [--overparametrised 3] [--replicates 50] \
        [--jobs 2] [--spare 10] [--out results/coverage] [--checkpoint PATH] [--rescore] \
        [--force]

Systems. The first ``--systems`` cases of the corpus (:mod:`freqid_casadi.systems.corpus`,
seed 0, at most :data:`MAX_POINTS` points) from its in-class families (``in-class``,
``modal-collocated``, ``modal-feedthrough``, ``negative-gain``) that are noisy, inside the
model class, without roots at the origin and with at most :data:`MAX_SECTIONS` sections
and whose replicate 0 the default fit explains (status "ok"; ``--spare`` more cases are
drawn for this screening, and the report lists those screened out); plus the
over-parametrised systems of :func:`overparametrised` (a model section more than the
system needs a zero pair: it must go to infinity, where it trades with the delay), the
first of them the one of issue 26. The truth of each: its modal frequencies and
dampings, delay and DC gain (signed). The sizes (points, sections) keep the default run
near 30 minutes on a loaded 2-core machine.

Replicates. Replicate ``r`` of a system multiplies its noiseless response by
``1 + sigma_i n_i`` (``n_i`` complex Gaussian, ``E|n_i|^2 = 1``, from
``default_rng([index, r])``), ``sigma_i`` the case's noise profile; weights ``1/sigma_i^2``
where the case gives its variance. Each is fitted with the default fit at the true order,
``freqid_casadi.fit(data, n_sections=<true>)``, and
:func:`~freqid_casadi.uncertainty.covariance.parameter_uncertainty` gives every
parameter's value, std and "determined" status (:mod:`freqid_casadi.uncertainty.determined`).
Fitted modes are matched to the true ones by nearest natural frequency (within 25 %).

Coverage. Per system and parameter: the fraction of replicates whose 95 % normal interval
holds the truth, over the replicates where it is reported determined ("reported"), and
over all with a finite std ("delta method, all"), each with its binomial standard error;
"in target" is the reported coverage in [0.90, 0.98].

Runs in a process pool of ``--jobs`` workers under ``nice``; every finished replicate is
appended to the checkpoint file (default in the temporary folder, named by the settings),
so a killed run started again with the same options and the same code goes on where it
stopped (records made by other code, told by a fingerprint of the package's source, are
fitted again); each
record keeps its pickled FitResult, and ``--rescore`` recomputes the intervals and
statuses from them (after a change of :mod:`freqid_casadi.uncertainty`) without refitting,
the checkpoint's fits of other code included (the report names the code that made them).
Writes
``--out`` atomically: ``report.md`` (first line: the command), ``coverage.json`` (every
number and every replicate) and ``coverage.png``.
"""

import argparse
import base64
import json
import math
import os
import pickle
import shlex
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np

from freqid_casadi import plots
from freqid_casadi.core.data import FrequencyData
from freqid_casadi.fitting.fit import fit
from freqid_casadi.report.environment import environment, environment_line
from freqid_casadi.report.folder import (code_fingerprint, generated_by_line, markdown_table,
                                         report_folder)
from freqid_casadi.studies.corpus import json_lines
from freqid_casadi.systems.corpus import CorpusSystem, case
from freqid_casadi.uncertainty.covariance import parameter_uncertainty

LEVEL = 0.95
Z = 1.959963984540054
TARGET = (0.90, 0.98)
FAMILIES = ("in-class", "modal-collocated", "modal-feedthrough", "negative-gain")
MAX_POINTS = 100
MAX_SECTIONS = 2
CORPUS_SEED = 0
#: Corpus cases drawn beyond --systems, in case some are screened out.
SPARE = 10

# --------------------------------------------------------------------------- systems

def _pair(w, zeta):
    r = -zeta * w + 1j * w * math.sqrt(1 - zeta * zeta)
    return [r, np.conj(r)]


def _unit_dc(zeros, poles, delay):
    g = 1.0
    for z, p in zip(zeros, poles):
        g *= abs(p) / (abs(z) if np.isfinite(z) else 1.0) / (1.0 if np.isfinite(z) else abs(p))
    return CorpusSystem(g, 0, np.asarray(zeros, complex), np.asarray(poles, complex),
                        np.zeros((0, 3)), 0.0, float(delay))


def overparametrised():
    """Systems a section short of zeros: list of dicts (name, truth, omega, sigma,
    n_sections, weights_given, index)."""
    w1, w2, w3 = 2 * np.pi * 5, 2 * np.pi * 17, 2 * np.pi * 40
    om = np.logspace(np.log10(2.0), np.log10(600.0), MAX_POINTS)
    specs = [   # (index: the replicates' seed, name, zeros, poles, delay, noise, omega)
        (10_000, "2 modes + 1 zero pair + 5 ms, 2 sections (issue 26)",
         _pair(60.0, 0.02) + [np.nan] * 2, _pair(w1, 0.02) + _pair(w2, 0.03), 0.005, 0.01, om),
        (10_002, "1 mode, no zero + 10 ms, 1 section, 0.5 % noise",
         [np.nan] * 2, _pair(w2, 0.03), 0.01, 0.005, np.logspace(0.5, 2.5, 120)),
        (10_001, "3 modes + 1 zero pair + 3 ms, 3 sections",
         _pair(60.0, 0.02) + [np.nan] * 4, _pair(w1, 0.02) + _pair(w2, 0.03)
         + _pair(w3, 0.01), 0.003, 0.01, om),
        (10_003, "2 modes, no zero + 2 ms, 2 sections, 2 % noise",
         [np.nan] * 4, _pair(w1, 0.05) + _pair(w2, 0.02), 0.002, 0.02, om),
    ]
    out = []
    for index, name, zeros, poles, h, noise, omega in specs:
        out.append({"name": name, "index": index, "family": "over-parametrised",
                    "truth": _unit_dc(zeros, poles, h), "omega": omega,
                    "sigma": np.full(omega.size, noise), "weights_given": False,
                    "n_sections": len(poles) // 2})
    return out


def corpus_systems(n, seed=CORPUS_SEED, max_index=2000):
    """The first ``n`` usable corpus cases (see the module notes), as dicts."""
    out = []
    for i in range(max_index):
        if len(out) == n:
            break
        if i % 9 not in (0, 1, 2, 4):            # families of FAMILIES, cheaply
            continue
        c = case(i, seed, max_points=MAX_POINTS)
        if (c.family not in FAMILIES or not c.in_class or c.noise == 0 or c.integrators
                or c.zeros_at_origin or c.n_sections > MAX_SECTIONS):
            continue
        out.append({"name": c.name, "index": c.index, "family": c.family, "truth": c.truth,
                    "omega": c.data.omega, "sigma": np.asarray(c.sigma),
                    "weights_given": c.variance_given, "n_sections": c.n_sections})
    return out


def truth_parameters(system):
    """``{name: value}``: delay, gain (DC, signed), omega_k and zeta_k by frequency."""
    t = system["truth"]
    if len(t.modes):
        modes = [(float(w), float(z)) for _, z, w in t.modes]
    else:
        modes = [(abs(p), -p.real / abs(p)) for p in t.poles if p.imag > 0]
    s0 = 1e-9 * float(np.min(system["omega"]))
    dc = CorpusSystem(t.gain, 0, t.zeros, t.poles, t.modes, t.feedthrough, 0.0).at(
        np.array([s0]))[0].real
    out = {"delay": float(t.delay), "gain": float(dc)}
    for k, (w, z) in enumerate(sorted(modes), 1):
        out[f"omega_{k}"], out[f"zeta_{k}"] = w, z
    return out


# --------------------------------------------------------------------------- replicates

def replicate_data(system, r):
    """Replicate ``r``: FrequencyData."""
    om, sigma = system["omega"], system["sigma"]
    rng = np.random.default_rng([int(system["index"]), int(r)])
    n = (rng.standard_normal(om.size) + 1j * rng.standard_normal(om.size)) / math.sqrt(2)
    w = 1 / sigma ** 2 if system["weights_given"] else None
    return FrequencyData(om, system["truth"](om) * (1 + sigma * n), system["name"], w)


def _reason_key(text):
    """A short name of a "not determined" reason (the sentences of
    :mod:`freqid_casadi.uncertainty.determined`)."""
    for part, key in (("fit's status", "fit status"), ("at its bound", "at bound"),
                      ("no finite", "singular"), ("within 3 std of its bound", "near 0"),
                      ("nearly cancel", "cancelling pair"),
                      ("trades with", "trades with a far or weak factor"),
                      ("known to", "weak factor"), ("the band", "outside the band")):
        if part in text:
            return key
    return text[:40]


def _entry(value, std, det, reason):
    return [float(value), float(std) if np.isfinite(std) else None, bool(det),
            _reason_key(reason) if reason else ""]


def score(system, res, rec):
    """Fill ``rec`` (a dict) from the FitResult ``res``: status, RMS, and the value, std,
    determined flag and reason of every tracked parameter (:func:`truth_parameters`)."""
    truth = truth_parameters(system)
    u = parameter_uncertainty(res)
    nd = u.not_determined
    p = rec["params"] = {}
    if "delay" in u.param_names:
        p["delay"] = _entry(u.delay, u.delay_std, "delay" not in nd, nd.get("delay", ""))
    p["gain"] = _entry(u.gain, u.gain_std, "log_gain" not in nd, nd.get("log_gain", ""))
    used = set()
    for k in range(1, 1 + sum(1 for n in truth if n.startswith("omega_"))):
        w = truth[f"omega_{k}"]
        cands = [(abs(math.log(m.omega_n / w)), j) for j, m in enumerate(u.modes)
                 if j not in used and abs(math.log(m.omega_n / w)) < math.log(1.25)]
        if not cands:
            continue
        j = min(cands)[1]
        used.add(j)
        m = u.modes[j]
        iw = u.param_names.index(f"omega_den[{m.section}]")
        iz = u.param_names.index(f"zeta_den[{m.section}]")
        p[f"omega_{k}"] = _entry(m.omega_n, m.omega_n_std, m.omega_n_determined, u.reasons[iw])
        p[f"zeta_{k}"] = _entry(m.zeta, m.zeta_std, m.zeta_determined, u.reasons[iz])
    rec.update(status=getattr(res.status, "value", res.status), rms=float(res.rms_rel_error),
               heteroscedastic=bool(u.heteroscedastic))
    return rec


def run_replicate(system, r):
    """Fit replicate ``r`` of ``system``; a JSON-ready record of its tracked parameters,
    with the pickled FitResult (base64, ``"fit"``) for :func:`rescore`."""
    t0 = time.perf_counter()
    rec = {"system": system["name"], "rep": int(r), "params": {}, "code": code_fingerprint()}
    try:
        res = fit(replicate_data(system, r), n_sections=system["n_sections"])
        score(system, res, rec)
        rec["fit"] = base64.b64encode(pickle.dumps(res)).decode("ascii")
    except Exception as exc:                           # a failed replicate is data too
        rec.update(status="error", error=f"{type(exc).__name__}: {exc}")
    rec["time"] = time.perf_counter() - t0
    return rec


def rescore(systems, recs):
    """Records re-scored from their pickled fits (after a change of the uncertainty
    code: no refit); records without a fit are kept as they are."""
    by_name = {s["name"]: s for s in systems}
    out = []
    for rec in recs:
        if "fit" in rec:
            res = pickle.loads(base64.b64decode(rec["fit"]))
            rec = score(by_name[rec["system"]], res, dict(rec))
        out.append(rec)
    return out


def _worker_init():
    import warnings

    warnings.simplefilter("ignore")          # resolution warnings of noisy replicates
    try:
        os.nice(10)
    except OSError:
        pass


def _read_checkpoint(path, rescore=False):
    """The checkpoint's records made by this code (:func:`code_fingerprint`), by (system,
    replicate); records of other code are set aside (said on stderr), to be fitted again.
    With ``rescore`` every record is kept (this code's where both exist): their fits are
    scored again by this code, which is what ``--rescore`` is for."""
    if not rescore:
        return {(r["system"], r["rep"]): r for r in json_lines(path, code_fingerprint())}
    code = code_fingerprint()
    out = {}
    for rec in sorted(json_lines(path), key=lambda r: r.get("code") == code):
        out[(rec["system"], rec["rep"])] = rec
    return out


def _run(todo, jobs, checkpoint, done, t0):
    if not todo:
        return
    with open(checkpoint, "a", encoding="utf-8") as fh, ProcessPoolExecutor(
            max_workers=jobs, initializer=_worker_init) as pool:
        futures = [pool.submit(run_replicate, s, r) for s, r in todo]
        for k, fut in enumerate(as_completed(futures), 1):
            rec = fut.result()
            done[(rec["system"], rec["rep"])] = rec
            fh.write(json.dumps(rec) + "\n")
            fh.flush()
            if k % 50 == 0:
                print(f"{k}/{len(todo)} replicates, {time.perf_counter() - t0:.0f} s",
                      file=sys.stderr, flush=True)


def monte_carlo(fixed, candidates, n, replicates, jobs, checkpoint, rescore=False):
    """Screen, then run every replicate (resuming from ``checkpoint``).

    Replicate 0 of every system is fitted first; the ``fixed`` systems are all kept, of
    the ``candidates`` the first ``n`` whose replicate 0 has status "ok" (a default fit
    that does not explain the data says nothing about its intervals: the other cases
    are listed as excluded). Returns the kept systems, the excluded ones with their
    replicate-0 status, every record of the kept ones, the wall time (s) and the number
    of new fits.
    """
    done = _read_checkpoint(checkpoint, rescore)
    before = len(done)
    t0 = time.perf_counter()
    screen = [(s, 0) for s in fixed + candidates if (s["name"], 0) not in done]
    _run(screen, jobs, checkpoint, done, t0)
    kept, excluded = list(fixed), []
    for s in candidates:
        st = done[(s["name"], 0)].get("status")
        if st == "ok" and len(kept) < len(fixed) + n:
            kept.append(s)
        elif st != "ok":
            excluded.append((s, st, done[(s["name"], 0)].get("rms")))
    todo = [(s, r) for r in range(1, replicates) for s in kept if (s["name"], r) not in done]
    _run(todo, jobs, checkpoint, done, t0)
    recs = [done[(s["name"], r)] for s in kept for r in range(replicates)]
    return kept, excluded, recs, time.perf_counter() - t0, len(done) - before


def from_json(path, known, candidates, jobs, checkpoint):
    """The first stage of a previous run (its ``coverage.json``): the systems it kept (by
    name, among ``known``), its records as recorded (estimates, stds, statuses), and the
    corpus candidates it screened out (those drawn before its last kept one; their
    replicate 0 is fitted again, or read from ``checkpoint``, for the status)."""
    with open(path, encoding="utf-8") as fh:
        old = json.load(fh)
    by_name = {s["name"]: s for s in known}
    names = [s["name"] for s in old["systems"]]
    missing = [n for n in names if n not in by_name]
    if missing:
        raise SystemExit(f"error: {path} holds systems these options do not draw: "
                         f"{missing}; pass its --systems / --overparametrised")
    systems = [by_name[n] for n in names]
    kept = set(names)
    last = max((i for i, c in enumerate(candidates) if c["name"] in kept), default=-1)
    screened = [c for c in candidates[:last + 1] if c["name"] not in kept]
    done = _read_checkpoint(checkpoint)
    before = len(done)
    _run([(c, 0) for c in screened if (c["name"], 0) not in done], jobs, checkpoint, done,
         time.perf_counter())
    excluded = [(c, done[(c["name"], 0)].get("status"), done[(c["name"], 0)].get("rms"))
                for c in screened]
    return systems, excluded, old["records"], 0.0, len(done) - before


#: A system gets the follow-up's fresh replicates when one of its pairs has an exact
#: two-sided binomial p-value below this (evidence against 95 %, either side).
FOLLOW_P = 0.1


def follow_up(systems, rows, first, extra, jobs, checkpoint, rescore=False):
    """Fresh replicates ``first ... first + extra - 1`` of every system with a pair whose
    coverage is in doubt (``p_value < FOLLOW_P``): the records (resuming from
    ``checkpoint``) and the new fits. Their coverage is independent of the selection, so
    it tells a miscalibrated pair (still off) from binomial noise (back near 95 %)."""
    doubt = {r["system"] for r in rows if r["p_value"] is not None
             and r["p_value"] < FOLLOW_P}
    chosen = [s for s in systems if s["name"] in doubt]
    done = _read_checkpoint(checkpoint, rescore)
    before = len(done)
    todo = [(s, r) for r in range(first, first + extra) for s in chosen
            if (s["name"], r) not in done]
    _run(todo, jobs, checkpoint, done, time.perf_counter())
    recs = [done[(s["name"], r)] for s in chosen for r in range(first, first + extra)]
    return chosen, recs, len(done) - before


# --------------------------------------------------------------------------- summary

def _cov(hits):
    n = len(hits)
    if n == 0:
        return None, None, 0
    c = float(np.mean(hits))
    return c, math.sqrt(max(c * (1 - c), 0.25 / n) / n), n


def _p_outside(n):
    """Probability that ``n`` intervals of true coverage 95 % cover outside the target."""
    from scipy import stats

    lo, hi = math.ceil(TARGET[0] * n - 1e-9), math.floor(TARGET[1] * n + 1e-9)
    return float(stats.binom.cdf(lo - 1, n, 0.95) + stats.binom.sf(hi, n, 0.95))


def _consistent(c, n):
    """The coverage ``c`` of ``n`` intervals is within 2 binomial standard errors (of a
    95 % coverage) of the target range."""
    se = math.sqrt(0.95 * 0.05 / n)
    return TARGET[0] - 2 * se <= c <= TARGET[1] + 2 * se


def _target_counts(n):
    """The hit counts of ``n`` intervals whose coverage lies in the target."""
    return range(math.ceil(TARGET[0] * n - 1e-9), math.floor(TARGET[1] * n + 1e-9) + 1)


def p_in_target(n, level=LEVEL):
    """Probability that ``n`` intervals of true coverage ``level`` cover inside the target
    (0.885 for n = 50 at 95 %: 50 of 50 has probability 0.077, 44 or fewer 0.038)."""
    from scipy import stats

    k = _target_counts(n)
    if len(k) == 0:
        return 0.0
    return float(stats.binom.cdf(k[-1], n, level) - stats.binom.cdf(k[0] - 1, n, level))


def binomial_p(hits, n, level=LEVEL):
    """Exact two-sided binomial p-value of ``hits`` covers in ``n`` under coverage
    ``level`` (twice the smaller tail, at most 1)."""
    from scipy import stats

    if n == 0:
        return None
    return float(min(1.0, 2 * min(stats.binom.cdf(hits, n, level),
                                  stats.binom.sf(hits - 1, n, level))))


def _p_below(n, alpha, level=LEVEL):
    """Probability that a calibrated pair of ``n`` intervals has ``binomial_p < alpha``."""
    from scipy import stats

    k = np.arange(n + 1)
    pv = np.array([binomial_p(int(h), n, level) for h in k])
    return float(np.sum(stats.binom.pmf(k, n, level)[pv < alpha]))


def expectation(rows, alpha=0.01, level=LEVEL):
    """What calibrated intervals (true coverage ``level``) would give, from each pair's own
    number of reported replicates: pairs expected in the target (mean and SD: a sum of
    Bernoulli), pairs expected with ``binomial_p < alpha``, and the Bonferroni bound
    ``0.05 / pairs`` under which a pair's coverage is called miscalibrated."""
    rep = [r for r in rows if r["reported"]]
    p_in = [p_in_target(r["reported"], level) for r in rep]
    p_lo = [_p_below(r["reported"], alpha, level) for r in rep]
    return {"pairs": len(rep), "in_target": sum(1 for r in rep if r["in_target"]),
            "expected_in_target": float(sum(p_in)),
            "sd_in_target": float(math.sqrt(sum(p * (1 - p) for p in p_in))),
            "alpha": alpha, "below_alpha": sum(1 for r in rep if r["p_value"] < alpha),
            "expected_below_alpha": float(sum(p_lo)),
            "bonferroni": 0.05 / max(len(rep), 1),
            "miscalibrated": [(r["system"], r["parameter"]) for r in rep
                              if r["p_value"] < 0.05 / len(rep)]}


def standardized(systems, recs, keys=("kind", "family")):
    """Standardized errors ``(estimate - truth) / std`` of the reported parameters, by
    parameter kind (and family and kind): n, mean and SD, each with its standard error
    under calibration (``1 / sqrt(n)``, ``1 / sqrt(2 (n - 1))``). A bias shows in the mean,
    a wrong width in the SD, long before either moves the coverage of 50 replicates."""
    truth = {s["name"]: truth_parameters(s) for s in systems}
    family = {s["name"]: s["family"] for s in systems}
    groups = {}
    for r in recs:
        for name, (v, sd, det, _) in r.get("params", {}).items():
            if not det or sd is None or sd <= 0:
                continue
            z = (v - truth[r["system"]][name]) / sd
            kind = name.split("_")[0]
            groups.setdefault(kind, []).append(z)
            if "family" in keys:
                groups.setdefault(f"{family[r['system']]}: {kind}", []).append(z)
    out = {}
    for key, z in groups.items():
        z = np.asarray(z)
        n = z.size
        out[key] = {"n": int(n), "mean": float(z.mean()), "mean_se": 1 / math.sqrt(n),
                    "sd": float(z.std(ddof=1)) if n > 1 else None,
                    "sd_se": 1 / math.sqrt(2 * (n - 1)) if n > 1 else None,
                    "coverage": float(np.mean(np.abs(z) <= Z))}
    return out


def summarize(systems, recs):
    """Per system and parameter: coverage (reported, all), its SE, not-determined counts."""
    rows = []
    for s in systems:
        truth = truth_parameters(s)
        mine = [r for r in recs if r["system"] == s["name"]]
        for name, tv in truth.items():
            hits_all, hits_det, reasons, missing = [], [], {}, 0
            for r in mine:
                e = r["params"].get(name)
                if e is None:
                    missing += 1
                    continue
                v, sd, det, why = e
                hit = sd is not None and abs(v - tv) <= Z * sd
                if sd is not None:
                    hits_all.append(hit)
                if det:
                    hits_det.append(hit)
                else:
                    reasons[why] = reasons.get(why, 0) + 1
            c, se, n = _cov(hits_det)
            ca, sea, na = _cov(hits_all)
            rows.append({"system": s["name"], "family": s["family"], "parameter": name,
                         "truth": tv, "replicates": len(mine), "unmatched": missing,
                         "reported": n, "coverage": c, "se": se,
                         "coverage_all": ca, "se_all": sea, "n_all": na,
                         "not_determined": sum(reasons.values()), "reasons": reasons,
                         "in_target": None if c is None else TARGET[0] <= c <= TARGET[1],
                         "consistent": None if c is None else _consistent(c, n),
                         "p_value": binomial_p(int(round(c * n)), n) if n else None,
                         "in_target_all": None if ca is None else
                         TARGET[0] <= ca <= TARGET[1]})
    return rows


def pooled(rows, recs_by_kind=None):
    """Coverage pooled over the systems, by parameter kind (delay, gain, omega, zeta)."""
    out = {}
    for kind in ("delay", "gain", "omega", "zeta"):
        sel = [r for r in rows if r["parameter"].split("_")[0] == kind and r["reported"]]
        n = sum(r["reported"] for r in sel)
        hits = sum(round(r["coverage"] * r["reported"]) for r in sel)
        sel_a = [r for r in rows if r["parameter"].split("_")[0] == kind and r["n_all"]]
        na = sum(r["n_all"] for r in sel_a)
        ha = sum(round(r["coverage_all"] * r["n_all"]) for r in sel_a)
        nd = sum(r["not_determined"] for r in rows if r["parameter"].split("_")[0] == kind)
        out[kind] = {"reported": n, "coverage": hits / n if n else None,
                     "se": math.sqrt(0.95 * 0.05 / n) if n else None,
                     "n_all": na, "coverage_all": ha / na if na else None,
                     "not_determined": nd}
    return out


def _pct(c, se=None):
    if c is None:
        return "–"
    return f"{100 * c:.1f}" + (f" ± {100 * se:.1f}" if se is not None else "")


def figure(rows):
    """Reported coverage (dots, ±1 SE) and all-replicate coverage (crosses) per row."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(12, 4.5))
    x = np.arange(len(rows))
    for k, r in enumerate(rows):
        if r["coverage_all"] is not None:
            ax.plot(k, 100 * r["coverage_all"], "x", color="0.6")
        if r["coverage"] is not None:
            ax.errorbar(k, 100 * r["coverage"], yerr=100 * r["se"], fmt="o", ms=3,
                        color="C0" if r["in_target"] else "C3")
    ax.axhspan(100 * TARGET[0], 100 * TARGET[1], color="C2", alpha=0.15)
    ax.axhline(95, color="C2", lw=0.8)
    ax.set_xticks(x)
    ax.set_xticklabels([f"{r['system'].split(',')[0][:24]}: {r['parameter']}" for r in rows],
                       rotation=90, fontsize=5)
    ax.set_ylabel("coverage of the 95 % interval (%)")
    ax.set_ylim(max(0, min([100 * (r["coverage_all"] or 1) for r in rows] + [80]) - 5), 101)
    ax.set_title("dots: reported (determined) parameters ± 1 SE (red: outside 90-98 %); "
                 "crosses: every replicate's delta-method interval", fontsize=8)
    fig.tight_layout()
    return fig


def _z_rows(zs):
    def off(v):
        return (abs(v["mean"]) > 3 * v["mean_se"]
                or (v["sd"] is not None and abs(v["sd"] - 1) > 3 * v["sd_se"]))
    keys = [k for k in zs if ":" not in k] + [k for k in zs if ":" in k and off(zs[k])]
    return [(k, zs[k]["n"], f"{zs[k]['mean']:+.3f} ± {zs[k]['mean_se']:.3f}",
             "–" if zs[k]["sd"] is None else f"{zs[k]['sd']:.3f} ± {zs[k]['sd_se']:.3f}",
             f"{100 * zs[k]['coverage']:.1f}") for k in keys]


def follow_up_lines(rows, fresh_rows, chosen, extra, replicates):
    """The follow-up section: coverage of the doubted pairs on fresh replicates."""
    if not chosen:
        return []
    fresh = {(r["system"], r["parameter"]): r for r in fresh_rows}
    doubt = [r for r in rows if r["p_value"] is not None and r["p_value"] < FOLLOW_P]
    table, still = [], []
    for r in doubt:
        f = fresh.get((r["system"], r["parameter"]))
        if f is None or not f["reported"]:
            continue
        if f["p_value"] < 0.05 / len(doubt):
            still.append(r)
        table.append((r["system"], r["parameter"], f"{r['reported']}",
                      _pct(r["coverage"]), f"{r['p_value']:.3f}", f"{f['reported']}",
                      _pct(f["coverage"], f["se"]), f"{f['p_value']:.3f}"))
    hits = sum(round(f["coverage"] * f["reported"]) for f in fresh_rows if f["reported"])
    n = sum(f["reported"] for f in fresh_rows if f["reported"])
    return ["## Follow-up: fresh replicates of the doubted systems", "",
            f"Every system with a pair at binomial p < {FOLLOW_P:g} in the first "
            f"{replicates} replicates ({len(chosen)} systems) got {extra} fresh replicates "
            f"({replicates} ... {replicates + extra - 1}); their coverage does not depend on "
            "the selection. A miscalibrated pair stays off; binomial noise comes back near "
            f"95 %. Still off on the fresh replicates (p < 0.05 / {len(doubt)}): "
            + (", ".join(f"{r['system']}: {r['parameter']}" for r in still) or "none")
            + f". Every parameter of these systems pooled on the fresh replicates: "
            f"{_pct(hits / n if n else None, math.sqrt(0.95 * 0.05 / n) if n else None)} "
            f"% of {n}.", "",
            markdown_table(table, ["system", "parameter", "reported", "coverage (%)", "p",
                                   "fresh reported", "fresh coverage (%)", "fresh p"],
                           "llrrrrrr"), ""]


def report_lines(command, systems, rows, pool, wall, new, jobs, replicates, recs):
    """The Markdown report."""
    zs = standardized(systems, recs)
    n_fail = sum(1 for r in recs if r.get("status") == "error")
    status = {}
    for r in recs:
        status[r.get("status")] = status.get(r.get("status"), 0) + 1
    fit_time = sum(r.get("time", 0) for r in recs)
    rep = [r for r in rows if r["reported"]]
    inside = sum(1 for r in rep if r["in_target"])
    consistent = sum(1 for r in rep if r["consistent"])
    big = [r for r in rep if r["reported"] >= 20]
    ex = expectation(rows)
    nd_rows = [r for r in rows if r["not_determined"]]
    never = [r for r in rows if not r["reported"]]
    n_over = sum(1 for s in systems if s["family"] == "over-parametrised")
    counts = ", ".join(f"{k}: {v}" for k, v in sorted(status.items(), key=str))
    md = [generated_by_line(command), "",
          "# Coverage of the 95 % parameter intervals over a family of systems (issue 26, "
          "item 8)", "",
          f"{len(systems)} systems: {len(systems) - n_over} "
          f"from the corpus (seed {CORPUS_SEED}, families {', '.join(FAMILIES)}; noisy, in "
          f"the class, at most {MAX_SECTIONS} sections and {MAX_POINTS} points) and "
          f"{n_over} over-parametrised "
          "ones (a section whose zero pair must go to infinity). Each with "
          f"{replicates} noisy replicates, fitted with `fc.fit(data, n_sections=<true>)` "
          "(every other option at its default); 95 % normal intervals from "
          "`parameter_uncertainty` (`FitResult.uncertainty`).", "",
          f"Fits: {len(recs)} ({counts}"
          f"; {n_fail} raised). This invocation: {new} new fits in {wall:.0f} s ({jobs} "
          f"workers under nice, 2-core machine, load average {os.getloadavg()[0]:.1f} at "
          f"the end); the fits' own wall times summed over all replicates {fit_time:.0f} s "
          f"(the others come from the checkpoint).{_codes_line(recs)} This invocation ran "
          f"on `{environment_line(environment())}`.", "",
          "## Result", "",
          f"Reported (determined) parameters in the target [{TARGET[0]:.2f}, {TARGET[1]:.2f}]: "
          f"**{inside} of {len(rep)}** system-parameter pairs. Were every interval "
          f"calibrated (true coverage 95 %), the expected count is **"
          f"{ex['expected_in_target']:.1f} ± {ex['sd_in_target']:.1f}** (from each pair's "
          f"own number of reported replicates: with {replicates} a calibrated pair falls "
          f"outside the target by chance with probability {_p_outside(replicates):.3f} -- "
          f"{replicates} of {replicates} has probability {0.95 ** replicates:.3f}, "
          f"{math.ceil(TARGET[0] * replicates) - 1} or fewer "
          f"{_p_outside(replicates) - 0.95 ** replicates:.3f}; fewer replicates, more "
          f"often). Within 2 binomial standard errors of the target: **{consistent} of "
          f"{len(rep)}** (of the {len(big)} pairs reported in at least 20 replicates: "
          f"{sum(1 for r in big if r['in_target'])} in the target, "
          f"{sum(1 for r in big if r['consistent'])} within 2 SE).", "",
          f"Exact two-sided binomial test of a 95 % coverage per pair: "
          f"**{ex['below_alpha']}** pairs at p < {ex['alpha']:g} (expected by chance "
          f"{ex['expected_below_alpha']:.1f}); miscalibrated at the Bonferroni level "
          f"p < 0.05 / {ex['pairs']} = {ex['bonferroni']:.1e}: "
          + (", ".join(f"{a}: {b}" for a, b in ex["miscalibrated"]) or "**none**")
          + ". The standardized errors below are the sharper test.", "",
          f"Not determined: {sum(r['not_determined'] for r in rows)} parameter estimates of "
          f"{sum(r['replicates'] - r['unmatched'] for r in rows)} "
          f"({len(nd_rows)} system-parameter pairs in at least one replicate; "
          f"{len(never)} never reported determined).", "",
          "### Pooled over the systems", "",
          markdown_table([(k, v["reported"], _pct(v["coverage"], v["se"]), v["not_determined"],
                           v["n_all"], _pct(v["coverage_all"])) for k, v in pool.items()],
                         ["parameter kind", "reported", "coverage (%) ± SE", "not determined",
                          "all with a std", "coverage of all (%)"], "lrrrrr"), "",
          "### Standardized errors", "",
          "`(estimate - truth) / std` of the reported parameters: calibrated intervals give "
          "mean 0 and SD 1 (± the SE shown); a bias moves the mean, a wrong width the SD. "
          "By parameter kind, then the family rows more than 3 SE off in either.", "",
          markdown_table(_z_rows(zs), ["parameters", "n", "mean ± SE", "SD ± SE",
                                       "coverage (%)"], "lrrrr"), "",
          "### Per system and parameter", "",
          "`reported`: replicates where the parameter is determined; `coverage`: of those "
          "(± binomial SE); `all`: coverage of every replicate's delta-method interval, "
          "what the report said before the \"not determined\" status; `not det.`: "
          "replicates reported not determined, and why.", ""]
    table = []
    for r in rows:
        why = ", ".join(f"{k} {v}" for k, v in sorted(r["reasons"].items(), key=lambda t: -t[1]))
        table.append((r["system"], r["parameter"], f"{r['truth']:.6g}", r["reported"],
                      _pct(r["coverage"], r["se"]), _pct(r["coverage_all"], r["se_all"]),
                      f"{r['not_determined']}" + (f" ({why})" if why else ""),
                      r["unmatched"], "–" if r["in_target"] is None else
                      ("yes" if r["in_target"] else "no"),
                      "–" if r["consistent"] is None else
                      ("yes" if r["consistent"] else "no"),
                      "–" if r["p_value"] is None else f"{r['p_value']:.3f}"))
    md += [markdown_table(table, ["system", "parameter", "truth", "reported",
                                  "coverage (%)", "all (%)", "not det.", "unmatched",
                                  "in target", "within 2 SE", "binomial p"],
                          "llrrrrlrllr"), "",
           "`unmatched`: replicates whose fit has no mode within 25 % of the true one "
           "(a fit that missed the mode; no interval to test).", "",
           "![coverage](coverage.png)", "",
           "## What \"not determined\" means", "",
           "`ParameterUncertainty.determined` / `.reasons` / `.not_determined` "
           "(`freqid_casadi.uncertainty.determined`): a parameter of a fit whose status is "
           "not ok, at its bound, with no finite std, whose 95 % interval reaches 0, of a "
           "factor more than 2 times outside the band or known to worse than 5 %, or "
           "sharing more than half its variance with such a factor (the delay against a "
           "zero pair going to infinity) is reported not determined with the reason; its "
           "std is kept, its interval is not to be trusted.", "",
           "Noise level: with the noise from the residuals of an ok fit, when their level "
           "changes over the band (Bartlett's test over blocks of frequency, p < 0.01) the "
           "covariance is the sandwich with their local level "
           f"(`heteroscedastic`): {sum(1 for r in recs if r.get('heteroscedastic'))} of "
           f"{len(recs)} replicates here.", ""]
    return md


def excluded_lines(excluded, candidates):
    """The screened-out corpus cases."""
    if not excluded:
        return [f"No corpus case was screened out ({len(candidates)} drawn).", ""]
    rows = [(s["name"], st, "–" if rms is None else f"{rms:.3g}") for s, st, rms in excluded]
    return ["## Corpus cases screened out", "",
            "Replicate 0 fitted by the default fit without status \"ok\" (the fit does not "
            "explain the data, so its intervals are not tested here; its "
            "`ParameterUncertainty` reports every parameter not determined for that "
            "reason). These are fit failures of the default pipeline, counted in "
            "results/corpus.", "",
            markdown_table(rows, ["case", "status", "RMS rel. error"], "llr"), ""]


def _json_text(js):
    """``js`` as indented JSON with each replicate record on one line (thousands of records
    indented one value per line made a file of 400 000 lines)."""
    held = {}

    def hold(records):
        key = f"@records-{len(held)}@"
        held[key] = "[\n" + ",\n".join(json.dumps(r) for r in records) + "\n]"
        return key
    out = dict(js, records=hold(js["records"]))
    if js.get("follow_up"):
        out["follow_up"] = dict(js["follow_up"], records=hold(js["follow_up"]["records"]))
    text = json.dumps(out, indent=1)
    for key, value in held.items():
        text = text.replace(json.dumps(key), value, 1)
    return text + "\n"


def _codes_line(recs):
    """" Fits made by code ...": the source fingerprints of the records' fits when one is
    not this code's (a ``--rescore`` of an earlier run's fits)."""
    codes = Counter(r.get("code", "unknown") for r in recs)
    if set(codes) <= {code_fingerprint()}:
        return ""
    made = ", ".join(f"{n} by code {c}" for c, n in codes.most_common())
    return (f" Fits made {made} (this code: {code_fingerprint()}); their intervals and "
            "statuses computed by this code (`--rescore`).")


def default_checkpoint(n_systems, n_over, replicates):
    """Checkpoint file named by the settings, in the temporary folder."""
    return os.path.join(tempfile.gettempdir(), f"freqid_coverage_s{n_systems}_o{n_over}"
                        f"_r{replicates}_p{MAX_POINTS}.jsonl")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--systems", type=int, default=20, help="corpus systems (default 20)")
    ap.add_argument("--overparametrised", type=int, default=3,
                    help="over-parametrised systems, 0-4 (default 3)")
    ap.add_argument("--replicates", type=int, default=50)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="results/coverage")
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--spare", type=int, default=SPARE,
                    help=f"corpus cases drawn beyond --systems for the screening ({SPARE})")
    ap.add_argument("--follow-up", type=int, default=0, metavar="R",
                    help=f"R fresh replicates of every system with a pair at binomial "
                         f"p < {FOLLOW_P:g} (default 0: none)")
    ap.add_argument("--from-json", metavar="PATH", default=None,
                    help="take the first stage (systems, replicates and their recorded "
                         "estimates) from a previous run's coverage.json instead of fitting "
                         "it; with --follow-up the fresh replicates are fitted by this code")
    ap.add_argument("--rescore", action="store_true",
                    help="recompute every record's intervals from its stored fit (the "
                         "checkpoint's fits of other code too: they are scored by this code)")
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    for name, low in (("systems", 0), ("replicates", 1), ("jobs", 1), ("spare", 0),
                      ("follow_up", 0)):
        if getattr(args, name) < low:
            ap.error(f"--{name} must be >= {low}, got {getattr(args, name)}")
    if not 0 <= args.overparametrised <= 4:
        ap.error(f"--overparametrised must be in 0..4, got {args.overparametrised}")
    command = "python scripts/coverage.py " + " ".join(
        shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    import matplotlib

    matplotlib.use("Agg")
    try:
        os.nice(10)
    except OSError:
        pass
    fixed = overparametrised()[:args.overparametrised]
    candidates = corpus_systems(args.systems + args.spare) if args.systems else []
    ckpt = args.checkpoint or default_checkpoint(args.systems, args.overparametrised,
                                                 args.replicates)
    if args.from_json:
        systems, excluded, recs, wall, new = from_json(args.from_json, fixed + candidates,
                                                       candidates, args.jobs, ckpt)
        args.replicates = max(r["rep"] for r in recs) + 1
    else:
        systems, excluded, recs, wall, new = monte_carlo(fixed, candidates, args.systems,
                                                         args.replicates, args.jobs, ckpt,
                                                         args.rescore)
    if args.rescore:
        recs = rescore(systems, recs)
    rows = summarize(systems, recs)
    pool = pooled(rows)
    chosen, fresh, fresh_rows = [], [], []
    if args.follow_up:
        chosen, fresh, new_fresh = follow_up(systems, rows, args.replicates, args.follow_up,
                                             args.jobs, ckpt, args.rescore)
        new += new_fresh
        if args.rescore:
            fresh = rescore(systems, fresh)
        fresh_rows = summarize(chosen, fresh)
    md = report_lines(command.strip(), systems, rows, pool, wall, new, args.jobs,
                      args.replicates, recs)
    first = None
    if args.from_json:
        with open(args.from_json, encoding="utf-8") as fh:
            prev = json.load(fh)
        first = (prev.get("first_stage") or {}).get("command") or prev.get("command")
        k = md.index("## Result")
        md[k:k] = [f"First stage: the {len(recs)} records of `{args.from_json}` as that run "
                   f"recorded them (`{first}`; no refit, its code's estimates and "
                   "intervals); the follow-up's fresh replicates are fitted and scored by "
                   "this code.", ""]
    md += follow_up_lines(rows, fresh_rows, chosen, args.follow_up, args.replicates)
    md += excluded_lines(excluded, candidates)
    js = {"command": command.strip(), "level": LEVEL, "target": TARGET,
          "replicates": args.replicates, "wall_time_s": wall, "new_fits": new,
          "systems": [{"name": s["name"], "family": s["family"], "index": s["index"],
                       "n_sections": s["n_sections"], "n_points": int(s["omega"].size),
                       "noise_rms": float(np.sqrt(np.mean(s["sigma"] ** 2))),
                       "weights_given": bool(s["weights_given"]),
                       "truth": truth_parameters(s)} for s in systems],
          "first_stage": {"from": args.from_json, "command": first} if first else None,
          "excluded": [{"name": c["name"], "status": st, "rms": rms}
                       for c, st, rms in excluded],
          "rows": rows, "pooled": pool, "expectation": expectation(rows),
          "standardized": standardized(systems, recs),
          "follow_up": {"replicates": args.follow_up, "systems": [c["name"] for c in chosen],
                        "rows": fresh_rows,
                        "records": [{k: v for k, v in r.items() if k != "fit"}
                                    for r in fresh]},
          "records": [{k: v for k, v in r.items() if k != "fit"} for r in recs]}
    with report_folder(args.out, args.force) as (tmp, _):
        with open(os.path.join(tmp, "report.md"), "w", encoding="utf-8") as fh:
            fh.write("\n".join(md) + "\n")
        with open(os.path.join(tmp, "coverage.json"), "w", encoding="utf-8") as fh:
            fh.write(_json_text(js))
        plots.save_figure(figure(rows), os.path.join(tmp, "coverage.png"))
    for k, v in pool.items():
        print(f"{k:6s} reported {v['reported']:5d} coverage {_pct(v['coverage'])} % "
              f"(all {_pct(v['coverage_all'])} %), not determined {v['not_determined']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
