"""What a fit report states: the summary dict (summary.json) and its Markdown (layer L6).

:func:`fit_summary` collects every number of a fit report as a JSON-safe dict;
:func:`render_fit_summary` writes summary.md from it, so the two always agree. The folder
itself is written by :func:`freqid_casadi.report.folder.write_fit_report`, which re-exports these
names.
"""

import math

import numpy as np

from . import outputs as _outputs
from .._textio import md_text
from ..core.data import TIME_UNITS, dense_grid
from ..errors import FreqidError, OptionError
from .environment import environment, environment_line
from .formatting import generated_by_line, json_safe, markdown_table, number
from ..core.metrics import relative_error
from ..fitting.verdict import ROUNDING_RMS

__all__ = ["fit_summary", "render_fit_summary", "dense_error", "REPORT_FILES",
           "REPORT_FORMAT", "REPORT_VERSION"]

REPORT_FORMAT = "freqid_casadi.fit_report"
REPORT_VERSION = 1

#: Files of a fit report folder, in the order they are written.
REPORT_FILES = (_outputs.MARKER, "model.json", "rel_error.csv", "stages.csv", "bode.png",
                "rel_error.png", "pole_zero.png", "stages.png", "summary.json", "summary.md")



def fit_summary(result, *, command, title=None, thesis=None, truth=None, dense_factor=10,
                data_notes=()):
    """Everything a fit report states, as a JSON-safe dict (the content of summary.json).

    Parameters
    ----------
    result : FitResult
    command : str
        The command line that made the report.
    title : str, optional
        Report title (default ``"Fit report: <data name>"``).
    thesis : dict, optional
        Published numbers to compare with, keys among ``order`` (order of P_N),
        ``max_rel_error``, ``rms_rel_error``, ``delay`` (s) and ``source`` (str).
    truth : callable, optional
        ``truth(omega) -> complex ndarray``: the true system (analytic benchmarks). The
        report then also gives the relative error on a log grid ``dense_factor`` times
        denser than the data (the honest error between the samples).
    dense_factor : int
    data_notes : sequence of str
        How the data file was read (the reader's notes: a skipped preamble, the units
        taken, the columns chosen by convention), recorded under ``data.read_notes`` and
        as the section "How the data were read" of summary.md.

    Returns
    -------
    dict
    """
    model, data = result.model, result.data
    st = model.structure
    per = 2 if st.basis == "second-order" else 1
    rel = np.asarray(result.rel_error, float)
    i_max = int(np.argmax(rel))
    poles_all = model.poles()
    k = st.origin_order
    poles = poles_all[max(k, 0):]
    zeros = model.zeros()[max(-k, 0):]
    name = data.name or "data"
    summary = {
        "format": REPORT_FORMAT,
        "version": REPORT_VERSION,
        "command": " ".join(str(command).split()),
        "title": title if title is not None else f"Fit report: {name}",
        "data": {"name": name, "n_points": int(data.n_points),
                 "omega_min": float(data.omega[0]), "omega_max": float(data.omega[-1]),
                 "unit": data.unit,
                 **({"f_min_hz": float(data.omega[0] / (2 * np.pi)),
                     "f_max_hz": float(data.omega[-1] / (2 * np.pi))}
                    if data.unit == "rad/s" else {}),
                 **({"read_notes": [str(t) for t in data_notes]} if data_notes else {})},
        "structure": {"n_sections": st.n_sections, "basis": st.basis,
                      "integrator": st.integrator, "delay": st.delay,
                      "order_rational_part": per * st.n_sections, "order": st.order,
                      # k of integrator=k (|k| >= 2 only: the reports of 0 and 1 unchanged)
                      **({"origin_order": k} if k not in (0, 1) else {})},
        "method": result.method,
        "max_rel_error": float(result.max_rel_error),
        "rms_rel_error": float(result.rms_rel_error),
        "omega_at_max_rel_error": float(data.omega[i_max]),
        "delay": float(model.delay),
        "gain": float(model.gain),
        "wall_time": float(result.wall_time),
        "environment": environment(),
        "status": str(getattr(getattr(result, "status", None), "value", "") or ""),
        "success": bool(result.success),
        "message": str(getattr(result, "message", "") or ""),
        "details": dict(getattr(result, "details", None) or {}),
        "nit": int(sum(s.nit for s in result.stages)),
        "checks": {
            "stable": model.is_stable(),
            "minimum_phase": model.is_minimum_phase(),
            "n_poles_on_axis": int(model.poles_on_axis().size),
            "n_zeros_on_axis": int(np.count_nonzero(zeros.real == 0)),
            "n_poles": int(poles.size),
            "n_zeros": int(zeros.size),
            "max_pole_real_part": float(np.max(poles.real)) if poles.size else None,
            "max_zero_real_part": float(np.max(zeros.real)) if zeros.size else None,
            "min_pole_damping": _min_damping(poles),
            "min_zero_damping": _min_damping(zeros),
        },
        "stages": [_stage_dict(s) for s in result.stages],
        "thesis": _thesis_dict(thesis),
        "options": json_safe(result.options_dict() if hasattr(result, "options_dict")
                             else dict(getattr(result, "options", {}) or {})),
        "resolution": _resolution_dict(getattr(result, "resolution", None)),
        "dense": dense_error(model, data.omega, truth, dense_factor),
        "diagnostics": [d.as_dict() for d in getattr(result, "diagnostics", ())],
        "uncertainty": _uncertainty_dict(result),
        "files": list(REPORT_FILES),
    }
    return json_safe(summary)


