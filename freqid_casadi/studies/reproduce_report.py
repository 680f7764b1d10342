"""Reproduction of the thesis's chapter 4, the report: Table 4.1, Markdown, figures, folder.

:func:`write_reproduce_report` runs :func:`~freqid_casadi.studies.reproduce.run_reproduction`
and writes::

    report.md       first line: the command (formatting.generated_by_line); Table 4.1 and notes
    report.json     every number of report.md (full precision) and more
    curves.json     the curves of the figures (omega, errors)
    <X>_model.json  our fitted model of example X (RationalDelayModel.load)
    *.png           the figures (list in report.md, with the thesis figure they correspond to)

The folder is built in a temporary sibling folder and renamed into place when complete, so
either the whole report exists or nothing does; an existing folder is replaced only with
``force=True`` (checked before the fits start, and again before the rename). The command is
``freqid reproduce`` (:mod:`freqid_casadi.cli.app`; ``scripts/reproduce_thesis.py`` calls it).
"""

import json
import logging
import os
import time

import numpy as np

from .. import plots
from ..report.environment import environment, environment_line
from ..report.formatting import generated_by_line, json_safe, markdown_table, number
from ..report.folder import atomic_write_text, check_out_dir, report_folder
from .thesis_matlab import transcription_lines, transcription_rows
from .reproduce import (METHOD_KEYS, NO_DELAY, TABLE_QUANTITIES, THESIS_TABLE_4_1,
                        run_reproduction)

__all__ = ["write_reproduce_report", "render_reproduction", "table_4_1", "TABLE_COLUMNS",
           "REPRODUCE_FORMAT"]

log = logging.getLogger(__name__)

REPRODUCE_FORMAT = "freqid_casadi.reproduce_thesis"

#: Columns of Table 4.1.
TABLE_COLUMNS = ("thesis NLLS", "thesis subspace", "ours (IPOPT)", "ours (barrier-LM)",
                 "subspace (ours)", "Fourier (ours)", "AAA", "vector fitting")
_METHOD_LABELS = dict(zip(METHOD_KEYS, TABLE_COLUMNS[2:]))


# ----------------------------------------------------------------------------- Markdown


def table_4_1(examples):
    """Table 4.1 as JSON: columns and rows (example, quantity, one value per column).

    Parameters
    ----------
    examples : dict
        ``{"A": RationalExample.summary, ...}``.

    Returns
    -------
    dict
        ``columns`` (:data:`TABLE_COLUMNS`) and ``rows`` (``example``, ``quantity``,
        ``label``, ``values``: the thesis's two columns then one per method).
    """
    rows = []
    for key, ex in examples.items():
        t = THESIS_TABLE_4_1[key]
        n_poles_thesis = t["order"] + (1 if ex["integrator"] else 0)
        thesis_nlls = {"n_poles": n_poles_thesis, "max_rel_error": t["nlls"],
                       "rms_rel_error": None, "n_rhp_zeros": 0, "n_rhp_poles": 0,
                       "delay": t["delay"], "wall_time": None}
        thesis_sub = {"n_poles": None, "max_rel_error": t["subspace"], "rms_rel_error": None,
                      "n_rhp_zeros": None, "n_rhp_poles": None, "delay": NO_DELAY,
                      "wall_time": None}
        for q, label in TABLE_QUANTITIES:
            values = [thesis_nlls[q], thesis_sub[q]]
            values += [ex["methods"][m][q] for m in METHOD_KEYS]
            rows.append({"example": key, "quantity": q, "label": label, "values": values})
    return {"columns": list(TABLE_COLUMNS), "rows": rows}


def _render_table(table):
    rows = [[r["example"], r["label"]] + [number(v) for v in r["values"]]
            for r in table["rows"]]
    return markdown_table(rows, ["example", "quantity"] + table["columns"],
                          "ll" + "r" * len(table["columns"]))


