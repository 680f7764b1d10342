"""Ablation study: IPOPT vs the thesis's barrier-LM, and IPOPT's options one at a time (layer L5).

For each example (data and model structure, e.g. the CLI's ``EXAMPLES``) the study fits

* the **method comparison** (SPEC §3): IPOPT with true bounds (the package default) against
  the thesis's log-barrier + Levenberg-Marquardt with the faithful ``"thesis"`` damping
  ``sigma*I`` and with ``"marquardt"`` damping ``sigma*diag(A)``, all on the same data and the
  same main loop;
* the **IPOPT ablations**, one factor at a time from the default
  (:data:`DEFAULT_OPTIONS`): gauge, warm start, new-section initialisation, Hessian,
  variable scaling and the delay's upper bound (:func:`variants`).

Every number goes to ``ablation.json``; ``report.md`` shows them in tables (4 significant
digits) with figures, and ends its first section with conclusions computed from the numbers
by :func:`conclusions` (no hand-written claims). A variant that raises or returns a
non-finite error is kept as ``status="failed"`` with its message, never dropped.

The report folder (:func:`write_ablation_report`)::

    report.md                       first line: the command (report.generated_by_line)
    ablation.json                   every number of report.md, and per-stage records
    stages_<X>.png                  max error after each stage, IPOPT vs barrier-LM
    time_<X>.png                    max error against cumulative wall time (time to reach)
    rel_error_<X>.png               final relative error against frequency
    ablation_<X>.png                final max error and wall time of every variant

It is built in a temporary sibling folder and renamed into place when complete, as
:func:`freqid_casadi.report.write_fit_report` does.

"Time to reach" an error ``e`` (:func:`time_to_reach`): the cumulative stage wall time at the
first stage whose max relative error over all data is ``<= e``; ``None`` (n/a) if no stage
reaches it.
"""

import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from . import report
from ._io import atomic_write_text
from .errors import OptionError
from .fit import fit
from .options import options_from_keywords

__all__ = ["Variant", "variants", "run_ablation", "render_ablation", "conclusions",
           "time_to_reach", "write_ablation_report", "DEFAULT_OPTIONS", "LM_OPTIONS",
           "QUICK", "NEAR_BOUND", "VARIANT_COLUMNS", "ABLATION_FILES", "ABLATION_FORMAT",
           "ABLATION_VERSION"]

ABLATION_FORMAT = "freqid_casadi.ablation_report"
ABLATION_VERSION = 1

#: The IPOPT default every ablation starts from (the defaults of :func:`~freqid_casadi.fit.fit`).
DEFAULT_OPTIONS = dict(method="ipopt", gauge="dc", init="peak", scale_l=1.0, hessian="exact",
                       warm_start="primal-dual", scaled=True, bound_delay=True,
                       max_iter=100, final_max_iter=500)

#: Options of the barrier-LM stage solver besides the damping (the caps of the run):
#: ``max_inner`` = k_max, trial steps per inner LM solve (the solver's default is 500; 50
#: keeps the 27-section example C at a few minutes per variant on 2 cores); the outer loop
#: runs t = 1, 20, 400, ... <= 1e12 (10 barrier problems per stage, thesis code).
LM_OPTIONS = dict(max_inner=50, t0=1.0, t_factor=20.0, t_max=1e12)

#: The reduced problem of ``quick=True``: each example windowed to its first ``n_points``
#: points, with ``n_sections`` sections (at most its own number), and the barrier-LM's
#: ``max_inner`` lowered to ``lm_max_inner``.
QUICK = dict(n_points=300, n_sections=3, examples=("A", "fractional"), lm_max_inner=100)

#: A model parameter counts as "at or near its bound" when ``beta_i <= NEAR_BOUND`` (in the
#: model's units: s, rad/s or dimensionless), or the delay is within a relative NEAR_BOUND of
#: its upper bound ``delay_max``.
NEAR_BOUND = 1e-6

#: Files of the report folder other than the per-example figures.
ABLATION_FILES = ("ablation.json", "report.md")

#: Relative slack of "reached": the stage records and the final result compute the same
#: error along different code paths (rounding differences ~1e-15).
_REACH_RTOL = 1e-9

_FIGURES = ("stages", "time", "rel_error", "ablation")
_DASH = "—"