def _uncertainty_dict(result):
    """Delay, gain and modes with their standard deviations (FitResult.uncertainty), or
    None with the reason when the covariance cannot be formed."""
    try:
        u = result.uncertainty
    except (FreqidError, np.linalg.LinAlgError, ArithmeticError, AttributeError) as exc:
        return {"error": str(exc)}
    nd = u.not_determined
    with np.errstate(all="ignore"):
        model_gain = float(result.model.low_frequency_gain())
    return {"noise_source": u.noise_source, "delay": u.delay, "delay_std": u.delay_std,
            "gain": u.gain, "gain_std": u.gain_std,
            "model_gain": model_gain if math.isfinite(model_gain) else None,
            "delay_reason": nd.get("delay", "") if "delay" in u.param_names else "",
            "gain_reason": nd.get("log_gain", ""), "not_determined": nd,
            "modes": [{"omega_n": m.omega_n, "omega_n_std": m.omega_n_std,
                       "frequency_hz": m.frequency_hz, "zeta": m.zeta, "zeta_std": m.zeta_std,
                       "zeta_at_bound": m.zeta_at_bound,
                       "omega_n_determined": m.omega_n_determined,
                       "zeta_determined": m.zeta_determined, "reason": m.reason}
                      for m in u.modes]}


def dense_error(model, omega, truth, factor=10):
    """Relative error against the true system on a log grid denser than the data.

    Parameters
    ----------
    model : RationalDelayModel
        The fitted model.
    omega : array_like of float, shape (M,)
        The data's frequencies (rad/s).
    truth : callable or None
        ``truth(omega) -> complex ndarray``, the true system's response.
    factor : int
        The grid has ``factor * M`` log-spaced points over the data's range.

    Returns
    -------
    dict or None
        ``factor``, ``n_points``, ``max_rel_error``, ``omega_at_max_rel_error`` (rad/s),
        ``rms_rel_error``; None without ``truth``.
    """
    if truth is None:
        return None
    grid = dense_grid(omega, factor)
    err = relative_error(model, grid, np.asarray(truth(grid)))
    return {"factor": int(factor), "n_points": int(grid.size),
            "max_rel_error": err.max, "omega_at_max_rel_error": err.omega_at_max,
            "rms_rel_error": err.rms}