_FIGURE_NOTES = {
    "bode": "Bode plot of G and G_N (ours, IPOPT)",
    "rel_error": "relative error of our models (IPOPT, barrier-LM)",
    "pole_zero": "poles and zeros of P_N (ours, IPOPT)",
    "hsv": "Hankel singular values of P_N",
    "methods": "relative error of every method on one plot",
    "subspace_pole_zero": "poles and zeros of the subspace model",
    "perturbed": "perturbed plants (+5 %, +10 %) against the identified model's error",
}
# Thesis figure numbers stated in SPEC §4-§6; the others are matched by content only.
_THESIS_FIGS = {("A", "hsv"): "4.5", ("B", "hsv"): "4.11", ("C", "hsv"): "4.16",
                ("A", "perturbed"): "4.8", ("B", "perturbed"): "4.13",
                ("C", "perturbed"): "4.19", ("A", "subspace_pole_zero"): "4.7"}


def render_reproduction(summary):
    """The Markdown text of report.md from the content of report.json.

    Parameters
    ----------
    summary : dict
        The content of report.json (see :func:`write_reproduce_report`).

    Returns
    -------
    str
        Every number is taken from ``summary`` (:func:`freqid_casadi.report.formatting.number`).
    """
    s = summary
    lines = [generated_by_line(s["command"]), "",
             "# Reproduction of the thesis's chapter 4 (Table 4.1, figures 4.1–4.21)", ""]
    if s["quick"]:
        lines += ["**Quick mode**: small problems (windowed data, few sections) to test the "
                  "report; the numbers are NOT comparable with the thesis.", ""]
    lines += [f"Total wall time {number(s['wall_time'])} s. Every number below is in "
              "`report.json` at full precision; the plotted curves are in `curves.json`.", ""]
    if s.get("environment"):
        lines += [f"Computed on `{environment_line(s['environment'])}`. Another "
                  "BLAS kernel or numpy SIMD level can move the last digits, and example C "
                  "more (docs/guide/reproducibility.md).", ""]
    if s["examples"]:
        lines += _table_lines(s)
        for k, v in s["examples"].items():
            lines += _example_lines(k, v, s["figures"])
    if s.get("thesis_matlab") is not None or (s["examples"] and not s["quick"]):
        ours = {k: v["methods"]["ipopt"]["max_rel_error"] for k, v in s["examples"].items()}
        lines += transcription_lines(s.get("thesis_matlab"), ours)
    if s.get("fractional"):
        lines += _fractional_lines(s["fractional"])
    if s.get("moheimani"):
        lines += _moheimani_lines(s["moheimani"])
    lines += ["## Files", "", ", ".join(f"`{f}`" for f in s["files"]), ""]
    return "\n".join(lines)