@dataclass(frozen=True, eq=False)
class Variant:
    """One fit configuration of the study.

    Attributes
    ----------
    key : str
        Short identifier, unique within an example (e.g. ``"lm-thesis"``, ``"gauge-b1"``).
    group : str
        ``"method"`` for the IPOPT vs barrier-LM comparison, else the ablated factor
        (``"gauge"``, ``"warm start"``, ``"init"``, ``"hessian"``, ``"scaling"``,
        ``"delay bound"``).
    label : str
        How the report names it.
    options : dict
        Keyword arguments of :func:`~freqid_casadi.fit.fit` that differ from
        :data:`DEFAULT_OPTIONS`.
    note : str
        Remark printed under the table (empty if none).
    """

    key: str
    group: str
    label: str
    options: dict = field(default_factory=dict)
    note: str = ""

    def fit_options(self):
        """:data:`DEFAULT_OPTIONS` updated with this variant's options (a new dict)."""
        opts = dict(DEFAULT_OPTIONS)
        opts.update(self.options)
        return opts


def _lm_options(quick):
    """The barrier-LM options of a run (without the damping)."""
    return dict(LM_OPTIONS, max_inner=QUICK["lm_max_inner"]) if quick else dict(LM_OPTIONS)


def _lm(damping, quick=False):
    return {"method": "barrier-lm", "lm_options": dict(_lm_options(quick), damping=damping)}


def variants(*, delay=True, quick=False):
    """The variants of one example, the IPOPT default first.

    Parameters
    ----------
    delay : bool
        Whether the example fits a delay (else the delay-bound ablation is left out: the
        delay is fixed at 0 and has no bound).
    quick : bool
        The reduced set of the test suite: IPOPT, barrier-LM with Marquardt damping, and
        gauge b1.

    Returns
    -------
    tuple of Variant
    """
    ipopt = Variant("ipopt", "method", "IPOPT (default)")
    lm_t = Variant("lm-thesis", "method", "barrier-LM, thesis damping", _lm("thesis"))
    lm_m = Variant("lm-marquardt", "method", "barrier-LM, Marquardt damping",
                   _lm("marquardt", quick))
    b1 = Variant("gauge-b1", "gauge", "gauge b1", {"gauge": "b1"})
    if quick:
        return (ipopt, lm_m, b1)
    out = [
        ipopt, lm_t, lm_m, b1,
        Variant("gauge-raw-l2", "gauge", "gauge raw, scale_l=2", {"gauge": "raw", "scale_l": 2.0},
                note="scale_l rescales only the identity initial section; with the default "
                     "init=peak it has no effect, so this row isolates the gauge."),
        Variant("warm-none", "warm start", "warm start none", {"warm_start": "none"}),
        Variant("warm-primal", "warm start", "warm start primal", {"warm_start": "primal"}),
        Variant("init-identity", "init", "init identity", {"init": "identity"}),
        Variant("init-identity-raw-l2", "init", "init identity + gauge raw, scale_l=2",
                {"init": "identity", "gauge": "raw", "scale_l": 2.0},
                note="two factors at once: the thesis's own start (identity section scaled "
                     "by l=2 in the raw gauge)."),
        Variant("hessian-gn", "hessian", "Hessian gauss-newton", {"hessian": "gauss-newton"}),
        Variant("hessian-lbfgs", "hessian", "Hessian limited-memory",
                {"hessian": "limited-memory"}),
        Variant("unscaled", "scaling", "variables unscaled", {"scaled": False}),
    ]
    if delay:
        out.append(Variant("delay-unbounded", "delay bound", "delay unbounded above",
                           {"bound_delay": False}))
    return tuple(out)


# ----------------------------------------------------------------------------- numbers


def time_to_reach(stages, target):
    """Cumulative wall time (s) at the first stage whose max error is ``<= target``.

    Parameters
    ----------
    stages : sequence of StageRecord or of dict
        Per-stage records in order, with ``wall_time`` (s) and ``max_rel_error`` (over all
        data).
    target : float or None
        Error to reach.

    Returns
    -------
    (float, int) or (None, None)
        The cumulative time and the index of that stage, or ``(None, None)`` if no stage
        reaches ``target`` (or ``target`` is None or not finite).
    """
    if target is None or not math.isfinite(float(target)):
        return None, None
    total = 0.0
    for k, s in enumerate(stages):
        get = s.get if isinstance(s, dict) else (lambda name, s=s: getattr(s, name))
        total += float(get("wall_time"))
        err = get("max_rel_error")
        if err is not None and math.isfinite(float(err)) \
                and float(err) <= float(target) * (1.0 + _REACH_RTOL):
            return total, k
    return None, None


def _near_bound(result):
    """Names of the free model parameters at or near their bound (see NEAR_BOUND)."""
    model = result.model
    st = model.structure
    names = st.param_names()
    beta = np.asarray(model.beta, float)
    free = np.ones(beta.size, bool)
    if not st.delay:
        free[0] = False
    out = [names[i] for i in np.flatnonzero(free & (beta <= NEAR_BOUND))]
    dmax = result.delay_max
    if st.delay and dmax and beta[0] >= (1.0 - NEAR_BOUND) * dmax:
        out.append("delay (upper bound)" if beta[0] <= dmax else "delay (above delay_max)")
    return out