def _resolution_dict(check):
    if check is None:
        return None
    return {"ok": bool(check.ok), "n_flagged_pairs": len(check.flags),
            "n_unresolved": len(check.unresolved)}


def _min_damping(roots):
    """Smallest damping ratio -Re(r)/|r| of nonzero roots (1 for a real root in the LHP)."""
    roots = roots[np.abs(roots) > 0]
    return float(np.min(-roots.real / np.abs(roots))) if roots.size else None


def _stage_dict(rec):
    d = rec.as_dict() if hasattr(rec, "as_dict") else dict(rec.__dict__)
    return json_safe(d)


_THESIS_KEYS = ("order", "max_rel_error", "rms_rel_error", "delay")


def _thesis_dict(thesis):
    if thesis is None:
        return None
    unknown = set(thesis) - set(_THESIS_KEYS) - {"source"}
    if unknown:
        raise OptionError(f"thesis: unknown key(s) {sorted(unknown)}; use "
                          f"{', '.join(_THESIS_KEYS)} and 'source'")
    out = {k: thesis.get(k) for k in _THESIS_KEYS}
    if "source" in thesis:
        out["source"] = str(thesis["source"])
    return out


def render_fit_summary(summary):
    """The Markdown text of a fit report (summary.md).

    Parameters
    ----------
    summary : dict
        The :func:`fit_summary` dict.

    Returns
    -------
    str
        Every number in the text comes from ``summary`` (floats rounded to 4 significant
        digits, the delay and gain to 6), so summary.json and summary.md always agree.
    """
    s = summary
    lines = [generated_by_line(s["command"]), "", f"# {md_text(s['title'])}", ""]
    lines += _status_lines(s)
    lines += [markdown_table(_overview_rows(s), ("quantity", "value")), ""]
    lines += _read_lines(s)
    lines += _diagnostic_lines(s)
    lines += _uncertainty_lines(s)
    lines += _thesis_lines(s)
    lines += _stage_lines(s["stages"], _units(s)[0])
    lines += ["## Figures", "",
              "![Bode plot](bode.png)", "",
              "![Relative error](rel_error.png)", "",
              "![Poles and zeros](pole_zero.png)", "",
              "![Error after each stage](stages.png)", "",
              "## Files", "",
              "`model.json` (the model; `RationalDelayModel.load`), `rel_error.csv`, "
              "`stages.csv`, `summary.json` (every number above, full precision).", ""]
    return "\n".join(lines)


def _read_lines(s):
    """The reader's notes on the data file (its preamble, units, columns), if any."""
    notes = s["data"].get("read_notes") or ()
    if not notes:
        return []
    return (["## How the data were read", ""] + [f"- {md_text(t)}" for t in notes] + [""])


def _status_lines(s):
    """The report's lead: the status and the message (what to do next)."""
    if not s.get("status"):                 # (summaries written before the status)
        return []
    return [f"**Status: {s['status']}.** {md_text(s.get('message') or '')}", ""]


def _units(s):
    """(frequency unit, delay unit) of a summary: ("rad/s", "s") unless normalised."""
    unit = s["data"].get("unit", "rad/s")           # (summaries written before the unit)
    return unit, TIME_UNITS[unit]


def _roots_check(ok, real_part, damping, what, unit="rad/s", on_axis=0):
    """'yes'/'NO' with the largest real part and smallest damping of the poles or zeros;
    'only marginally' when ``on_axis`` of them lie on the imaginary axis (undamped)."""
    word = "NO" if not ok else "only marginally" if on_axis else "yes"
    return word + (
        f" (largest real part of a {what}: {number(real_part)} {unit}, "
        f"smallest damping ratio {number(damping)})" if real_part is not None else "") + (
        f", {on_axis} {what}(s) on the imaginary axis (undamped, zeta = 0, held at the "
        "bound of the fit's damping)" if on_axis else "")