def _table_lines(s):
    ex = s["examples"]
    lines = []
    lines += ["## Table 4.1", "",
              "Max relative error = max over the data of |(G − G_N)/G_N| (thesis Table "
              "4.1); RMS = the root mean square of the same curve (the thesis's MATLAB "
              "`cost_func` returns the RMS, SPEC §5). Every method has as many poles as "
              "our model: order of P_N, plus the integrator for A and C "
              "(AAA may stop with fewer poles once its tolerance is met; the count "
              "reached is in the table).", "",
              _render_table(s["table_4_1"]), "",
              f"\\* `{NO_DELAY}`: the method cannot fit a delay; it fitted the data as "
              "given (the delay stays in the data's phase and must be absorbed by the "
              "rational model). The thesis gives no wall times, RMS errors or RHP counts "
              "for its methods (its NLLS models are minimum phase by construction, hence "
              "0); a dash marks a number the thesis does not state.", ""]
    lm = [f"{k}: {v['methods']['barrier-lm'].get('note', v['methods']['barrier-lm'])}"
          for k, v in ex.items() if v["methods"]["barrier-lm"]["status"] != "ok"]
    b = s["barrier_lm"]
    lines += [f"Barrier-LM (the thesis's method, SPEC §3): lm_options {b['options']}. "
              f"It is included only if its fit of A finishes within "
              f"{number(b['time_limit_A'])} s; B and C then run with a cap of "
              f"{number(b['time_cap_B_C'])} s each"
              + (f". Not run or stopped: {'; '.join(lm)}." if lm
                 else ". It finished on every example."), ""]

    lines += ["## Subspace: ours vs the thesis's", "",
              markdown_table(
                  [[k, number(THESIS_TABLE_4_1[k]["subspace"]),
                    number(v["methods"]["subspace"]["max_rel_error"]),
                    number(v["methods"]["subspace"]["n_poles"])]
                   for k, v in ex.items()],
                  ["example", "thesis subspace max rel. error",
                   "our subspace max rel. error", "poles"], "lrrr"), ""]

    lines += ["## Minimum phase (zeros of each model)", "",
              "yes = no zero with Re > 0; in brackets the number of RHP zeros / RHP "
              "poles. Ours are minimum phase and stable by construction (β ≥ 0).", ""]
    mrows = []
    for k, v in ex.items():
        row = [k]
        for m in METHOD_KEYS:
            e = v["methods"][m]
            row.append(e["status"] if e["status"] != "ok" else
                       f"{number(e['minimum_phase'])} ({e['n_rhp_zeros']} / "
                       f"{e['n_rhp_poles']})")
        mrows.append(row)
    lines += [markdown_table(mrows, ["example"] + [_METHOD_LABELS[m]
                                                   for m in METHOD_KEYS]), ""]
    return lines


def _example_lines(k, v, figures):
    lines = []
    ours = v["methods"]["ipopt"]
    d = v["data"]
    lines += [f"## Example {k}", "",
              f"Data: {d['name']}, {d['n_points']} points, {number(d['omega_min'])}"
              f" to {number(d['omega_max'])} rad/s. Ours: {v['n_sections']} "
              f"second-order sections (order of P_N {v['order_p_n']}), "
              f"{'with' if v['integrator'] else 'no'} integrator, with delay; "
              f"max rel. error {number(ours['max_rel_error'])} "
              f"(thesis {number(v['thesis']['nlls'])}), delay "
              f"{number(ours['delay'])} s (true "
              f"{number(v['true_delay']) if v['true_delay'] else 'none in G'}, "
              f"thesis {number(v['thesis']['delay'])}), "
              f"final stage converged: {number(ours['success'])}.", "",
              f"Hankel singular values of P_N: {len(v['hankel_singular_values_p_n'])}"
              f", of which {v['hsv_above_1e-3']} above 1e-3 σ1 and "
              f"{v['hsv_above_1e-6']} above 1e-6 σ1 (σ1 = "
              f"{number(v['hankel_singular_values_p_n'][0])}).", ""]
    prow = [[p, number(e["max_rel_difference"]),
             number(e["fraction_of_points_above_model_error"])]
            for p, e in v["perturbed"].items()]
    lines += [markdown_table(prow, ["perturbed plant", "max |G_pert/G − 1|",
                                    "fraction of points where it exceeds the "
                                    "model's error"], "lrr"), ""]
    for fig in _FIGURE_NOTES:
        fname = f"{k}_{fig}.png"
        if fname in figures:
            tf = _THESIS_FIGS.get((k, fig))
            note = _FIGURE_NOTES[fig] + (f" (thesis fig. {tf})" if tf else "")
            lines += _figure_lines(fname, note, note)
    return lines