_RECORD_KEYS = ("max_rel_error", "rms_rel_error", "nit", "nfev", "wall_time", "stage_time",
                "n_near_bound", "n_active_final", "delay", "delay_max", "n_failed_stages",
                "n_max_iter_stages", "success")


def _ratio(a, b):
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b <= 0:
        return None
    return a / b


def _run_variant(data, spec, variant):
    """Fit one variant; a dict record (status "ok" or "failed") and the FitResult or None."""
    opts = variant.fit_options()
    rec = {"key": variant.key, "group": variant.group, "label": variant.label,
           "options": dict(variant.options), "note": variant.note}
    t0 = time.perf_counter()
    try:
        solver, loop = options_from_keywords(**opts)
        result = fit(data, n_sections=spec["n_sections"], integrator=spec["integrator"],
                     delay=spec["delay"], basis=spec["basis"], method=solver, loop=loop)
    except Exception as exc:           # noqa: BLE001 - reported as a failed variant
        rec.update(dict.fromkeys(_RECORD_KEYS), status="failed",
                   message=" ".join(f"{type(exc).__name__}: {exc}".split()),
                   wall_time=time.perf_counter() - t0, near_bound=[], failed_stages=[],
                   stages=[])
        return rec, None
    stages = [s.as_dict() for s in result.stages]
    total = 0.0
    for s in stages:
        total += s["wall_time"]
        s["cumulative_time"] = total
    bad = [r.stage for r in result.stages if int(r.status) < 0]
    limit = [r.stage for r in result.stages if r.status.name == "MAX_ITER"]
    near = _near_bound(result)
    finite = math.isfinite(result.max_rel_error) and math.isfinite(result.rms_rel_error)
    rec.update(
        status="ok" if finite else "failed",
        message=(result.stages[-1].solver_status if finite
                 else "non-finite relative error"),
        max_rel_error=float(result.max_rel_error),
        rms_rel_error=float(result.rms_rel_error),
        nit=int(sum(r.nit for r in result.stages)),
        nfev=int(sum(r.nfev for r in result.stages)),
        wall_time=float(result.wall_time),
        stage_time=float(total),
        n_near_bound=len(near),
        near_bound=near,
        n_active_final=int(result.stages[-1].n_active),
        delay=float(result.model.delay),
        delay_max=float(result.delay_max),
        n_failed_stages=len(bad),
        failed_stages=bad,
        n_max_iter_stages=len(limit),
        success=bool(result.success),
        stages=stages,
    )
    return rec, (result if finite else None)


def _data_of(spec, quick):
    data = spec["data"]
    data = data() if callable(data) else data
    n_sections = int(spec["n_sections"])
    if quick:
        data = data.window(min(QUICK["n_points"], data.n_points))
        n_sections = min(QUICK["n_sections"], n_sections)
    return data, dict(spec, n_sections=n_sections)


def _progress_writer(progress):
    if callable(progress):
        return progress
    if not progress:
        return lambda line: None

    def write(line):
        sys.stderr.write(line + "\n")
        sys.stderr.flush()

    return write


