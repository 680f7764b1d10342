"""Ablation study, the experiments: IPOPT vs the thesis's barrier-LM, and IPOPT's options
one at a time.

For each example of the catalogue (:data:`freqid_casadi.systems.examples.EXAMPLES`) the study fits

* the **method comparison** (SPEC §3): IPOPT with true bounds (the package default) against
  the thesis's log-barrier + Levenberg-Marquardt with the faithful ``"thesis"`` damping
  ``sigma*I`` and with ``"marquardt"`` damping ``sigma*diag(A)``, all on the same data and the
  same main loop;
* the **IPOPT ablations**, one factor at a time from the default
  (:data:`DEFAULT_OPTIONS`): gauge, warm start, new-section initialisation, Hessian,
  variable scaling and the delay's upper bound (:func:`variants`).

:func:`run_ablation` returns an :class:`AblationResult`: every number (``as_dict()``, the
content of ablation.json) and the fits. A variant that raises or returns a non-finite error
is kept as ``status="failed"`` with its message, never dropped. The report (Markdown,
figures, conclusions) is :mod:`freqid_casadi.studies.ablation_report`.

"Time to reach" an error ``e`` (:func:`time_to_reach`): the cumulative stage wall time at the
first stage whose max relative error over all data is ``<= e``; ``None`` (n/a) if no stage
reaches it.
"""

import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..errors import OptionError
from ..fitting.fit import fit
from ..report.environment import environment
from ..report.formatting import json_safe
from ..options import BarrierLMOptions, IpoptOptions, LoopOptions

__all__ = ["Variant", "AblationResult", "variants", "run_ablation", "time_to_reach",
           "DEFAULT_OPTIONS", "DEFAULT_IPOPT", "DEFAULT_LOOP", "DEFAULT_LM", "LM_OPTIONS",
           "QUICK", "NEAR_BOUND", "ABLATION_FORMAT", "ABLATION_VERSION"]

ABLATION_FORMAT = "freqid_casadi.ablation_report"
ABLATION_VERSION = 1

#: Options of the barrier-LM stage solver besides the damping (the caps of the run):
#: ``max_inner`` = k_max, trial steps per inner LM solve (the solver's default is 500; 50
#: keeps the 27-section example C at a few minutes per variant on 2 cores); the outer loop
#: runs t = 1, 20, 400, ... <= 1e12 (10 barrier problems per stage, thesis code).
LM_OPTIONS = dict(max_inner=50, t0=1.0, t_factor=20.0, t_max=1e12)

#: The stage-solver options every variant starts from: the defaults of the option objects
#: (:class:`~freqid_casadi.options.IpoptOptions`, :class:`~freqid_casadi.options.LoopOptions`)
#: except ``final_max_iter=500`` (fit: 200), an explicit choice. The final all-data stage
#: runs into its iteration cap in nearly every variant (results/ablation/ablation.json: every
#: IPOPT variant of A, C and the fractional example stops at Maximum_Iterations_Exceeded), so
#: the final errors compare how far each variant gets within a fixed budget; 2.5x fit's
#: budget lets the ablated option, more than the cap, set the ranking, and keeps the
#: published numbers of results/ablation unchanged. The barrier-LM variants share the same
#: stage limits (as they did when fit took flat keywords).
DEFAULT_IPOPT = replace(IpoptOptions(), final_max_iter=500)
DEFAULT_LOOP = LoopOptions()
DEFAULT_LM = replace(BarrierLMOptions(), warm_start=DEFAULT_IPOPT.warm_start,
                     max_iter=DEFAULT_IPOPT.max_iter,
                     final_max_iter=DEFAULT_IPOPT.final_max_iter, **LM_OPTIONS)

#: The default as the report states it (one flat dict, ``settings.default`` of ablation.json).
DEFAULT_OPTIONS = dict(method="ipopt", gauge=DEFAULT_LOOP.gauge, init=DEFAULT_LOOP.init,
                       scale_l=DEFAULT_LOOP.scale_l, hessian=DEFAULT_IPOPT.hessian,
                       warm_start=DEFAULT_IPOPT.warm_start, scaled=DEFAULT_LOOP.scaled,
                       bound_delay=DEFAULT_LOOP.bound_delay, max_iter=DEFAULT_IPOPT.max_iter,
                       final_max_iter=DEFAULT_IPOPT.final_max_iter)

#: The reduced problem of ``quick=True``: each example windowed to its first ``n_points``
#: points, with ``n_sections`` sections (at most its own number), and the barrier-LM's
#: ``max_inner`` lowered to ``lm_max_inner``.
QUICK = dict(n_points=300, n_sections=3, examples=("A", "fractional"), lm_max_inner=100)

#: A model parameter counts as "at or near its bound" when ``beta_i <= NEAR_BOUND`` (in the
#: model's units: s, rad/s or dimensionless), or the delay is within a relative NEAR_BOUND of
#: its upper bound ``delay_max``.
NEAR_BOUND = 1e-6