def _fractional_lines(f):
    lines = ["## 1/√s (thesis §4.2, figs 4.20–4.21)", "",
              f"Data: 1/√s on {f['data']['n_points']} points, "
              f"{number(f['data']['omega_min'])} to "
              f"{number(f['data']['omega_max'])} rad/s. Ours: {f['n_sections']} "
              "first-order sections, no delay; continued fraction (Matsuda & Fujii) of "
              f"the same order; Newton process (Carlson & Halijak) with "
              f"{f['newton_iterations']} iterations (orders are (3^k − 1)/2, the nearest "
              "at or above ours); Fourier method (Gu, Khargonekar & Lee) of the same "
              "order. E(jω) = |G_D − G_N/(1 + G_N)| with G_D = 1/(1 + √s).", ""]
    frows = [[label, number(e["n_poles"]), number(e["max_closed_loop_error"]),
              number(e["max_rel_error"]), number(e["minimum_phase"]),
              number(e["wall_time"])] for label, e in f["methods"].items()]
    lines += [markdown_table(frows, ["method", "poles", "max E(jω)",
                                     "max rel. error (open loop)", "minimum phase",
                                     "wall time (s)"], "lrrrlr"), ""]
    lines += _figure_lines("fractional_bode.png", "1/√s and its approximations",
                           "1/√s and the approximations (thesis fig. 4.20)")
    lines += _figure_lines("fractional_closed_loop_error.png", "closed-loop error",
                           "E(jω) for each method (thesis fig. 4.21)")
    return lines


def _figure_lines(fname, alt, caption):
    """A figure of report.md and its caption line."""
    return [f"![{alt}]({fname})", "", f"*{fname}: {caption}.*", ""]


def _moheimani_lines(m):
    lines = ["## Moheimani's beam with and without K_opt", "",
              f"{m['n_modes']}-mode simply-supported beam as the truth, "
              f"{m['n_kept']}-mode truncation G_r, ω_c = {number(m['omega_c'])} rad/s "
              "(SPEC §4).", "",
              markdown_table([
                  ["K_opt, closed form (m/N)", number(m["k_opt"])],
                  ["K from the data, (1/2ω_c) ∫ Re(G − G_r) dω (m/N)",
                   number(m["k_from_data"])],
                  ["max |G − G_r| for ω ≤ ω_c (m/N)",
                   number(m["max_abs_error_in_band_without_k"])],
                  ["max |G − G_r − K_opt| for ω ≤ ω_c (m/N)",
                   number(m["max_abs_error_in_band_with_k"])],
                  ["RMS |G − G_r| for ω ≤ ω_c (m/N)",
                   number(m["rms_abs_error_in_band_without_k"])],
                  ["RMS |G − G_r − K_opt| for ω ≤ ω_c (m/N)",
                   number(m["rms_abs_error_in_band_with_k"])]],
                  ["quantity", "value"], "lr"), ""]
    lines += _figure_lines("moheimani_bode.png", "beam",
                           "magnitude of the truth, G_r and G_r + K_opt")
    lines += _figure_lines("moheimani_error.png", "beam error",
                           "|G − G_r| with and without K_opt")
    return lines


# ----------------------------------------------------------------------------- figures

_OMEGA = r"frequency $\omega$ (rad/s)"
_REL = r"relative error $|(G - G_N)/G_N|$"


def _thesis_line(thesis_max):
    return dict(y=thesis_max, color="k", ls=":", lw=0.9,
                label=f"thesis NLLS max ({thesis_max})")


