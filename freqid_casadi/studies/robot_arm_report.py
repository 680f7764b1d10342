"""The DaISy flexible robot arm, the report: report.md, report.json, frf.csv and figures.

:func:`write_robot_arm_report` runs :func:`freqid_casadi.studies.robot_arm.run_robot_arm` and
writes the folder atomically: ``report.md`` (first line: the command), ``report.json``
(every number), ``frf.csv`` (the estimate of G) and the figures ``bode.png``,
``rel_error.png``, ``error_vs_order.png``, ``pole_zero.png`` and ``uncertainty_weight.png``.
"""

import json
import os

import numpy as np

from .. import plots
from ..io.loaders import save_csv
from ..report.environment import computed_on_lines, environment
from ..report.formatting import generated_by_line, json_safe, markdown_table, number
from ..report.folder import atomic_write_text, check_out_dir, report_folder
from .robot_arm import CITATION, CRITERION, WITHIN, low_frequency, run_robot_arm

__all__ = ["write_robot_arm_report", "render_robot_arm"]


def _why(study):
    """Why the chosen order: a sentence from the numbers."""
    rows, pick, best, res = study.rows, study.chosen, study.best, study.model
    est, data = study.estimate, study.data
    smaller = [r for r in rows if r["n_sections"] < pick["n_sections"]]
    why = (f"Every fit with fewer sections has an RMS relative error above "
           f"{WITHIN:g} x {number(best)} = {number(WITHIN * best)} (best of those "
           f"{number(min(r[CRITERION] for r in smaller))}); more sections gain at most "
           f"{number(pick[CRITERION] / best, 3)}x in RMS." if smaller else
           "It is the smallest order tried.")
    i_max = int(np.argmax(res.rel_error))
    why += (f" The max relative error is at omega = {number(data.omega[i_max])} rad/sample "
            f"(bin {int(est.bins[i_max])}), where |G| = "
            f"{number(abs(data.response[i_max]), 3)}: the "
            "antiresonance near 1.12 rad/sample, where the single-period estimate has the "
            "lowest signal-to-noise ratio; a raw fit that reaches a small max there does so "
            "with a zero/pole pair narrower than the bin spacing (see the table), so the "
            "max is not used to choose.")
    return why


def _summary(study, command):
    """report.json (JSON-safe)."""
    est, pick, best, res, weight = (study.estimate, study.chosen, study.best, study.model,
                                    study.weight)
    rows = study.rows
    peaks = est.bins[np.argsort(-np.abs(est.data.response))[:2]]
    summary = {
        "command": command, "citation": CITATION, "environment": environment(),
        "data": {"n_samples": int(est.period * est.n_periods), "n_points": est.data.n_points,
                 "bin_min": int(est.bins[0]), "bin_max": int(est.bins[-1]),
                 "omega_min": float(est.data.omega[0]), "omega_max": float(est.data.omega[-1]),
                 "peak_bins": sorted(int(b) for b in peaks), "frequency_unit": "rad/sample",
                 "spacing": float(np.diff(est.data.omega)[0])},
        "low_frequency": low_frequency(est), "fitted": "-G", "integrator": False,
        "rows": rows, "within": WITHIN, "criterion": CRITERION, "best_rms_rel_error": best,
        "chosen": pick,
        "why": _why(study),
        "chosen_model": res.model.to_dict(),
        "chosen_poles": [[p.real, p.imag] for p in res.model.poles()],
        "chosen_zeros": [[z.real, z.imag] for z in res.model.zeros()],
        "chosen_poles_text": _roots_text(res.model.poles()),
        "chosen_zeros_text": _roots_text(res.model.zeros()),
        "weight": {"order": weight.order, "gain": weight.gain,
                   "overbound_mean_db": weight.overbound.mean_db,
                   "overbound_max_db": weight.overbound.max_db,
                   "overbound_min_db": weight.overbound.min_db,
                   "success": weight.success, "message": weight.message,
                   "poles": [[p.real, p.imag] for p in weight.poles()],
                   "zeros": [[z.real, z.imag] for z in weight.zeros()]},
    }
    return json_safe(summary)


