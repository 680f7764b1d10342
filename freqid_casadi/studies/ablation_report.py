"""Ablation study, the report: conclusions, Markdown, figures and the report folder.

The folder (:func:`write_ablation_report`)::

    report.md                       first line: the command (formatting.generated_by_line)
    ablation.json                   every number of report.md, and per-stage records
    stages_<X>.png                  max error after each stage, IPOPT vs barrier-LM
    time_<X>.png                    max error against cumulative wall time (time to reach)
    rel_error_<X>.png               final relative error against frequency
    ablation_<X>.png                final max error and wall time of every variant

Every number of report.md comes from ablation.json (4 significant digits), and its first
section ends with conclusions computed from the numbers by :func:`conclusions` (no
hand-written claims). The folder is built in a temporary sibling folder and renamed into
place when complete (:func:`freqid_casadi.report.folder.report_folder`).
"""

import json
import math
import os
from functools import partial

from .. import plots
from ..report.environment import environment_line
from ..report.formatting import generated_by_line, markdown_table, number, ratio
from ..report.folder import atomic_write_text, check_out_dir, report_folder
from .thesis_matlab import transcription_lines, transcription_rows
from .ablation import NEAR_BOUND, run_ablation

__all__ = ["conclusions", "render_ablation", "write_ablation_report", "VARIANT_COLUMNS",
           "ABLATION_FILES"]

#: Files of the report folder other than the per-example figures.
ABLATION_FILES = ("ablation.json", "report.md")

_FIGURES = ("stages", "time", "rel_error", "ablation")

# numbers inside the conclusions' sentences: 3 significant digits, "n/a" when missing
_short = partial(number, digits=3, missing="n/a")


