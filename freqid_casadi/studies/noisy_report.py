"""Example A on noisy data, the report: report.md, report.json and two figures.

:func:`write_noisy_report` runs :func:`freqid_casadi.studies.noisy.run_noisy` and writes
the folder atomically: ``report.md`` (first line: the command), ``report.json`` (every
number) and ``clean_error.png``, ``weights.png``.
"""

import json
import os

from .. import plots
from ..report.environment import computed_on_lines, environment
from ..report.formatting import generated_by_line, json_safe, markdown_table, number
from ..report.folder import atomic_write_text, check_out_dir, report_folder
from .noisy import DENSE, NOISE, SEED, SIGMA_RANGE, run_noisy

__all__ = ["write_noisy_report", "render_noisy", "weights_effect"]


def _row(label, st, key):
    c = st[key]
    return (label, f"{number(c['samples']['max'])}", f"{number(c['samples']['rms'])}",
            f"{number(c['dense']['max'])}", f"{number(c['dense']['rms'])}")


_HEAD = ("", "max at samples", "RMS at samples", "max on dense grid", "RMS on dense grid")


def render_noisy(command, s):
    """The Markdown text of report.md.

    Parameters
    ----------
    command : str
        The command that made the report (first line).
    s : dict
        The content of report.json.

    Returns
    -------
    str
    """
    a = s["noisy"]
    f = a["floor"]
    head = _HEAD
    lines = [generated_by_line(command), "", "# Example A on noisy data", "",
             *computed_on_lines(s.get("environment")),
             f"G_A on the thesis grid ({s['n_points']} points, 1e-2..1e3 rad/s) times "
             f"(1 + n), n complex Gaussian with RMS {100 * NOISE:g} % (seed {SEED}; measured "
             f"RMS {number(s['noise_rms'])}, max |n| {number(s['noise_max'])}). Fit: "
             f"{a['n_sections']} "
             "sections, integrator, delay (the thesis's order). Errors are against the "
             f"*clean* G_A at the data points and on a {DENSE}x denser log grid "
             f"({s['n_dense']} points).", "",
             "## Plain fit and the safeguard", "",
             "The plain fit's final stage converged: "
             + ("yes" if a["success"] else "no (iteration limit; the best point is kept)")
             + "; its error "
             f"against the noisy data: max {number(a['fit_max_rel_error_vs_noisy'])}, RMS "
             f"{number(a['fit_rms_rel_error_vs_noisy'])}. `validation.check_resolution` flags "
             f"{a['n_flagged_pairs']} zero/pole pairs that nearly cancel and are narrower than "
             f"the grid spacing (smallest damping ratio {number(a['min_zeta_flagged'], 2)}):", ""]
    lines += [f"- {t}" for t in a["flagged_text"]] + [""]
    lines += [f"`validation.prune_sections` removes them and refits the rest on the data: "
              f"{a['n_sections']} -> {a['n_sections_after']} sections, resolved after: "
              f"{'yes' if a['resolved_after'] else 'NO'}; error against the noisy data "
              f"max {number(a['after_max_rel_error_vs_noisy'])}, RMS "
              f"{number(a['after_rms_rel_error_vs_noisy'])}.", "",
              markdown_table([_row("plain fit", a, "clean_before"),
                              _row(f"pruned ({a['n_sections_after']} sections)", a,
                                   "clean_after"),
                              _row(f"damping floor ({f['n_sections']} sections)", f, "clean")],
                             head, "lrrrr"), "",
              f"Before the safeguard the model is close to the clean system at the samples "
              f"but not between them (dense max {number(a['clean_before']['dense']['max'], 3)} vs "
              f"{number(a['clean_before']['samples']['max'], 3)} at the samples). After it the "
              "error against the clean system is, at the samples, RMS "
              f"{number(a['clean_after']['samples']['rms'], 3)} and max "
              f"{number(a['clean_after']['samples']['max'], 3)}, and on the dense grid RMS "
              f"{number(a['clean_after']['dense']['rms'], 3)} and max "
              f"{number(a['clean_after']['dense']['max'], 3)}: the RMS is "
              + ("below" if max(a['clean_after']['samples']['rms'],
                                a['clean_after']['dense']['rms']) < s['noise_rms'] else "ABOVE")
              + f" the noise RMS {number(s['noise_rms'], 3)} and the max "
              + ("below" if max(a['clean_after']['samples']['max'],
                                a['clean_after']['dense']['max']) < s['noise_max'] else "ABOVE")
              + f" the largest noise sample {number(s['noise_max'], 3)}, at and between the "
                "samples.",
              ""]
    lines += _floor_lines(s)
    lines += _weights_lines(s)
    lines += ["`report.json` holds every number above at full precision.", ""]
    return "\n".join(lines)