#: Relative slack of "reached": the stage records and the final result compute the same
#: error along different code paths (rounding differences ~1e-15).
_REACH_RTOL = 1e-9


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
        What differs from the default: fields of LoopOptions or IpoptOptions by name, or
        ``method="barrier-lm"`` with ``lm_options`` (fields of BarrierLMOptions).
    note : str
        Remark printed under the table (empty if none).
    """

    key: str
    group: str
    label: str
    options: dict = field(default_factory=dict)
    note: str = ""

    def fit_options(self):
        """``{"method": solver options, "loop": LoopOptions}`` for
        :func:`~freqid_casadi.fitting.fit.fit`:
        :data:`DEFAULT_IPOPT` (or :data:`DEFAULT_LM`) and :data:`DEFAULT_LOOP` with this
        variant's changes (``dataclasses.replace``)."""
        changes = dict(self.options)
        loop = replace(DEFAULT_LOOP, **{k: changes.pop(k) for k in list(changes)
                                        if k in _LOOP_FIELDS})
        if changes.pop("method", "ipopt") == "barrier-lm":
            return {"method": replace(DEFAULT_LM, **changes.pop("lm_options", {}), **changes),
                    "loop": loop}
        return {"method": replace(DEFAULT_IPOPT, **changes), "loop": loop}


_LOOP_FIELDS = {f.name for f in fields(LoopOptions)}


@dataclass(frozen=True, eq=False)
class AblationResult:
    """What :func:`run_ablation` measured.

    Attributes
    ----------
    quick : bool
        Whether the reduced problems of :data:`QUICK` were run.
    settings : dict
        The default options, the barrier-LM caps, :data:`NEAR_BOUND`, the quick sizes and
        the machine (CPU count, Python, platform).
    cases : dict
        Per example (in order): ``name``, ``data`` (name, points, range in rad/s),
        ``structure``, ``thesis`` (published numbers or None), ``variants`` (one record per
        variant: errors, iterations, times in s, per-stage records, status), ``comparison``
        (IPOPT vs each barrier-LM variant) and ``ablation`` (error and time ratios to the
        default).
    fits : dict
        ``{example: {variant key: FitResult}}`` of the successful variants.
    total_wall_time : float
        Wall time of the whole study (s).
    """

    quick: bool
    settings: dict
    cases: dict
    fits: dict
    total_wall_time: float

    def as_dict(self):
        """The JSON-safe numbers (the content of ablation.json without the command, the
        conclusions and the file list, which the report adds)."""
        return json_safe({"format": ABLATION_FORMAT, "version": ABLATION_VERSION,
                          "quick": self.quick, "examples": list(self.cases),
                          "settings": self.settings, "cases": self.cases,
                          "total_wall_time": self.total_wall_time})


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
                     "init=relocate it has no effect, so this row isolates the gauge."),
        Variant("warm-none", "warm start", "warm start none", {"warm_start": "none"}),
        Variant("warm-primal", "warm start", "warm start primal", {"warm_start": "primal"}),
        Variant("init-peak", "init", "init peak (no relocation)", {"init": "peak"}),
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
    rec = {"key": variant.key, "group": variant.group, "label": variant.label,
           "options": dict(variant.options), "note": variant.note}
    t0 = time.perf_counter()
    try:
        result = fit(data, n_sections=spec["n_sections"], integrator=spec["integrator"],
                     delay=spec["delay"], basis=spec["basis"],
                     **{"start": "sequential", **variant.fit_options()})
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
        fit_status=str(result.status),
        message=(result.message if finite else "the relative error is not finite; see the "
                 "stage records (stages) for the first stage that failed"),
        solver_status=result.stages[-1].solver_status,
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


def _data_of(example, quick):
    """The data and the model structure of one example (windowed and smaller with quick)."""
    data = example.data()
    n_sections = int(example.n_sections)
    if quick:
        data = data.window(min(QUICK["n_points"], data.n_points))
        n_sections = min(QUICK["n_sections"], n_sections)
    thesis = example.thesis.as_dict() if example.thesis is not None else None
    return data, dict(example.structure(n_sections), thesis=thesis)


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
    examples : mapping name -> Example
        Entries of the catalogue (:data:`freqid_casadi.systems.examples.EXAMPLES`) or
        ``dataclasses.replace`` of them: the data (``example.data()``), the structure and
        the thesis's numbers.
    quick : bool
        Reduced problems (:data:`QUICK`) and variants (:func:`variants`).
    progress : bool or callable
        True writes one line per variant to stderr; a callable receives each line (str).

    Returns
    -------
    AblationResult
        Per example the ``variants`` records, the ``comparison`` and ``ablation`` ratios,
        and the FitResult of every successful variant.
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
    settings = {"default": dict(DEFAULT_OPTIONS), "lm_options": _lm_options(quick),
                "near_bound": NEAR_BOUND, "quick": dict(QUICK) if quick else None,
                "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                            "platform": platform.platform()},
                "environment": environment()}
    return AblationResult(bool(quick), settings, cases, fits, time.perf_counter() - t_start)


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