def conclusions(summary):
    """Sentences computed from the numbers of a study (no hand-written claims).

    Parameters
    ----------
    summary : dict
        The numbers of a study, :meth:`AblationResult.as_dict` (``cases`` filled in).

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
                           f"{_short(base['max_rel_error'])} in {_short(base['wall_time'])} s.")
                continue
            ratio = c["error_ratio"]
            verdict = ("n/a" if ratio is None else "IPOPT lower" if ratio > 1
                       else "IPOPT not lower")
            reach = (f"IPOPT first reached the barrier-LM's final error after "
                     f"{_short(c['ipopt_time_to_reach'])} s (stage {c['ipopt_stage_to_reach']}), "
                     f"vs {_short(c['lm_stage_time'])} s for the whole barrier-LM run "
                     f"({_short(c['reach_speedup'])}x faster)"
                     if c["ipopt_time_to_reach"] is not None
                     else "IPOPT never reached the barrier-LM's final error")
            out.append(
                f"{name}: IPOPT's final max relative error {_short(base['max_rel_error'])} vs "
                f"{_short(c['lm_max_rel_error'])} for {c['lm_label']} (ratio barrier-LM/IPOPT "
                f"{_short(ratio)}, {verdict}); "
                f"total time {_short(base['wall_time'])} s vs {_short(c['lm_wall_time'])} s; "
                f"{reach}.")
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
                   f"lower: {'MET' if met_err else 'NOT MET'} ({_short(r)}x); time to reach the "
                   f"barrier-LM's final error lower: {'MET' if met_time else 'NOT MET'} "
                   f"({_short(t_i)} s vs {_short(t_l)} s).")
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
                       f"{best['label']} ({best['group']}): {ratio(best['error_ratio'])} the "
                       f"default's error, at {ratio(best['time_ratio'])} its time.")
    if effects:
        ranked = sorted(effects.items(), key=lambda kv: -max(e[0] for e in kv[1]))
        parts = []
        for group, items in ranked:
            eff, name, a = max(items, key=lambda e: e[0])
            parts.append(f"{group} (up to {ratio(a['error_ratio'])} on {name}, {a['label']})")
        out.append("Factors ranked by their largest effect on the final max error (ratio to "
                   "the IPOPT default; > 1x is worse): " + "; ".join(parts) + ".")
        slow = [(a["time_ratio"], n, a) for n, c in cases.items() for a in c["ablation"]
                if a["time_ratio"] is not None]
        if slow:
            tr, n, a = max(slow, key=lambda e: abs(math.log(e[0])) if e[0] > 0 else math.inf)
            out.append(f"Largest change of wall time: {a['label']} on {n}, "
                       f"{ratio(tr)} the default's time.")
    return out



def _reach_text(t):
    return number(t, missing="n/a")


#: Columns of the per-variant tables of report.md: (header, JSON key of the variant record).
VARIANT_COLUMNS = (("max rel. error", "max_rel_error"), ("RMS rel. error", "rms_rel_error"),
                   ("iterations", "nit"), ("function evaluations", "nfev"),
                   ("wall time (s)", "wall_time"), ("params near bound", "n_near_bound"),
                   ("delay (s)", "delay"), ("failed stages", "n_failed_stages"),
                   ("iteration-limit stages", "n_max_iter_stages"))


def _variant_row(r, first):
    cells = list(first)
    cells += [number(r.get(k)) for _, k in VARIANT_COLUMNS]
    if r["status"] == "ok":
        # the fit's status (ok / poor-fit / not-converged); its message is listed below the
        # table (:func:`_message_lines`)
        status = r.get("fit_status") or ("ok" if r["success"] else "not-converged")
    else:
        status = f"FAILED: {r['message']}"
    return cells + [status]


def _message_lines(records):
    """One bullet per variant whose fit is not "ok": its message (a sentence with the next
    step, :attr:`FitResult.message`)."""
    notes = [f"- {r['label']}: {r['message']}" for r in records
             if r["status"] == "ok" and (r.get("fit_status") or "ok") != "ok"]
    return (["Messages of the fits whose status is not ok:", ""] + notes + [""]) if notes \
        else []


def render_ablation(summary):
    """The Markdown text of report.md from the content of ablation.json.

    Parameters
    ----------
    summary : dict
        :meth:`AblationResult.as_dict` with ``command`` and ``conclusions`` added.

    Returns
    -------
    str
        Every number in the text is taken from ``summary`` (4 significant digits), so
        ablation.json and report.md agree.
    """
    s = summary
    lines = _intro_lines(s)
    lines += ["## Conclusions (computed from the numbers below)", ""]
    lines += [f"- {c}" for c in s["conclusions"]] + [""]
    lines += _summary_lines(s["cases"])
    if "thesis_matlab" in s and not s.get("quick"):
        ours = {n: c["comparison"][0]["ipopt_max_rel_error"] for n, c in s["cases"].items()
                if c.get("comparison")}
        lines += transcription_lines(s["thesis_matlab"], ours)
    for name, case in s["cases"].items():
        lines += _case_lines(name, case)
    lines += ["## Files", "",
              "`ablation.json`: every number above at full precision, with the per-stage "
              "records of every variant (`cases.<example>.variants[].stages`).", ""]
    return "\n".join(lines)


def _intro_lines(s):
    lm = s["settings"]["lm_options"]
    lines = [generated_by_line(s["command"]), "",
             "# Ablation: IPOPT with bounds vs the thesis's barrier-LM, and IPOPT's options", "",
             f"Command: `{s['command']}`. Total run time {number(s['total_wall_time'])} s on "
             f"{s['settings']['machine']['cpu_count']} CPUs (Python "
             f"{s['settings']['machine']['python']}).", "",
             *([f"Computed on `{environment_line(s['settings']['environment'])}`.", ""]
               if s["settings"].get("environment") else []),
             "Default (every ablation changes one factor from it): IPOPT, "
             + ", ".join(f"{k}={v}" for k, v in s["settings"]["default"].items()
                         if k != "method")
             + " (fit's defaults except final_max_iter, 200 in fit: the final stage runs "
               "into its cap in nearly every variant, and a larger budget lets the ablated "
               "option rather than the cap set the ranking). Barrier-LM caps: "
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
    return lines


def _summary_lines(cases):
    rows = []
    for name, case in cases.items():
        t = (case.get("thesis") or {}).get("max_rel_error")
        for c in case["comparison"]:
            rows.append((name, c["lm_label"], number(c["ipopt_max_rel_error"]),
                         number(c["lm_max_rel_error"]), number(c["error_ratio"]),
                         number(c["ipopt_wall_time"]), number(c["lm_wall_time"]),
                         _reach_text(c["ipopt_time_to_reach"]),
                         number(c["lm_stage_time"]), number(t)))
    return ["## Summary: does IPOPT reach a lower max error than the barrier-LM, and how "
            "fast?", "",
            markdown_table(rows, (
                "example", "barrier-LM variant", "IPOPT max rel. error",
                "barrier-LM max rel. error", "error ratio LM/IPOPT", "IPOPT time (s)",
                "barrier-LM time (s)", "IPOPT time to reach LM error (s)",
                "barrier-LM stage time (s)", "thesis max rel. error (published)"),
                "llrrrrrrrr"), ""]


_HEADERS = ["variant"] + [h for h, _ in VARIANT_COLUMNS] + ["status"]
_ALIGN = "l" + "r" * len(VARIANT_COLUMNS) + "l"


def _case_lines(name, case):
    d, st = case["data"], case["structure"]
    lines = [f"## Example {name}: {d['name']}", "",
             f"{d['n_points']} points from {number(d['omega_min'])} to "
             f"{number(d['omega_max'])} rad/s; {st['n_sections']} {st['basis']} sections, "
             f"{'with' if st['integrator'] else 'no'} integrator, "
             f"{'with' if st['delay'] else 'no'} delay.", ""]
    method = [r for r in case["variants"] if r["group"] == "method"]
    lines += ["### IPOPT vs barrier-LM", "",
              markdown_table([_variant_row(r, (r["label"],)) for r in method], _HEADERS,
                             _ALIGN), ""] + _message_lines(method)
    crows = [(c["lm_label"], number(c["lm_max_rel_error"]),
              _reach_text(c["ipopt_time_to_reach"]), number(c["ipopt_stage_to_reach"]),
              _reach_text(c["lm_time_to_reach"]), number(c["lm_stage_time"]),
              number(c["reach_speedup"])) for c in case["comparison"]]
    if crows:
        lines += ["Time to reach the barrier-LM's final max error:", "",
                  markdown_table(crows, (
                      "target (barrier-LM variant)", "target max rel. error",
                      "IPOPT time to reach (s)", "IPOPT stage", "barrier-LM time to reach (s)",
                      "barrier-LM stage time (s)", "speed-up"), "lrrrrrr"), ""]
    lines += [f"![max error after each stage, {name}](stages_{name}.png)", "",
              f"![max error against time, {name}](time_{name}.png)", "",
              f"![relative error, {name}](rel_error_{name}.png)", ""]
    return lines + _ablation_lines(name, case)


def _ablation_lines(name, case):
    abl = [r for r in case["variants"] if r["group"] != "method"]
    if not abl:
        return []
    ratios = {a["key"]: a for a in case["ablation"]}
    base = next((r for r in case["variants"] if r["key"] == "ipopt"), None)
    rows = []
    if base is not None:
        rows.append(_variant_row(base, ("default", base["label"], number(1.0), number(1.0))))
    for r in abl:
        a = ratios[r["key"]]
        rows.append(_variant_row(r, (r["group"], r["label"], number(a["error_ratio"]),
                                     number(a["time_ratio"]))))
    lines = ["### IPOPT ablations (one factor at a time from the default)", "",
             markdown_table(rows, ["factor", "variant", "error ratio", "time ratio"]
                            + _HEADERS[1:], "llrr" + _ALIGN[1:]), "",
             "error ratio / time ratio: the variant's final max error / wall time "
             "divided by the default's (> 1: worse / slower).", ""]
    lines += _message_lines(([base] if base is not None else []) + abl)
    notes = [f"- {r['label']}: {r['note']}" for r in abl if r.get("note")]
    lines += notes + ([""] if notes else [])
    return lines + [f"![ablations, {name}](ablation_{name}.png)", ""]


# ----------------------------------------------------------------------------- figures


def _figures(summary, fits, folder):
    written = []
    for name, case in summary["cases"].items():
        res = fits.get(name, {})
        labels = {r["key"]: r["label"] for r in case["variants"]}
        method = {labels[k]: res[k] for k in ("ipopt", "lm-thesis", "lm-marquardt")
                  if k in res}
        title = f"{name}: {case['data']['name']}"
        if method:
            stages = plots.stage_errors(method, title=f"{title}: max error after each stage")
            rel = plots.relative_error(
                method, title=f"{title}: relative error of the final models",
                reference=(case.get("thesis") or {}).get("max_rel_error"),
                reference_label="thesis (published max)")
        else:
            stages = plots.message_figure(f"{title}: every method variant failed")
            rel = plots.message_figure(f"{title}: every method variant failed")
        plots.save_figure(stages, os.path.join(folder, f"stages_{name}.png"))
        plots.save_figure(rel, os.path.join(folder, f"rel_error_{name}.png"))
        plots.save_figure(_time_figure(case, title), os.path.join(folder, f"time_{name}.png"))
        bars = [dict(label=r["label"], group=r["group"],
                     max_rel_error=r["max_rel_error"] if r["status"] == "ok" else None,
                     wall_time=r["wall_time"]) for r in case["variants"]]
        base = next((r for r in case["variants"]
                     if r["key"] == "ipopt" and r["status"] == "ok"), None)
        plots.save_figure(plots.variant_bars(bars, title=f"{title}: every variant",
                                             baseline=base),
                          os.path.join(folder, f"ablation_{name}.png"))
        written += [f"{k}_{name}.png" for k in _FIGURES]
    return written


def _time_figure(case, title):
    """Max error over all data against cumulative stage wall time, method variants."""
    method = [r for r in case["variants"] if r["group"] == "method" and r["status"] == "ok"]
    lines, hlines = [], []
    for k, r in enumerate(method):
        lines.append(dict(x=[s["cumulative_time"] for s in r["stages"]],
                          y=[s["max_rel_error"] for s in r["stages"]], color=f"C{k}",
                          marker="o", ms=3.5, lw=1.1, label=r["label"]))
        if r["key"] != "ipopt":
            hlines.append(dict(y=r["max_rel_error"], color=f"C{k}", ls=":", lw=0.9))
    reached = [c for c in case["comparison"] if c["ipopt_time_to_reach"] is not None]
    lines.append(dict(x=[c["ipopt_time_to_reach"] for c in reached],
                      y=[c["lm_max_rel_error"] for c in reached], color="k", marker="*",
                      ms=9, ls="none", label="IPOPT reaches the barrier-LM's final error"))
    return plots.line_plot(lines, hlines=hlines, title=f"{title}: error against time",
                           xlabel="cumulative wall time of the stages (s)",
                           ylabel="max relative error over all data")


# ----------------------------------------------------------------------------- writer


def write_ablation_report(examples, out_dir, *, command, quick=False, force=False,
                          progress=False):
    """Run the study and write its report folder (see the module docstring).

    Parameters
    ----------
    examples : mapping name -> Example
        As in :func:`~freqid_casadi.studies.ablation.run_ablation`.
    out_dir : str or os.PathLike
        Folder to create; its parent must exist.
    command : str
        The command that made the report (first line of report.md).
    quick : bool
        Reduced problems and variants (:data:`~freqid_casadi.studies.ablation.QUICK`).
    force : bool
        Replace an existing ``out_dir`` (only after the new report is complete).
    progress : bool or callable
        As in :func:`~freqid_casadi.studies.ablation.run_ablation`.

    Returns
    -------
    (str, dict)
        The absolute path of the folder and the content of ablation.json.

    Raises
    ------
    OptionError
        If ``out_dir`` exists and ``force`` is false (checked before the study and again
        before the rename), or its parent does not exist, or ``examples`` is empty.
    """
    path = check_out_dir(out_dir, force)
    result = run_ablation(examples, quick=quick, progress=progress)
    summary = dict(command=" ".join(str(command).split()), **result.as_dict())
    summary["conclusions"] = conclusions(summary)
    summary["thesis_matlab"] = None if quick else transcription_rows()
    with report_folder(out_dir, force) as (tmp, _):
        figures = _figures(summary, result.fits, tmp)
        summary["files"] = list(ABLATION_FILES) + figures
        atomic_write_text(os.path.join(tmp, "ablation.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), render_ablation(summary))
    return path, summary