def _figures(folder, study):
    data, results, rows, pick, weight = (study.data, study.results, study.rows, study.chosen,
                                         study.weight)
    res = results[(pick["delay"], pick["n_sections"])]
    label = f"{res.model.n_sections} sections, {'with' if pick['delay'] else 'no'} delay"
    plots.save_figure(plots.bode(data, {label: res.model}, data_label="FRF estimate (-G)",
                                 title="robot arm (DaISy 96-009): data and model",
                                 unit="rad/sample"),
                      os.path.join(folder, "bode.png"))
    others = {f"{n} sections fitted": results[(pick["delay"], n)]
              for n in sorted({r["n_sections"] for r in rows})}
    plots.save_figure(plots.relative_error(others, annotate_max=False, unit="rad/sample",
                                           title="robot arm: relative error "
                                                 f"({'with' if pick['delay'] else 'no'} delay)"),
                      os.path.join(folder, "rel_error.png"))
    plots.save_figure(plots.pole_zero(res.model, title=f"robot arm: poles and zeros ({label})",
                                      unit="rad/sample", zoom="auto"),
                      os.path.join(folder, "pole_zero.png"))
    lines = []
    for delay, marker, ls in ((False, "o", "-"), (True, "s", "--")):
        rr = [r for r in rows if r["delay"] == delay]
        x = [r["n_sections"] for r in rr]
        lines += [dict(x=x, y=[r["max_rel_error"] for r in rr], marker=marker, ls=ls,
                       color=f"C{2 * delay}", label=f"max, {'with' if delay else 'no'} delay"),
                  dict(x=x, y=[r["rms_rel_error"] for r in rr], marker=marker, ls=ls,
                       color=f"C{2 * delay + 1}", alpha=0.5,
                       label=f"RMS, {'with' if delay else 'no'} delay")] if rr else []
    plots.save_figure(plots.line_plot(
        lines, xscale="linear", vlines=[dict(x=pick["n_sections"], color="k", ls=":",
                                             label="chosen")],
        xlabel="sections N (order 2N)", ylabel="relative error",
        title="robot arm: error against order"), os.path.join(folder, "error_vs_order.png"))
    dense = np.logspace(np.log10(data.omega[0]), np.log10(data.omega[-1]), 2000)
    plots.save_figure(plots.line_plot(
        [dict(x=data.omega, y=res.rel_error, marker="o", ms=3, ls="none",
              label="relative error |G/G_N - 1|"),
         dict(x=dense, y=np.abs(weight.frequency_response(dense)),
              label=f"|W|, order {weight.order}")],
        xlabel=r"$\omega$ (rad/sample)", ylabel="magnitude",
        title=f"robot arm: multiplicative uncertainty weight ({label})"),
        os.path.join(folder, "uncertainty_weight.png"))