def _origin_words(st):
    """"with integrator", "no integrator", "2 poles at the origin", "1 zero at the origin"
    for a summary's structure dict (``origin_order`` absent in older summaries)."""
    k = st.get("origin_order", int(st["integrator"]))
    if k in (0, 1):
        return f"{'with' if k else 'no'} integrator"
    n, what = abs(k), "poles" if k > 0 else "zeros"
    return f"{n} {what[:-1] if n == 1 else what} at the origin"


def _overview_rows(s):
    """(quantity, value) rows of the first table of summary.md."""
    d, st, ck = s["data"], s["structure"], s["checks"]
    fu, tu = _units(s)
    structure = (f"{st['n_sections']} {st['basis']} sections, "
                 f"{_origin_words(st)}, "
                 f"{'with' if st['delay'] else 'no'} delay; order of P_N "
                 f"{st['order_rational_part']}, model order {st['order']}")
    rows = [
        ("command", f"`{s['command']}`"),
        ("data", f"{d['name']}: {d['n_points']} points, {number(d['omega_min'])} to "
                 f"{number(d['omega_max'])} {fu}" + (
                     f" ({number(d['f_min_hz'])} to {number(d['f_max_hz'])} Hz)"
                     if "f_min_hz" in d else "")),
        ("structure", structure),
        ("method", s["method"]),
        ("max relative error", f"{number(s['max_rel_error'])} at "
                               f"{number(s['omega_at_max_rel_error'])} {fu}"),
        ("RMS relative error", number(s["rms_rel_error"])),
    ]
    dn = s.get("dense")
    if dn:
        rows.append((f"max relative error between the samples ({dn['factor']}x denser grid, "
                     "true system)", f"{number(dn['max_rel_error'])} at "
                                     f"{number(dn['omega_at_max_rel_error'])} {fu} (RMS "
                                     f"{number(dn['rms_rel_error'])})"))
    rows += [
        ("delay h", f"{number(s['delay'], 6)} {tu}"),
        ("gain K (model.gain, in front of the sections)", number(s["gain"], 6)),
        ("wall time", f"{number(s['wall_time'])} s"),
        *([("computed on", f"`{environment_line(s['environment'])}`")]
          if s.get("environment") else []),
        ("iterations (all stages, polish steps included)", number(s["nit"])),
        ("success (final stage converged)", ("yes" if s["success"] else "NO") + (
            f": {md_text(s['message'])}" if s.get("message") and not s["success"]
            and not s.get("status") else "") + _to_the_noise(s)),
        ("P_N stable", _roots_check(ck["stable"], ck["max_pole_real_part"],
                                    ck["min_pole_damping"], "pole", fu,
                                    ck.get("n_poles_on_axis", 0))),
        ("P_N minimum phase", _roots_check(ck["minimum_phase"], ck["max_zero_real_part"],
                                           ck["min_zero_damping"], "zero", fu,
                                           ck.get("n_zeros_on_axis", 0))),
    ]
    floor = (s.get("options") or {}).get("min_damping")
    if floor is not None:
        rows.append(("damping floor", f"zeta >= {number(floor)} on every pole and zero "
                                      "(min_damping, imposed in every stage NLP)"))
    res = s.get("resolution")
    if res is not None:
        rows.append(("resolution check", "passed: no pole or zero narrower than the spacing"
                     if res["ok"] else
                     f"FAILED: {res['n_flagged_pairs']} near-cancelling pair(s), "
                     f"{res['n_unresolved']} unresolved pole(s)/zero(s) narrower than the "
                     "frequency spacing " + (
                         "(spare sections: the fit is exact to rounding; fit fewer sections)"
                         if s["rms_rel_error"] <= ROUNDING_RMS
                         else "(try min_damping='auto')")))
    return rows