def _floor_lines(s):
    a, f = s["noisy"], s["noisy"]["floor"]
    return [
        "### At the thesis's order: the damping floor", "",
        f"`fit(..., min_damping=\"auto\")` (CLI `--min-damping auto`) keeps all "
        f"{f['n_sections']} sections and bounds the damping ratio of every pole and zero "
        f"by the frequency resolution, zeta >= {number(f['zeta_min'])} (half the relative "
        "spacing: no pole or zero narrower than the spacing), as constraints of every "
        "stage NLP. A near-cancelling pair can then no longer fit the noise at one "
        "sample and hide between samples. Its final stage converged: "
        + ("yes" if f["success"] else "no") + "; resolution check: "
        + ("passed" if f["resolution_ok"] else
           f"FAILED ({f['n_flagged_pairs']} pairs)")
        + f". Against the clean system: at the samples RMS "
        f"{number(f['clean']['samples']['rms'], 3)}, max "
        f"{number(f['clean']['samples']['max'], 3)}; "
        f"on the dense grid RMS {number(f['clean']['dense']['rms'], 3)}, max "
        f"{number(f['clean']['dense']['max'], 3)} (plain fit: "
        f"{number(a['clean_before']['dense']['max'], 3)}). The RMS is "
        + ("below" if max(f['clean']['samples']['rms'], f['clean']['dense']['rms'])
           < s['noise_rms'] else "ABOVE")
        + f" the noise RMS {number(s['noise_rms'], 3)} and the max "
        + ("below" if max(f['clean']['samples']['max'], f['clean']['dense']['max'])
           < s['noise_max'] else "ABOVE")
        + f" the largest noise sample {number(s['noise_max'], 3)}, at and between the samples; "
        "the max is "
        + ("below" if max(f['clean']['samples']['max'], f['clean']['dense']['max'])
           < s['noise_rms'] else "above")
        + f" the noise RMS. Pruning to {a['n_sections_after']} sections gives the lower "
        "max; the floor keeps the requested order. The floor's price on clean data "
        f"(example A, {f['n_sections']} sections): max relative error "
        f"{number(s['clean_fit']['floor'], 2)} instead of {number(s['clean_fit']['plain'], 2)}, "
        "because A's lightest modes are narrower than this grid's spacing.", "",
        "![Error against the clean system](clean_error.png)", "",]


def _weights_lines(s):
    u, w = s["uniform"], s["weighted"]
    head = _HEAD
    return [
        "## Weighted fitting", "",
        f"Noise RMS sigma(omega) growing log-linearly from {100 * SIGMA_RANGE[0]:g} % at "
        f"1e-2 rad/s to {100 * SIGMA_RANGE[1]:g} % at 1e3 rad/s "
        "(seed 1). Uniform weights against w_i = 1/sigma_i^2 (the inverse relative "
        "variance, what `experiment.frf_from_periodic` puts in `data.weights`), "
        "normalised to mean 1; each fitted plain, pruned, and with the damping floor "
        f"(plain fits: flagged pairs uniform {u['n_flagged_pairs']}, weighted "
        f"{w['n_flagged_pairs']}; poles/zeros over 100x narrower than the spacing: "
        f"uniform {u['n_unresolved']}, weighted {w['n_unresolved']}).", "",
        markdown_table([_row("uniform, plain", u, "clean_before"),
                        _row(f"uniform, pruned ({u['n_sections_after']} sections)", u,
                             "clean_after"),
                        _row("uniform, damping floor", u["floor"], "clean"),
                        _row("1/sigma^2, plain", w, "clean_before"),
                        _row(f"1/sigma^2, pruned ({w['n_sections_after']} sections)", w,
                             "clean_after"),
                        _row("1/sigma^2, damping floor", w["floor"], "clean")],
                       head, "lrrrr"), "",
        s["weights_effect"], "",
        "![Uniform against variance weights](weights.png)", "",]