def render_robot_arm(command, summary):
    """report.md of the robot arm, every number taken from ``summary``.

    Parameters
    ----------
    command : str
        The command line of the run, named on the first line.
    summary : dict
        What report.json holds.

    Returns
    -------
    str
    """
    s = summary
    p = s["chosen"]
    lf = s["low_frequency"]
    lines = [generated_by_line(command), "", "# Flexible robot arm (DaISy 96-009)", "",
             *computed_on_lines(s.get("environment")),
             f"Data: {CITATION} Input: measured reaction torque; output: arm acceleration; "
             f"{s['data']['n_samples']} samples, one period, sampling time not given, so "
             "frequencies are normalised (rad/sample) and the delay is in samples.", "",
             "## Frequency-response estimate", "",
             f"{s['data']['n_points']} odd DFT bins ({s['data']['bin_min']}..{s['data']['bin_max']}"
             f"), omega {number(s['data']['omega_min'])} to {number(s['data']['omega_max'])} "
             "rad/sample, one period (no variance or coherence). Largest |G| at bins "
             f"{', '.join(str(b) for b in s['data']['peak_bins'])} (the resonances).", "",
             "## Structure", "",
             f"- **No integrator.** Over the first {len(lf['bins'])} bins |G| goes from "
             f"{number(lf['magnitude'][0])} to {number(lf['magnitude'][-1])} (ratio "
             f"{number(lf['magnitude_ratio_last_first'], 3)}) while omega grows "
             f"{number(lf['omega_ratio_last_first'], 3)}x: flat, not the 1/omega of an integrator.",
             f"- **Sign.** The phase there is {lf['phase_deg'][0]:.1f} to "
             f"{lf['phase_deg'][-1]:.1f} degrees: a negative static gain. The model class has "
             "K >= 0 (phase 0 at DC), so -G is fitted; the model of G is -G_N.",
             "- **Delay.** Fitted with and without a delay; see the table.", "",
             "## Fits against order", ""]
    lines += ["Each fit is checked with `validation.check_resolution`: a section whose pole "
              "and zero nearly cancel and are narrower than the bin spacing "
              f"({number(s['data']['spacing'])} rad/sample) is a feature between the bins that "
              "the data does not support; `validation.prune_sections` removes it and refits "
              "the rest. 'raw' is the plain fit, the other columns the safeguarded model.",
              ""]
    rows = [("yes" if r["delay"] else "no", r["n_sections"], f"{number(r['raw_max_rel_error'])}",
             "; ".join(r["removed_text"]) or "none",
             r["n_sections_kept"], f"{number(r['max_rel_error'])}", f"{number(r['rms_rel_error'])}",
             f"{number(r['max_dense_change'], 3)}", f"{number(r['delay_estimate'])}",
             "yes" if r["success"] else "no", f"{r['wall_time']:.1f}") for r in s["rows"]]
    lines += [markdown_table(rows, ("delay", "sections fitted", "raw max rel. error",
                                    "removed zero/pole pairs", "sections kept", "max rel. error",
                                    "RMS rel. error", "max change between bins",
                                    "delay (samples)", "converged", "time (s)"),
                             "lrrlrrrrrlr"), ""]
    lines += ["## Chosen model", "",
              f"Rule: the smallest number of sections whose RMS relative error (after the "
              f"safeguard) is within {s['within']:g}x the best over all fits "
              f"({number(s['best_rms_rel_error'])}); no delay preferred on a tie.", "",
              f"**Chosen: {p['n_sections']} sections fitted, {p['n_sections_kept']} kept "
              f"(order {2 * p['n_sections_kept']}), "
              f"{'with' if p['delay'] else 'no'} delay**: max relative error "
              f"{number(p['max_rel_error'])}, RMS {number(p['rms_rel_error'])}, stable "
              f"{'yes' if p['stable'] else 'NO'}, minimum phase "
              f"{'yes' if p['minimum_phase'] else 'NO'}. {s['why']}", "",
              f"Poles (rad/sample): {', '.join(s['chosen_poles_text'])}.", "",
              f"Zeros (rad/sample): {', '.join(s['chosen_zeros_text'])}.", "",
              "## Multiplicative uncertainty weight", "",
              f"W of order {s['weight']['order']} with |W(j w_i)| >= e_i at every bin "
              "(fit_uncertainty_weight): overbound mean "
              f"{number(s['weight']['overbound_mean_db'], 3)} "
              f"dB, max {number(s['weight']['overbound_max_db'], 3)} dB, min "
              f"{number(s['weight']['overbound_min_db'], 3)} dB, IPOPT "
              f"{'converged' if s['weight']['success'] else 'did NOT converge'}.", "",
              "## Figures", "",
              "![Bode plot of data and model](bode.png)", "",
              "![Relative error against frequency](rel_error.png)", "",
              "![Error against order](error_vs_order.png)", "",
              "![Poles and zeros](pole_zero.png)", "",
              "![Relative error and uncertainty weight](uncertainty_weight.png)", "",
              "`report.json` holds every number above at full precision; `frf.csv` the "
              "estimate (omega, real, imag of G, not -G).", ""]
    return "\n".join(lines)


def _roots_text(roots):
    return [f"{number(r.real)}{r.imag:+.4g}j" for r in roots] or ["none"]


def write_robot_arm_report(out_dir, *, command, orders=(1, 2, 3, 4, 5), force=False,
                           path=None, delays=(False, True), progress=None):
    """Run the robot-arm study and write its report folder.

    Parameters
    ----------
    out_dir : str or os.PathLike
        The report folder (new unless ``force``; in an existing parent).
    command : str
        The command line of the run, named on report.md's first line.
    orders : sequence of int
        Numbers of sections to fit.
    force : bool
        Replace an existing ``out_dir`` (only after the new report is complete).
    path, delays, progress
        As in :func:`~freqid_casadi.studies.robot_arm.run_robot_arm`.

    Returns
    -------
    dict
        Everything report.json holds.

    Raises
    ------
    OptionError
        If ``out_dir`` exists and ``force`` is false, or its parent does not exist.
    """
    check_out_dir(out_dir, force)                 # early: before the long study
    study = run_robot_arm(orders, path=path, delays=delays, progress=progress)
    summary = _summary(study, command)
    with report_folder(out_dir, force) as (tmp, _):
        save_csv(study.estimate.data, os.path.join(tmp, "frf.csv"))
        _figures(tmp, study)
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), render_robot_arm(command, summary))
    return summary