def _to_the_noise(s):
    """", to the noise (...)" for a fit whose final stage is converged to the data's noise
    (``details["final_stage"]["noise_stall"]``), else ""."""
    stall = ((s.get("details") or {}).get("final_stage") or {}).get("noise_stall")
    if not (s.get("success") and stall):
        return ""
    return (f", to the noise: its last {stall['window']} iterations lowered the cost by "
            f"{number(stall['chi2'])} noise variances (at most {number(stall['chi2_allowed'])})"
            "; the strict stationarity test did not pass")


def _diagnostic_lines(s):
    """The "Diagnostics" section: what the checks found (empty when nothing)."""
    diags = s.get("diagnostics") or []
    if not diags:
        return []
    return (["## Diagnostics", ""]
            + [f"- **{d['code']}** ({d['severity']}): {md_text(d['message'])}" for d in diags]
            + [""])


def _pm(value, std, digits=4, determined=True):
    """'value ± std', '(not determined)' appended when std > |value| or the interval is
    not to be trusted (``determined`` False), or '(at its bound)'."""
    if std != std:
        return f"{number(value, digits)} (at its bound)"
    vague = (" (not determined)" if std is not None and (std > abs(value) or not determined)
             else "")
    return f"{number(value, digits)} ± {number(std)}{vague}"


def _bias_note(u):
    """Beside the low-frequency gain: the model's own when the bias correction moved it."""
    mine, gain = u.get("model_gain"), u.get("gain")
    if mine is None or gain is None or not gain or abs(mine / gain - 1) < 1e-4:
        return ""
    return (f" (corrected for the relative-error fit's bias, 1 + sigma^2; the model's own, "
            f"as exported: {number(mine, 6)})")


def _uncertainty_lines(s):
    """The "What the data determine" section: delay, gain and modes with ± one std."""
    u = s.get("uncertainty")
    if not u or "error" in u:
        return ([f"Parameter uncertainty: not available ({md_text(u['error'])}).", ""]
                if u else [])
    k = s["structure"].get("origin_order", int(s["structure"]["integrator"]))
    low = ("DC gain G(0)" if k == 0 else "K0 = lim s G(s)" if k == 1 else
           f"K0 = lim s^{k} G(s)" if k > 0 else f"K0 = lim G(s) / s^{-k}")
    fu, tu = _units(s)
    hz = fu == "rad/s"
    rows = [(f"delay h ({tu})", _pm(u["delay"], u["delay_std"], 6,
                                    not u.get("delay_reason"))),
            (f"low-frequency gain ({low})", _pm(u["gain"], u["gain_std"], 4,
                                                not u.get("gain_reason")) + _bias_note(u))]
    rows += [(f"mode {k}: omega_n ({fu})" + (" [f_n (Hz)]" if hz else "") + ", zeta",
              f"{_pm(m['omega_n'], m['omega_n_std'], 4, m.get('omega_n_determined', True))}"
              + (f" [{number(m['frequency_hz'])} Hz]" if hz else "")
              + f", {_pm(m['zeta'], m['zeta_std'], 4, m.get('zeta_determined', True))}")
             for k, m in enumerate(u["modes"], 1)]
    why = [(f"delay h ({tu})", u.get("delay_reason")), ("gain", u.get("gain_reason"))]
    why += [(f"mode {k}", m.get("reason")) for k, m in enumerate(u["modes"], 1)]
    notes = [f"- {name}: not determined: {md_text(r)}" for name, r in why if r]
    return ["## What the data determine", "",
            "One standard deviation from the weighted Jacobian at the optimum (delta method; "
            f"noise variance from the {u['noise_source']}); `FitResult.uncertainty`. "
            "\"Not determined\": the std exceeds the value (a pole/zero pair that nearly "
            "cancels, a mode outside the band, a delay traded against a far zero) or the "
            "95 % interval is not to be trusted (`ParameterUncertainty.not_determined` "
            "says why).", "",
            markdown_table(rows, ("parameter", "value ± std")), ""] + (notes + [""] if notes
                                                                     else [])