def _example_figures(key, ex):
    """(file name, figure) of example ``key`` (a RationalExample), in report order."""
    omega, rel = ex.data.omega, ex.curves["rel_error"]
    thesis_max = THESIS_TABLE_4_1[key]["nlls"]
    ours = [dict(x=omega, y=rel["ipopt"], color="C0", lw=1.3,
                 label=f"ours, IPOPT (max {np.max(rel['ipopt']):.3g})")]
    if "barrier-lm" in rel:
        ours.append(dict(x=omega, y=rel["barrier-lm"], color="C1", lw=1.0, ls="--",
                         label=f"ours, barrier-LM (max {np.max(rel['barrier-lm']):.3g})"))
    methods = [dict(x=omega, y=r, label=f"{_METHOD_LABELS[m]} (max {np.max(r):.3g})",
                    **plots.line_style(k)) for k, (m, r) in enumerate(rel.items())]
    hsv = ex.summary["hankel_singular_values_p_n"]
    pert = [dict(x=omega, y=rel["ipopt"], color="C0", lw=1.4,
                 label=r"identified model $|(G - G_N)/G_N|$")]
    pert += [dict(x=omega, y=d, color=f"C{k + 1}", lw=1.0, ls="--",
                  label=rf"perturbed plant {label}: $|G_{{pert}}/G - 1|$")
             for k, (label, d) in enumerate(ex.curves["perturbed"].items())]
    figs = [
        ("bode", lambda: plots.bode(ex.ours, title=f"Example {key}: G and G_N (ours, IPOPT)")),
        ("rel_error", lambda: plots.line_plot(
            ours, hlines=[_thesis_line(thesis_max)], xlabel=_OMEGA, ylabel=_REL,
            title=f"Example {key}: relative error of our models")),
        ("pole_zero", lambda: plots.pole_zero(ex.ours.model, zoom="auto")),
        ("hsv", lambda: plots.line_plot(
            [dict(x=np.arange(1, hsv.size + 1), y=hsv, color="C0", marker="o", ms=4, lw=0.8)],
            xscale="linear", xlabel="index i",
            ylabel=r"Hankel singular value $\sigma_i$ of $P_N$",
            title=f"Example {key}: Hankel singular values of $P_N$ (order {hsv.size})")),
        ("methods", lambda: plots.line_plot(
            methods, hlines=[_thesis_line(thesis_max)], xlabel=_OMEGA, ylabel=_REL,
            title=f"Example {key}: relative error of each method",
            legend_fontsize="x-small", figsize=(7.2, 4.8))),
    ]
    if "subspace" in ex.models:
        figs.append(("subspace_pole_zero", lambda: plots.pole_zero_symlog(
            ex.models["subspace"], title=f"Example {key}: poles and zeros of the subspace "
                                         "model")))
    figs.append(("perturbed", lambda: plots.line_plot(
        pert, xlabel=_OMEGA, ylabel="relative error",
        title=f"Example {key}: perturbed plants vs the model's error")))
    return [(f"{key}_{name}.png", make) for name, make in figs]


def _fractional_figures(study):
    c = study.curves
    errors = [dict(x=c["omega"], y=e, label=f"{label} (max {np.max(e):.3g})",
                   **plots.line_style(k))
              for k, (label, e) in enumerate(c["closed_loop_error"].items())]
    return [
        ("fractional_bode.png", lambda: plots.bode_curves(
            c["omega"], c["response"], reference=(r"$1/\sqrt{s}$", study.data.response),
            title=r"$1/\sqrt{s}$ and its rational approximations", phase_limits=(-100, 10))),
        ("fractional_closed_loop_error.png", lambda: plots.line_plot(
            errors, xlabel=_OMEGA, ylabel=r"$E(j\omega) = |G_D - G_{N,\mathrm{closed\ loop}}|$",
            title=r"closed loop $G_D = 1/(1 + \sqrt{s})$: error of each approximation",
            figsize=(7.2, 4.8))),
    ]


def _moheimani_figures(study):
    c, m = study.curves, study.summary
    names = {"truth": f"{m['n_modes']}-mode model (truth)",
             "G_r": f"{m['n_kept']}-mode truncation $G_r$",
             "G_r + K_opt": f"$G_r + K_{{opt}}$ ($K_{{opt}}$ = {m['k_opt']:.3g} m/N)"}
    bode = [dict(x=c["omega"], y=np.abs(c[key]), label=label,
                 **dict(plots.line_style(k), lw=2.0 if key == "truth" else 1.0))
            for k, (key, label) in enumerate(names.items())]
    err = [dict(x=c["omega"], y=c["error_without_k"], label=r"$|G - G_r|$ (without $K_{opt}$)",
                **plots.line_style(1)),
           dict(x=c["omega"], y=c["error_with_k"],
                label=r"$|G - G_r - K_{opt}|$ (with $K_{opt}$)", **plots.line_style(2))]
    band = [dict(x=m["omega_c"], color="0.3", ls=":", lw=0.9,
                 label=rf"$\omega_c$ = {m['omega_c']:g} rad/s")]
    return [
        ("moheimani_bode.png", lambda: plots.line_plot(
            bode, vlines=band, xlabel=_OMEGA, ylabel="|G(jω)| (m/N)",
            title="Moheimani's simply-supported beam")),
        ("moheimani_error.png", lambda: plots.line_plot(
            err, vlines=band, xlabel=_OMEGA, ylabel="absolute error (m/N)",
            title="Moheimani's beam: truncation error with and without $K_{opt}$")),
    ]


