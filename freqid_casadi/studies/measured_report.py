"""Measured data end to end, the report: report.md, report.json and figures.

:func:`write_measured_report` runs :func:`freqid_casadi.studies.measured.run_measured` and
writes the folder atomically: ``report.md`` (first line: the command), ``report.json`` (every
number), ``actuator_frf.png`` (H1 and its coherence), ``actuator_bode.png``,
``actuator_rel_error.png``, ``robot_arm_bode.png`` and ``robot_arm_rel_error.png``.
"""

import json
import os

import numpy as np

from .. import plots
from ..report.environment import computed_on_lines, environment
from ..report.formatting import generated_by_line, json_safe, markdown_table, number
from ..core.metrics import relative_error
from ..report.folder import atomic_write_text, check_out_dir, report_folder
from .measured import DELAY_UNITS, run_measured

__all__ = ["write_measured_report", "render_measured"]

_LABEL = {"freqid": "freqid (ours)", "skrf-vector-fitting": "scikit-rf vector fitting",
          "aaa": "scipy AAA"}


def _yes(v):
    return "—" if v is None else ("yes" if v else "NO")


_UNITS = DELAY_UNITS


def _std(r):
    """The delay's std of a row (None in JSON for a NaN: no delay, or at a bound)."""
    v = r.get("delay_std")
    return float("nan") if v is None else v


def _table(ds_rows, scale, unit):
    rows = []
    for r in ds_rows:
        if "error" in r:
            rows.append((_LABEL[r["method"]], r["order"], "failed: " + r["error"][:60],
                         "", "", "", "", "", ""))
            continue
        delay = (f"{number(r['delay'] * scale, 4)} ± {number(_std(r) * scale, 2)}"
                 if r["method"] == "freqid" else "—")
        diags = ", ".join(d["code"] for d in r.get("diagnostics", ())) or "—"
        rows.append((_LABEL[r["method"]], r["order"], number(r["max_rel_error"]),
                     number(r["rms_rel_error"]), delay, _yes(r["stable"]),
                     _yes(r["minimum_phase"]), _yes(r["success"]), diags))
    return markdown_table(rows, ("method", "order", "max rel. error", "RMS rel. error",
                                 f"delay ± std ({unit})", "stable", "min. phase", "converged",
                                 "diagnostics"), "lrrrrllll")


def _best_peer(ds, n):
    peers = [r for r in ds.rows if r["n_sections"] == n and r["method"] != "freqid"
             and "error" not in r]
    return min(peers, key=lambda r: r["max_rel_error"]) if peers else None


def _conclusions(ds):
    """Sentences computed from the rows."""
    scale, unit = _UNITS[ds.name]
    out = []
    ours = [r for r in ds.rows if r["method"] == "freqid"]
    for r in ours:
        peer = _best_peer(ds, r["n_sections"])
        cmp = (f"; best peer {_LABEL[peer['method']]} {number(peer['max_rel_error'])} "
               f"({'lower' if peer['max_rel_error'] < r['max_rel_error'] else 'higher'}, "
               f"{'stable' if peer['stable'] else 'UNSTABLE'}, "
               f"{'minimum phase' if peer['minimum_phase'] else 'not minimum phase'})"
               if peer else "")
        out.append(f"{r['n_sections']} section(s) (order {r['order']}): max relative error "
                   f"{number(r['max_rel_error'])}, RMS {number(r['rms_rel_error'])}, delay "
                   f"{number(r['delay'] * scale, 4)} ± {number(_std(r) * scale, 2)} "
                   f"{unit}, {'converged' if r['success'] else 'NOT converged'}{cmp}.")
        for d in r.get("diagnostics", ()):
            out.append(f"  {r['n_sections']} section(s), {d['code']}: {d['message']}")
    determined = [r for r in ours if _delay_determined(r)]
    rule = ("(converged, std <= half the delay, no delay-undetermined or "
            "no-better-than-trivial diagnostic)")
    if len(determined) >= 2:
        d = [r["delay"] * scale for r in determined]
        out.append(f"Delays the data determine {rule}: "
                   + ", ".join(f"{r['n_sections']} section(s) {number(r['delay'] * scale, 4)}"
                               for r in determined)
                   + f" {unit}; spread {number(max(d) - min(d), 3)} {unit}.")
    elif determined:
        r = determined[0]
        out.append(f"Only the {r['n_sections']}-section fit determines the delay {rule}: "
                   f"{number(r['delay'] * scale, 4)} {unit}.")
    elif ours:
        out.append(f"The data determine the delay at none of these orders {rule}.")
    return out


def _delay_determined(row):
    """True if the fit of ``row`` converged, its delay's std is at most half the delay and
    no diagnostic says the delay is undetermined or the fit explains nothing."""
    codes = {d["code"] for d in row.get("diagnostics", ())}
    return (bool(row["success"]) and np.isfinite(_std(row)) and row["delay"] > 0
            and _std(row) <= 0.5 * row["delay"]
            and not codes & {"delay-undetermined", "no-better-than-trivial"})