def _thesis_lines(s):
    """The "Thesis vs ours" section (empty without published numbers)."""
    t = s.get("thesis")
    if not t:
        return []
    st = s["structure"]
    src = t.get("source") or "thesis"
    trows = [(src, number(t.get("order")), number(t.get("max_rel_error")),
              number(t.get("rms_rel_error")), number(t.get("delay"), 6)),
             ("ours", number(st["order_rational_part"]), number(s["max_rel_error"]),
              number(s["rms_rel_error"]), number(s["delay"], 6))]
    lines = ["## Thesis vs ours", "",
             markdown_table(trows, ("", "order of P_N", "max rel. error", "RMS rel. error",
                                    "delay h (s)"), "lrrrr"), ""]
    if t.get("max_rel_error") is not None:
        better = s["max_rel_error"] <= t["max_rel_error"]
        lines += [f"Max relative error: ours is {'at or below' if better else 'ABOVE'} "
                  "the published value.", ""]
    return lines


_STATUS_WORDS = {"CONVERGED": "converged", "ACCEPTABLE": "converged (acceptable level)",
                 "COST_TOL": "converged (cost tolerance)", "MAX_ITER": "iteration limit",
                 "SMALL_STEP": "step too small", "STALLED": "stalled, not stationary",
                 "FAILED": "failed", "ERROR": "evaluation error"}


def _stage_status(r):
    """A stage's status in words ("converged", "iteration limit", ...); the solver's own
    status string stays in the machine-readable records (stages.csv, summary.json)."""
    word = _STATUS_WORDS.get(r.get("status"))
    return word or ("vector fitting" if r.get("solver_status") == "vector-fitting"
                    else "—")


def _iterations(r):
    """A stage's iterations: the solver's, plus the polish steps tried after it (so a
    stage at its limit of 200 reads "200 + 4 polish", not 204)."""
    d = r.get("details") or {}
    steps = d.get("polish_steps") or 0
    if steps and "ipopt_iterations" in d:
        return f"{number(d['ipopt_iterations'])} + {number(steps)} polish"
    return number(r["nit"])


def _stage_lines(stages, unit="rad/s"):
    """The "Stages" section: one table row per stage record (the main loop's stages by
    number, the others by their kind)."""
    srows, kinds = [], []
    for r in stages:
        kind = r.get("kind", "final" if r["stage"] > r["n_sections"] else "section")
        label = number(r["stage"]) if kind in ("gain-delay", "section") else kind
        if label == kind and kind not in kinds:
            kinds.append(kind)
        srows.append((label, number(r["n_sections"]), number(r["window"]),
                      number(r["omega_c"]), number(r["max_rel_error"]), _iterations(r),
                      number(r["wall_time"]), _stage_status(r)))
    known = {"final": "final: the loop's last stage, on all data",
             "rational-start": "rational-start: vector fitting of all sections (no solve; "
                               "its iterations are the trial delays)",
             "delay-search": "delay-search: the polish of the best nearby delay's vector fit "
                             "of a fit that did not converge",
             "far-roots": "far-roots: the model with its roots far above the band moved to "
                          "infinity (their phase into the delay), polished, for a fit that "
                          "did not converge",
             "zero-delay": "zero-delay: the model at h = 0, polished",
             "minimax": "minimax: the p-norm continuation of the minimax polish"}
    parts = [known.get(k, k) for k in kinds]
    if len(kinds) < len(srows):
        parts.insert(0, "stage 0 fits the gain and delay; stage N adds section N at omega_c "
                        "and refits on the window (the lowest-frequency points)")
    text = "; ".join(parts)
    text = text[:1].upper() + text[1:] + "."
    return ["## Stages", "", text, "",
            markdown_table(srows, ("stage", "sections", "window", f"omega_c ({unit})",
                                   "max rel. error (all data)", "iterations", "time (s)",
                                   "status"), "rrrrrrrl"), ""]