def weights_effect(n_sections, s):
    """The sentence on the weighted fits (``weights_effect`` of report.json).

    Parameters
    ----------
    n_sections : int
        Sections of the fits.
    s : dict
        :attr:`NoisyStudy.summary <freqid_casadi.studies.noisy.NoisyStudy>`.

    Returns
    -------
    str
    """
    effect, uni, wtd = s["weighted_study"], s["uniform"], s["weighted"]
    better_lo = effect["weighted_rms_below_1rad"] < effect["uniform_rms_below_1rad"]
    better_hi = effect["weighted_rms_above_100rad"] < effect["uniform_rms_above_100rad"]
    uf, wf = uni["floor"]["clean"], wtd["floor"]["clean"]
    text = (f"Effect (damping-floor fits, {n_sections} sections, clean error at the samples): "
            f"below 1 rad/s, where the data is precise, RMS "
            f"{number(effect['uniform_rms_below_1rad'], 3)} (uniform) vs "
            f"{number(effect['weighted_rms_below_1rad'], 3)} (1/sigma^2); above 100 rad/s, "
            "where it "
            f"is noisy, {number(effect['uniform_rms_above_100rad'], 3)} vs "
            f"{number(effect['weighted_rms_above_100rad'], 3)}. Over all samples RMS "
            f"{number(uf['samples']['rms'], 3)} vs {number(wf['samples']['rms'], 3)} (max "
            f"{number(uf['samples']['max'], 3)} vs {number(wf['samples']['max'], 3)}), on the "
            "dense grid "
            f"RMS {number(uf['dense']['rms'], 3)} vs {number(wf['dense']['rms'], 3)}. "
            + ("The variance weights give the lower error in both bands: with uniform "
               "weights the noisy high-frequency points dominate the cost, with 1/sigma^2 the "
               "precise points count most and the noisy ones no more than their noise allows."
               if better_lo and better_hi else
               "The variance weights are better "
               + ("below 1 rad/s" if better_lo else "above 100 rad/s" if better_hi else
                  "in neither band") + " only on this realisation."))
    return text


# ----------------------------------------------------------------------------- figures

_OMEGA = r"$\omega$ (rad/s)"
_CLEAN = r"$|G_A/G_N - 1|$ (clean system)"


def _clean_figure(c, n_sections):
    lines = []
    for key, color, label in (("before", "C3", "plain fit"), ("after", "C0", "pruned"),
                              ("floor", "C2", "damping floor")):
        if c[key] is None:
            continue
        dense_label = (f"damping floor ({n_sections} sections), dense grid" if key == "floor"
                       else f"{label}, dense grid")
        lines += [dict(x=c["dense"], y=c[key][1], color=color, lw=0.8, label=dense_label),
                  dict(x=c["omega"], y=c[key][0], color=color, marker="o", ms=2.5, ls="none",
                       label=f"{label}, samples")]
    return plots.line_plot(
        lines, hlines=[dict(y=NOISE, color="k", ls=":", label=f"noise RMS {100 * NOISE:g} %")],
        xlabel=_OMEGA, ylabel=_CLEAN, ylim=(1e-5, None), figsize=(7.5, 4.8),
        title=f"example A + {100 * NOISE:g} % noise, {n_sections} sections: error against "
              "the clean system")


def _weights_figure(c):
    lines = [dict(x=c["dense"], y=c["uniform"][1], color="C1", lw=0.8,
                  label="uniform weights (dense grid)"),
             dict(x=c["dense"], y=c["weighted"][1], color="C2", lw=0.8,
                  label=r"weights $1/\sigma^2$ (dense grid)"),
             dict(x=c["omega"], y=c["sigma"], color="k", ls=":",
                  label=r"noise RMS $\sigma(\omega)$")]
    return plots.line_plot(
        lines, xlabel=_OMEGA, ylabel=_CLEAN, ylim=(1e-5, None), figsize=(7.5, 4.8),
        title="frequency-dependent noise: uniform against variance weights (damping floor)")


# ----------------------------------------------------------------------------- writer


def write_noisy_report(out_dir, *, command, n_sections=17, force=False):
    """Run the noisy-data study and write its report folder.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Folder to create; its parent must exist.
    command : str
        The command that made the report (first line of report.md).
    n_sections : int
        Sections of every fit (default: the thesis's 17).
    force : bool
        Replace an existing ``out_dir`` (only after the new report is complete).

    Returns
    -------
    dict
        Every number of the report, as written to report.json.

    Raises
    ------
    OptionError
        If ``out_dir`` exists and ``force`` is false, or its parent does not exist.
    """
    check_out_dir(out_dir, force)                 # early: before the long study
    result = run_noisy(n_sections)
    summary = json_safe({"command": command, **result.summary, "environment": environment(),
                         "weights_effect": weights_effect(n_sections, result.summary)})
    with report_folder(out_dir, force) as (tmp, _):
        plots.save_figure(_clean_figure(result.curves, n_sections),
                          os.path.join(tmp, "clean_error.png"))
        plots.save_figure(_weights_figure(result.curves), os.path.join(tmp, "weights.png"))
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), render_noisy(command, summary))
    return summary