def run_ablation(examples, *, quick=False, progress=False):
    """Run the study on each example; return the numbers and the fits.

    Parameters
    ----------
    examples : mapping name -> dict
        Each value has ``data`` (a :class:`~freqid_casadi.data.FrequencyData` or a function
        returning one), ``n_sections``, ``integrator``, ``delay``, ``basis`` and optionally
        ``thesis`` (published numbers, a dict with ``max_rel_error``), like the CLI's
        ``EXAMPLES``.
    quick : bool
        Reduced problems (:data:`QUICK`) and variants (:func:`variants`).
    progress : bool or callable
        True writes one line per variant to stderr; a callable receives each line (str).

    Returns
    -------
    (dict, dict)
        The JSON-safe summary (``cases`` per example with ``variants`` records,
        ``comparison`` and ``ablation`` ratios, and ``conclusions``) and the FitResult of
        every successful variant, ``{example: {variant key: FitResult}}``.
    """
    if not examples:
        raise OptionError("examples is empty; give at least one example")
    say = _progress_writer(progress)
    t_start = time.perf_counter()
    plan = []
    for name, spec in examples.items():
        data, spec = _data_of(spec, quick)
        plan.append((name, data, spec, variants(delay=bool(spec["delay"]), quick=quick)))
    n_total = sum(len(p[3]) for p in plan)
    cases, fits = {}, {}
    done = 0
    for name, data, spec, vars_ in plan:
        say(f"example {name}: {data.name}, {data.n_points} points, {spec['n_sections']} "
            f"{spec['basis']} sections, {len(vars_)} variants")
        records, fits[name] = [], {}
        for v in vars_:
            done += 1
            rec, res = _run_variant(data, spec, v)
            records.append(rec)
            if res is not None:
                fits[name][v.key] = res
            if rec["status"] == "ok":
                say(f"[{done:2d}/{n_total}] {name} {v.label}: max rel. error "
                    f"{rec['max_rel_error']:.3e}, {rec['nit']} it, {rec['wall_time']:.1f} s")
            else:
                say(f"[{done:2d}/{n_total}] {name} {v.label}: FAILED ({rec['message']}), "
                    f"{rec['wall_time']:.1f} s")
        cases[name] = _case_summary(name, data, spec, records)
    summary = {
        "format": ABLATION_FORMAT,
        "version": ABLATION_VERSION,
        "quick": bool(quick),
        "examples": list(cases),
        "settings": {"default": dict(DEFAULT_OPTIONS), "lm_options": _lm_options(quick),
                     "near_bound": NEAR_BOUND, "quick": dict(QUICK) if quick else None,
                     "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                                 "platform": platform.platform()}},
        "cases": cases,
        "total_wall_time": time.perf_counter() - t_start,
    }
    summary["conclusions"] = conclusions(summary)
    return report._clean(summary), fits


def _case_summary(name, data, spec, records):
    by_key = {r["key"]: r for r in records}
    base = by_key.get("ipopt")
    ok = base is not None and base["status"] == "ok"
    comparison = []
    for r in records:
        if r["group"] != "method" or r["key"] == "ipopt":
            continue
        lm_ok = r["status"] == "ok"
        target = r["max_rel_error"] if lm_ok else None
        t_ipopt, k_ipopt = time_to_reach(base["stages"], target) if ok else (None, None)
        t_lm, k_lm = time_to_reach(r["stages"], target) if lm_ok else (None, None)
        comparison.append({
            "lm": r["key"], "lm_label": r["label"],
            "lm_max_rel_error": target,
            "ipopt_max_rel_error": base["max_rel_error"] if ok else None,
            "error_ratio": _ratio(target, base["max_rel_error"]) if ok else None,
            "lm_wall_time": r["wall_time"] if lm_ok else None,
            "ipopt_wall_time": base["wall_time"] if ok else None,
            "time_ratio": _ratio(base["wall_time"], r["wall_time"]) if ok and lm_ok else None,
            "ipopt_time_to_reach": t_ipopt,
            "ipopt_stage_to_reach": (base["stages"][k_ipopt]["stage"]
                                     if k_ipopt is not None else None),
            "lm_time_to_reach": t_lm,
            "lm_stage_time": r["stage_time"] if lm_ok else None,
            "reach_speedup": _ratio(r["stage_time"], t_ipopt) if lm_ok else None,
        })
    ablation = []
    for r in records:
        if r["group"] == "method":
            continue
        good = ok and r["status"] == "ok"
        ablation.append({
            "key": r["key"], "group": r["group"], "label": r["label"],
            "error_ratio": _ratio(r["max_rel_error"], base["max_rel_error"]) if good else None,
            "time_ratio": _ratio(r["wall_time"], base["wall_time"]) if good else None,
        })
    thesis = spec.get("thesis") or None
    return {
        "name": name,
        "data": {"name": data.name, "n_points": int(data.n_points),
                 "omega_min": float(data.omega[0]), "omega_max": float(data.omega[-1])},
        "structure": {"n_sections": int(spec["n_sections"]), "integrator": bool(spec["integrator"]),
                      "delay": bool(spec["delay"]), "basis": spec["basis"]},
        "thesis": dict(thesis) if thesis else None,
        "variants": records,
        "comparison": comparison,
        "ablation": ablation,
    }


# ----------------------------------------------------------------------------- conclusions


def _g(x, digits=3):
    return "n/a" if x is None else f"{x:.{digits}g}"


def _times(r):
    """A ratio as text: '12.3x', 'n/a'."""
    return "n/a" if r is None else f"{r:.3g}x"


def conclusions(summary):
    """Sentences computed from the numbers of a study (no hand-written claims).

    Parameters
    ----------
    summary : dict
        The summary of :func:`run_ablation` (``cases`` filled in).

    Returns
    -------
    list of str
        Per example: IPOPT's final max error against each barrier-LM variant (ratio) and
        the time IPOPT needed to reach the barrier-LM's final error; the targets (IPOPT at
        least 10x lower on A and C, and faster to the barrier-LM's error); the failed
        variants; per example the ablated factor with the largest effect on the final
        max error; and the factors ranked by their largest effect over all examples.
    """
    out = []
    cases = summary["cases"]
    for name, case in cases.items():
        base = next((r for r in case["variants"] if r["key"] == "ipopt"), None)
        if base is None:
            continue
        if base["status"] != "ok":
            out.append(f"{name}: the IPOPT default FAILED ({base['message']}); no ratios.")
            continue
        for c in case["comparison"]:
            if c["lm_max_rel_error"] is None:
                out.append(f"{name}: {c['lm_label']} FAILED; IPOPT reached "
                           f"{_g(base['max_rel_error'])} in {_g(base['wall_time'])} s.")
                continue
            ratio = c["error_ratio"]
            verdict = ("n/a" if ratio is None else "IPOPT lower" if ratio > 1
                       else "IPOPT not lower")
            reach = (f"IPOPT first reached the barrier-LM's final error after "
                     f"{_g(c['ipopt_time_to_reach'])} s (stage {c['ipopt_stage_to_reach']}), "
                     f"vs {_g(c['lm_stage_time'])} s for the whole barrier-LM run "
                     f"({_g(c['reach_speedup'])}x faster)"
                     if c["ipopt_time_to_reach"] is not None
                     else "IPOPT never reached the barrier-LM's final error")
            out.append(
                f"{name}: IPOPT's final max relative error {_g(base['max_rel_error'])} vs "
                f"{_g(c['lm_max_rel_error'])} for {c['lm_label']} (ratio barrier-LM/IPOPT "
                f"{_g(ratio)}, {verdict}); "
                f"total time {_g(base['wall_time'])} s vs {_g(c['lm_wall_time'])} s; {reach}.")
    out += _target_sentences(cases)
    failed = [(n, r["label"], r["message"]) for n, c in cases.items() for r in c["variants"]
              if r["status"] != "ok"]
    if failed:
        out.append("Failed variants: " + "; ".join(f"{n} {lab} ({msg})"
                                                   for n, lab, msg in failed) + ".")
    else:
        out.append("No variant failed (every fit returned a finite error).")
    out += _factor_sentences(cases)
    return out


def _target_sentences(cases):
    out = []
    for name in ("A", "C"):
        case = cases.get(name)
        if case is None:
            continue
        c = next((c for c in case["comparison"] if c["lm"] == "lm-thesis"), None)
        if c is None:
            continue
        r = c["error_ratio"]
        met_err = r is not None and r >= 10
        t_i, t_l = c["ipopt_time_to_reach"], c["lm_stage_time"]
        met_time = t_i is not None and t_l is not None and t_i < t_l
        out.append(f"Target on {name} (vs the thesis-damping barrier-LM): error at least 10x "
                   f"lower: {'MET' if met_err else 'NOT MET'} ({_g(r)}x); time to reach the "
                   f"barrier-LM's final error lower: {'MET' if met_time else 'NOT MET'} "
                   f"({_g(t_i)} s vs {_g(t_l)} s).")
    return out


def _factor_sentences(cases):
    out = []
    effects = {}                         # group -> list of (|log10 ratio|, example, row)
    for name, case in cases.items():
        rows = [a for a in case["ablation"] if a["error_ratio"] is not None]
        for a in rows:
            effects.setdefault(a["group"], []).append(
                (abs(math.log10(a["error_ratio"])) if a["error_ratio"] > 0 else math.inf,
                 name, a))
        if rows:
            best = max(rows, key=lambda a: abs(math.log10(a["error_ratio"]))
                       if a["error_ratio"] > 0 else math.inf)
            out.append(f"{name}: the ablation that changes the final max error most is "
                       f"{best['label']} ({best['group']}): {_times(best['error_ratio'])} the "
                       f"default's error, at {_times(best['time_ratio'])} its time.")
    if effects:
        ranked = sorted(effects.items(), key=lambda kv: -max(e[0] for e in kv[1]))
        parts = []
        for group, items in ranked:
            eff, name, a = max(items, key=lambda e: e[0])
            parts.append(f"{group} (up to {_times(a['error_ratio'])} on {name}, {a['label']})")
        out.append("Factors ranked by their largest effect on the final max error (ratio to "
                   "the IPOPT default; > 1x is worse): " + "; ".join(parts) + ".")
        slow = [(a["time_ratio"], n, a) for n, c in cases.items() for a in c["ablation"]
                if a["time_ratio"] is not None]
        if slow:
            tr, n, a = max(slow, key=lambda e: abs(math.log(e[0])) if e[0] > 0 else math.inf)
            out.append(f"Largest change of wall time: {a['label']} on {n}, "
                       f"{_times(tr)} the default's time.")
    return out


# ----------------------------------------------------------------------------- Markdown


def _f(x, digits=4):
    """How a number appears in report.md (ablation.json keeps full precision)."""
    if x is None:
        return _DASH
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    x = float(x)
    return f"{x:.{digits}g}" if math.isfinite(x) else _DASH


def _reach(t):
    return "n/a" if t is None else _f(t)


#: Columns of the per-variant tables of report.md: (header, JSON key of the variant record).
VARIANT_COLUMNS = (("max rel. error", "max_rel_error"), ("RMS rel. error", "rms_rel_error"),
                   ("iterations", "nit"), ("function evaluations", "nfev"),
                   ("wall time (s)", "wall_time"), ("params near bound", "n_near_bound"),
                   ("delay (s)", "delay"), ("failed stages", "n_failed_stages"),
                   ("iteration-limit stages", "n_max_iter_stages"))


def _variant_row(r, first):
    cells = list(first)
    cells += [_f(r.get(k)) for _, k in VARIANT_COLUMNS]
    if r["status"] == "ok":
        status = "converged" if r["success"] else f"not converged ({r['message']})"
    else:
        status = f"FAILED: {r['message']}"
    return cells + [status]


def render_ablation(summary):
    """The Markdown text of report.md from the summary of :func:`run_ablation`.

    Every number in the text is taken from ``summary`` (4 significant digits), so
    ablation.json and report.md agree.
    """
    s = summary
    lines = [report.generated_by_line(s["command"]), "",
             "# Ablation: IPOPT with bounds vs the thesis's barrier-LM, and IPOPT's options", ""]
    lm = s["settings"]["lm_options"]
    lines += [
        f"Command: `{s['command']}`. Total run time {_f(s['total_wall_time'])} s on "
        f"{s['settings']['machine']['cpu_count']} CPUs (Python "
        f"{s['settings']['machine']['python']}).", "",
        "Default (every ablation changes one factor from it): IPOPT, "
        + ", ".join(f"{k}={v}" for k, v in s["settings"]["default"].items() if k != "method")
        + ". Barrier-LM caps: "
        + ", ".join(f"{k}={v:g}" for k, v in lm.items())
        + " (k_max trial steps per inner LM solve; 10 barrier problems per stage); the "
          "barrier-LM imposes no upper bound on the delay.", ""]
    if s["quick"]:
        q = s["settings"]["quick"]
        lines += [f"**Quick mode**: each example windowed to its first {q['n_points']} points "
                  f"with {q['n_sections']} sections, and a reduced set of variants; the "
                  "numbers are a smoke test, not the study.", ""]
    lines += ["Errors are relative errors |(G - G_N)/G_N| over all data points; \"time to "
              "reach\" is the cumulative stage wall time at the first stage whose max error "
              "over all data is <= the target (n/a: never). \"params near bound\": model "
              f"parameters <= {NEAR_BOUND:g}, or the delay within a relative {NEAR_BOUND:g} "
              "of its upper bound. \"failed stages\": solver status ERROR or FAILED; "
              "\"stage time\": the sum of the stages' wall times (the clock of time to "
              "reach; the total wall time also counts setup and the final error); "
              "\"iteration-limit stages\": stages stopped by max_iter / k_max.", ""]

    lines += ["## Conclusions (computed from the numbers below)", ""]
    lines += [f"- {c}" for c in s["conclusions"]] + [""]

    lines += ["## Summary: does IPOPT reach a lower max error than the barrier-LM, and how "
              "fast?", ""]
    rows = []
    for name, case in s["cases"].items():
        t = (case.get("thesis") or {}).get("max_rel_error")
        for c in case["comparison"]:
            rows.append((name, c["lm_label"], _f(c["ipopt_max_rel_error"]),
                         _f(c["lm_max_rel_error"]), _f(c["error_ratio"]),
                         _f(c["ipopt_wall_time"]), _f(c["lm_wall_time"]),
                         _reach(c["ipopt_time_to_reach"]),
                         _f(c["lm_stage_time"]), _f(t)))
    lines += [report.markdown_table(rows, (
        "example", "barrier-LM variant", "IPOPT max rel. error", "barrier-LM max rel. error",
        "error ratio LM/IPOPT", "IPOPT time (s)", "barrier-LM time (s)",
        "IPOPT time to reach LM error (s)", "barrier-LM stage time (s)",
        "thesis max rel. error (published)"), "llrrrrrrrr"), ""]

    for name, case in s["cases"].items():
        d, st = case["data"], case["structure"]
        lines += [f"## Example {name}: {d['name']}", "",
                  f"{d['n_points']} points from {_f(d['omega_min'])} to {_f(d['omega_max'])} "
                  f"rad/s; {st['n_sections']} {st['basis']} sections, "
                  f"{'with' if st['integrator'] else 'no'} integrator, "
                  f"{'with' if st['delay'] else 'no'} delay.", ""]
        headers = ["variant"] + [h for h, _ in VARIANT_COLUMNS] + ["status"]
        align = "l" + "r" * len(VARIANT_COLUMNS) + "l"
        method = [r for r in case["variants"] if r["group"] == "method"]
        lines += ["### IPOPT vs barrier-LM", "",
                  report.markdown_table([_variant_row(r, (r["label"],)) for r in method],
                                        headers, align), ""]
        crows = [(c["lm_label"], _f(c["lm_max_rel_error"]), _reach(c["ipopt_time_to_reach"]),
                  _f(c["ipopt_stage_to_reach"]), _reach(c["lm_time_to_reach"]),
                  _f(c["lm_stage_time"]), _f(c["reach_speedup"]))
                 for c in case["comparison"]]
        if crows:
            lines += ["Time to reach the barrier-LM's final max error:", "",
                      report.markdown_table(crows, (
                          "target (barrier-LM variant)", "target max rel. error",
                          "IPOPT time to reach (s)", "IPOPT stage", "barrier-LM time to reach (s)",
                          "barrier-LM stage time (s)", "speed-up"), "lrrrrrr"), ""]
        lines += [f"![max error after each stage, {name}](stages_{name}.png)", "",
                  f"![max error against time, {name}](time_{name}.png)", "",
                  f"![relative error, {name}](rel_error_{name}.png)", ""]
        abl = [r for r in case["variants"] if r["group"] != "method"]
        if abl:
            ratios = {a["key"]: a for a in case["ablation"]}
            base = next((r for r in case["variants"] if r["key"] == "ipopt"), None)
            rows = []
            if base is not None:
                rows.append(_variant_row(base, ("default", base["label"], _f(1.0), _f(1.0))))
            for r in abl:
                a = ratios[r["key"]]
                rows.append(_variant_row(r, (r["group"], r["label"], _f(a["error_ratio"]),
                                             _f(a["time_ratio"]))))
            lines += ["### IPOPT ablations (one factor at a time from the default)", "",
                      report.markdown_table(rows, ["factor", "variant", "error ratio",
                                                   "time ratio"] + headers[1:],
                                            "llrr" + align[1:]), "",
                      "error ratio / time ratio: the variant's final max error / wall time "
                      "divided by the default's (> 1: worse / slower).", ""]
            notes = [f"- {r['label']}: {r['note']}" for r in abl if r.get("note")]
            lines += notes + ([""] if notes else [])
            lines += [f"![ablations, {name}](ablation_{name}.png)", ""]
    lines += ["## Files", "",
              "`ablation.json`: every number above at full precision, with the per-stage "
              "records of every variant (`cases.<example>.variants[].stages`).", ""]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- figures


def _figures(summary, fits, folder):
    from . import plots

    written = []
    for name, case in summary["cases"].items():
        res = fits.get(name, {})
        labels = {r["key"]: r["label"] for r in case["variants"]}
        method = {labels[k]: res[k] for k in ("ipopt", "lm-thesis", "lm-marquardt")
                  if k in res}
        title = f"{name}: {case['data']['name']}"
        path = os.path.join(folder, f"stages_{name}.png")
        if method:
            plots.save_figure(plots.stage_errors(method, title=f"{title}: max error after "
                                                               "each stage"), path)
            plots.save_figure(plots.relative_error(
                method, title=f"{title}: relative error of the final models",
                reference=(case.get("thesis") or {}).get("max_rel_error"),
                reference_label="thesis (published max)"),
                os.path.join(folder, f"rel_error_{name}.png"))
        else:
            _empty_figure(plots, f"{title}: every method variant failed", path)
            _empty_figure(plots, f"{title}: every method variant failed",
                          os.path.join(folder, f"rel_error_{name}.png"))
        plots.save_figure(_time_figure(plots, case, title),
                          os.path.join(folder, f"time_{name}.png"))
        plots.save_figure(_ablation_figure(plots, case, title),
                          os.path.join(folder, f"ablation_{name}.png"))
        written += [f"{k}_{name}.png" for k in _FIGURES]
    return written


def _empty_figure(plots, text, path):
    fig, ax = plots._new_figure()
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()
    plots.save_figure(fig, path)


def _time_figure(plots, case, title):
    """Max error over all data against cumulative stage wall time, method variants."""
    fig, ax = plots._new_figure()
    method = [r for r in case["variants"] if r["group"] == "method" and r["status"] == "ok"]
    for k, r in enumerate(method):
        t = [s["cumulative_time"] for s in r["stages"]]
        e = [s["max_rel_error"] for s in r["stages"]]
        ax.loglog(t, e, "-o", color=f"C{k}", ms=3.5, lw=1.1, label=r["label"])
        if r["key"] != "ipopt":
            ax.axhline(r["max_rel_error"], color=f"C{k}", ls=":", lw=0.9)
    for c in case["comparison"]:
        if c["ipopt_time_to_reach"] is not None:
            ax.plot([c["ipopt_time_to_reach"]], [c["lm_max_rel_error"]], "k*", ms=9)
    ax.plot([], [], "k*", ms=9, label="IPOPT reaches the barrier-LM's final error")
    ax.set_xlabel("cumulative wall time of the stages (s)")
    ax.set_ylabel("max relative error over all data")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    ax.set_title(f"{title}: error against time")
    return fig


def _ablation_figure(plots, case, title):
    """Final max error and wall time of every variant (horizontal bars, log scales)."""
    rows = case["variants"]
    n = len(rows)
    fig, (ax_e, ax_t) = plots._new_figure(1, 2, figsize=(10.0, 0.35 * n + 1.8), sharey=True)
    y = np.arange(n)[::-1]
    groups = list(dict.fromkeys(r["group"] for r in rows))
    for yi, r in zip(y, rows):
        color = f"C{groups.index(r['group'])}"
        if r["status"] == "ok":
            ax_e.barh(yi, r["max_rel_error"], color=color, alpha=0.85)
            ax_e.annotate(f"{r['max_rel_error']:.3g}", (r["max_rel_error"], yi),
                          xytext=(3, 0), textcoords="offset points", va="center",
                          fontsize="x-small")
            ax_t.barh(yi, r["wall_time"], color=color, alpha=0.85)
            ax_t.annotate(f"{r['wall_time']:.3g} s", (r["wall_time"], yi), xytext=(3, 0),
                          textcoords="offset points", va="center", fontsize="x-small")
        else:
            ax_e.annotate("FAILED", (0.02, yi), xycoords=("axes fraction", "data"),
                          va="center", color="C3", fontsize="small")
    base = next((r for r in rows if r["key"] == "ipopt" and r["status"] == "ok"), None)
    if base is not None:
        ax_e.axvline(base["max_rel_error"], color="k", ls="--", lw=0.8)
        ax_t.axvline(base["wall_time"], color="k", ls="--", lw=0.8)
    from matplotlib import ticker

    for ax in (ax_e, ax_t):
        ax.set_xscale("log")
    ax_t.xaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax_t.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
    ax_t.xaxis.set_minor_formatter(ticker.NullFormatter())
    ax_e.set_yticks(y, [r["label"] for r in rows], fontsize="small")
    ax_e.set_xlabel("final max relative error (dashed: IPOPT default)")
    ax_t.set_xlabel("wall time (s)")
    for ax in (ax_e, ax_t):
        plots._finish_axes(ax)
        ax.margins(x=0.25)
    fig.suptitle(f"{title}: every variant")
    return fig


# ----------------------------------------------------------------------------- writer


def write_ablation_report(examples, out_dir, *, command, quick=False, force=False,
                          progress=False):
    """Run the study and write its report folder (see the module docstring).

    Parameters
    ----------
    examples : mapping name -> dict
        As in :func:`run_ablation`.
    out_dir : str or os.PathLike
        Folder to create; its parent must exist.
    command : str
        The command that made the report (first line of report.md).
    quick : bool
        Reduced problems and variants (:data:`QUICK`).
    force : bool
        Replace an existing ``out_dir`` (only after the new report is complete).
    progress : bool or callable
        As in :func:`run_ablation`.

    Returns
    -------
    (str, dict)
        The absolute path of the folder and the summary (the content of ablation.json).

    Raises
    ------
    OptionError
        If ``out_dir`` exists and ``force`` is false (checked before the study and again
        before the rename), or its parent does not exist, or ``examples`` is empty.
    """
    path = report.check_out_dir(out_dir, force)
    summary, fits = run_ablation(examples, quick=quick, progress=progress)
    summary = dict(command=" ".join(str(command).split()), **summary)
    with report.report_folder(out_dir, force) as (tmp, _):
        figures = _figures(summary, fits, tmp)
        summary["files"] = list(ABLATION_FILES) + figures
        atomic_write_text(os.path.join(tmp, "ablation.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), render_ablation(summary))
    return path, summary