def render_measured(summary):
    """report.md from the JSON-ready summary.

    Parameters
    ----------
    summary : dict
        As written to report.json.

    Returns
    -------
    str
    """
    lines = [generated_by_line(summary["command"]), "",
             "# Measured data: the actuator from raw records, and the robot arm", "",
             *computed_on_lines(summary.get("environment")),
             f"Command: `{summary['command']}` ({number(summary['wall_time'])} s). Ours: "
             "`fit(data, n_sections=N, delay=True, start='best')` (stable by construction, "
             "minimum phase, a delay, the gain sign found from the data); peers at the same "
             "order: scikit-rf's vector fitting and scipy's AAA (neither is constrained to "
             "be stable or minimum phase; both minimise the absolute error, so where |G| is "
             "small, at antiresonances, their relative error is large). Max and RMS of "
             "|Phi/G_N - 1| over the data; delay "
             "± one standard deviation from the parameter covariance "
             "(`FitResult.uncertainty`).", ""]
    for key, title in (("actuator", "Servo-hydraulic actuator (chirp, raw records)"),
                       ("robot_arm", "DaISy flexible robot arm (96-009)")):
        ds = summary[key]
        lines += [f"## {title}", ""] + [f"{n}" for n in ds["notes"]] + [""]
        if key == "actuator":
            lines += ["![H1 and coherence](actuator_frf.png)", ""]
        lines += [_table_from(ds), "", "Conclusions (computed from the numbers):", ""]
        lines += [f"- {c}" if not c.startswith("  ") else f"  - {c.strip()}"
                  for c in ds["conclusions"]]
        lines += ["", f"![Bode]({key}_bode.png)", "", f"![Relative error]({key}_rel_error.png)",
                  ""]
    lines += ["Data: actuator chirp test, MIT license, github.com/DanielMaurelE/"
              "vRTHS_AMBC_MRdamper (`freqid_casadi/datasets/actuator/SOURCE.md`); B. De Moor "
              "et al., DaISy: Database for the Identification of Systems, data set 96-009.", ""]
    return "\n".join(lines)


def _table_from(ds_summary):
    return _table(ds_summary["rows"], *_UNITS[ds_summary["name"]])


def _figures(folder, study):
    est = study.actuator.estimate
    f = est.data.omega / (2 * np.pi)
    fig = plots.line_plot(
        [{"x": f, "y": np.abs(est.data.response), "label": "|H1|"},
         {"x": f, "y": est.coherence, "label": "coherence", "ls": "--"}],
        xlabel="frequency (Hz)", ylabel="|H1| (mm/mm), coherence", yscale="linear",
        title="Actuator: H1 from the raw chirp records (Welch)")
    plots.save_figure(fig, os.path.join(folder, "actuator_frf.png"))
    for key, ds in (("actuator", study.actuator), ("robot_arm", study.robot_arm)):
        w = ds.data.omega
        responses, errors = {}, []
        for (method, n), model in ds.models.items():
            if model is None:
                continue
            m = getattr(model, "model", model)
            label = f"{_LABEL[method]}, order {2 * n}"
            g = m.frequency_response(w)
            if method == "freqid" or n == max(r["n_sections"] for r in ds.rows):
                responses[label] = g
            errors.append({"x": w, "y": relative_error(m, ds.data).values, "label": label,
                           "lw": 1.6 if method == "freqid" else 0.9,
                           "ls": "-" if method == "freqid" else ":"})
        xlabel = (r"frequency $\omega$ (rad/s)" if key == "actuator" else
                  r"normalised frequency $\omega$ (rad/sample)")
        fig = plots.bode_curves(w, responses, reference=("data", ds.data.response),
                                title=f"{ds.name}: data and models", xlabel=xlabel)
        plots.save_figure(fig, os.path.join(folder, f"{key}_bode.png"))
        fig = plots.line_plot(errors, xlabel=xlabel, ylabel="|Phi/G_N - 1|",
                              title=f"{ds.name}: relative error", legend_fontsize="x-small")
        plots.save_figure(fig, os.path.join(folder, f"{key}_rel_error.png"))


def _ds_summary(ds):
    return {"name": ds.name, "notes": list(ds.notes), "rows": list(ds.rows),
            "n_points": ds.data.n_points, "omega_min": float(ds.data.omega[0]),
            "omega_max": float(ds.data.omega[-1]),
            "conclusions": _conclusions(ds),
            "models": {f"{m}:{n}": (getattr(v, "model", v).to_dict()
                                    if m == "freqid" else None)
                       for (m, n), v in ds.models.items()}}


def write_measured_report(out_dir, *, command, force=False, progress=None):
    """Run the measured-data study and write its report folder (atomically).

    Parameters
    ----------
    out_dir : str
        The folder to create (replaced only with ``force`` and only if this package wrote
        it).
    command : str
        The command line, written as the report's first line.
    force : bool
    progress : callable, optional
        Receives one line per fit.

    Returns
    -------
    dict
        The summary written to report.json.
    """
    check_out_dir(out_dir, force)
    study = run_measured(progress)
    summary = json_safe({"command": command, "wall_time": study.wall_time,
                         "environment": environment(),
                         "settings": study.settings,
                         "actuator": _ds_summary(study.actuator),
                         "robot_arm": _ds_summary(study.robot_arm)})
    with report_folder(out_dir, force) as (tmp, _):
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), render_measured(summary))
        _figures(tmp, study)
    return summary