# ----------------------------------------------------------------------------- writer


def _curves_json(curves):
    """Complex arrays as {"real": ..., "imag": ...}; the rest as lists."""
    if isinstance(curves, dict):
        return {k: _curves_json(v) for k, v in curves.items()}
    arr = np.asarray(curves)
    if np.iscomplexobj(arr):
        return {"real": arr.real.tolist(), "imag": arr.imag.tolist()}
    return arr.tolist()


def _summary(run, command):
    """report.json without figures, files and wall time (added by the writer)."""
    summary = {"format": REPRODUCE_FORMAT, "version": 1,
               "command": " ".join(str(command).split()), "quick": run.quick,
               "environment": environment(),
               "examples_run": list(run.examples_run), "barrier_lm": run.barrier_lm,
               "examples": {k: ex.summary for k, ex in run.examples.items()},
               "fractional": run.fractional.summary if run.fractional else None,
               "moheimani": run.moheimani.summary if run.moheimani else None}
    if summary["examples"]:
        summary["table_4_1"] = table_4_1(summary["examples"])
    summary["thesis_matlab"] = None if run.quick else transcription_rows()
    return summary


def _curves(run):
    curves = {k: ex.curves for k, ex in run.examples.items()}
    for name in ("fractional", "moheimani"):
        if getattr(run, name) is not None:
            curves[name] = getattr(run, name).curves
    return curves


def write_reproduce_report(out_dir, *, command, force=False, quick=False, examples=None):
    """Run the thesis's comparisons and write the report folder ``out_dir``.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Folder to create (its parent must exist).
    command : str
        The command that made the report; the first line of report.md names it.
    force : bool
        Replace an existing ``out_dir`` (only once the new one is complete).
    quick : bool
        Small problems for tests (see
        :func:`~freqid_casadi.studies.reproduce.run_reproduction`).
    examples : str or sequence of str, optional
        Subset of :data:`~freqid_casadi.studies.reproduce.EXAMPLE_NAMES`. Default: all;
        with ``quick``: A, fractional and moheimani.

    Returns
    -------
    dict
        The content of report.json.

    Raises
    ------
    OptionError
        If ``out_dir`` exists without ``force``, its parent does not exist, or
        ``examples`` names an unknown example.
    """
    t0 = time.perf_counter()
    path = check_out_dir(out_dir, force)            # before the long fits
    run = run_reproduction(examples, quick=quick)
    summary = _summary(run, command)
    figures = [f for key, ex in run.examples.items() for f in _example_figures(key, ex)]
    figures += _fractional_figures(run.fractional) if run.fractional else []
    figures += _moheimani_figures(run.moheimani) if run.moheimani else []
    with report_folder(out_dir, force) as (tmp, _):
        for key, ex in run.examples.items():
            ex.ours.model.save(os.path.join(tmp, f"{key}_model.json"))
        for name, make in figures:
            plots.save_figure(make(), os.path.join(tmp, name))
        summary["figures"] = [name for name, _ in figures]
        summary["files"] = (["report.md", "report.json", "curves.json"]
                            + [f"{k}_model.json" for k in summary["examples"]]
                            + summary["figures"])
        summary["wall_time"] = time.perf_counter() - t0
        summary = json_safe(summary)
        atomic_write_text(os.path.join(tmp, "curves.json"),
                          json.dumps(json_safe(_curves_json(_curves(run))),
                                     allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), render_reproduction(summary))
    log.info("report written to %s in %.0f s", path, summary["wall_time"])
    return summary
