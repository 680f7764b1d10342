"""Example A on noisy data: error against the clean system at and between the samples.

Usage::

    python scripts/noisy_example.py [--sections 17] [--out results/noisy] [--force]

1. G_A on the thesis's grid (500 points) times ``1 + n_i``, ``n_i`` complex Gaussian with
   RMS 2 % (seed 0); fit at the thesis's order (17 sections, integrator, delay).
2. Error against the *clean* G_A at the data points and on a 10x denser log grid, before
   and after the safeguard :func:`freqid_casadi.validation.prune_sections` (removes zero/
   pole pairs that nearly cancel and are narrower than the frequency spacing, then refits),
   and of the fit at the same order with the damping floor ``min_damping="auto"`` (no pole
   or zero narrower than the spacing, imposed in every stage NLP).
3. Weighted fitting: noise whose RMS grows from 0.5 % (low frequency) to 8 % (high
   frequency), fitted with uniform weights and with ``w_i = 1 / sigma_i^2`` (relative
   variance, normalised to mean 1), plain, pruned and with the damping floor.

Writes the folder ``--out`` atomically: ``report.md`` (first line: the command),
``report.json`` (every number) and ``clean_error.png``, ``weights.png``.
"""

import argparse
import json
import os
import shlex
import sys

import numpy as np

from freqid_casadi import plots, systems
from freqid_casadi._io import atomic_write_text
from freqid_casadi.data import FrequencyData
from freqid_casadi.fit import fit
from freqid_casadi.report import (_clean, check_out_dir, report_folder,
                                  generated_by_line, markdown_table)
from freqid_casadi.validation import check_resolution, dense_grid, prune_sections

SEED = 0
NOISE = 0.02
SIGMA_RANGE = (0.005, 0.08)
DENSE = 10


def noisy_data(sigma, seed=SEED, name=None):
    """G_A on the thesis grid times (1 + n), n complex Gaussian with RMS ``sigma`` (scalar
    or per point): ``E|n_i|^2 = sigma_i^2``."""
    clean = systems.G_A()
    rng = np.random.default_rng(seed)
    m = clean.n_points
    n = (rng.standard_normal(m) + 1j * rng.standard_normal(m)) / np.sqrt(2)
    return clean, FrequencyData(clean.omega, clean.response * (1 + sigma * n),
                                name or f"G_A + {100 * NOISE:g} % noise")


def clean_errors(model, clean, dense):
    """Relative errors |G_A / G_N - 1| at the samples and on the dense grid."""
    ref = systems.G_A(omega=dense).response
    e_s = np.abs(clean.response / model.frequency_response(clean.omega) - 1)
    e_d = np.abs(ref / model.frequency_response(dense) - 1)
    return e_s, e_d


def _stats(e):
    return {"max": float(np.max(e)), "rms": float(np.sqrt(np.mean(e ** 2)))}


def study(data, clean, dense, n_sections, weights=None, floor=False):
    """Fit, errors against the clean system before/after the safeguard (pruning), and,
    with ``floor``, of the fit with the damping floor ``min_damping="auto"``."""
    res = fit(data, n_sections=n_sections, integrator=True, delay=True, weights=weights)
    check = check_resolution(res, data.omega)
    pr = prune_sections(res, reference=lambda w: systems.G_A(omega=w), dense_factor=DENSE)
    before = clean_errors(res.model, clean, dense)
    after = clean_errors(pr.model, clean, dense)
    out = {
        "n_sections": n_sections, "wall_time": res.wall_time, "success": res.success,
        "fit_max_rel_error_vs_noisy": res.max_rel_error,
        "fit_rms_rel_error_vs_noisy": res.rms_rel_error,
        "n_flagged_pairs": len(check.flags),
        "flagged": [f.as_dict() for f in check.flags],
        "flagged_text": [f.text() for f in check.flags],
        "min_zeta_flagged": min([min(f.zero.zeta, f.pole.zeta) for f in check.flags],
                                default=None),
        "n_unresolved": len(check.unresolved),
        "unresolved_text": [f"{q.kind} {q.omega:.4g} rad/s zeta {q.zeta:.2g}"
                            for q in check.unresolved],
        "n_sections_after": pr.model.n_sections, "resolved_after": pr.check.ok,
        "refit_success": pr.refit_success,
        "after_max_rel_error_vs_noisy": pr.max_rel_error_after,
        "after_rms_rel_error_vs_noisy": pr.rms_rel_error_after,
        "clean_before": {"samples": _stats(before[0]), "dense": _stats(before[1])},
        "clean_after": {"samples": _stats(after[0]), "dense": _stats(after[1])},
        "max_dense_change": pr.max_dense_change,
    }
    if floor:
        rf = fit(data, n_sections=n_sections, integrator=True, delay=True, weights=weights,
                 min_damping="auto")
        fe = clean_errors(rf.model, clean, dense)
        out["floor"] = {
            "n_sections": rf.model.n_sections, "zeta_min": rf.zeta_min,
            "wall_time": rf.wall_time, "success": rf.success,
            "resolution_ok": rf.resolution.ok, "n_flagged_pairs": len(rf.resolution.flags),
            "fit_max_rel_error_vs_noisy": rf.max_rel_error,
            "fit_rms_rel_error_vs_noisy": rf.rms_rel_error,
            "clean": {"samples": _stats(fe[0]), "dense": _stats(fe[1])},
            "model": rf.model.to_dict()}
        out["_floor_errors"] = fe
    return out, res, pr, before, after


def _figure_clean(folder, clean, dense, before, after, floor=None):
    plt = plots._pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.8), layout="constrained")
    ax.loglog(dense, before[1], "-", color="C3", lw=0.8, label="plain fit, dense grid")
    ax.loglog(clean.omega, before[0], "o", color="C3", ms=2.5, label="plain fit, samples")
    ax.loglog(dense, after[1], "-", color="C0", lw=0.8, label="pruned, dense grid")
    ax.loglog(clean.omega, after[0], "o", color="C0", ms=2.5, label="pruned, samples")
    if floor is not None:
        ax.loglog(dense, floor[1], "-", color="C2", lw=0.8,
                  label="damping floor (17 sections), dense grid")
        ax.loglog(clean.omega, floor[0], "o", color="C2", ms=2.5,
                  label="damping floor, samples")
    ax.axhline(NOISE, color="k", ls=":", label=f"noise RMS {100 * NOISE:g} %")
    ax.set_xlabel(r"$\omega$ (rad/s)")
    ax.set_ylabel(r"$|G_A/G_N - 1|$ (clean system)")
    ax.set_ylim(1e-5, None)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", ncol=2)
    ax.set_title("example A + 2 % noise, 17 sections: error against the clean system")
    plots.save_figure(fig, os.path.join(folder, "clean_error.png"))


def _figure_weights(folder, clean, dense, sigma, uni, wtd):
    plt = plots._pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.8), layout="constrained")
    ax.loglog(dense, uni[1], "-", color="C1", lw=0.8, label="uniform weights (dense grid)")
    ax.loglog(dense, wtd[1], "-", color="C2", lw=0.8,
              label=r"weights $1/\sigma^2$ (dense grid)")
    ax.loglog(clean.omega, sigma, "k:", label=r"noise RMS $\sigma(\omega)$")
    ax.set_xlabel(r"$\omega$ (rad/s)")
    ax.set_ylabel(r"$|G_A/G_N - 1|$ (clean system)")
    ax.set_ylim(1e-5, None)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title("frequency-dependent noise: uniform against variance weights (damping floor)")
    plots.save_figure(fig, os.path.join(folder, "weights.png"))


def _row(label, st, key):
    c = st[key]
    return (label, f"{c['samples']['max']:.4g}", f"{c['samples']['rms']:.4g}",
            f"{c['dense']['max']:.4g}", f"{c['dense']['rms']:.4g}")


def _markdown(command, s):
    a = s["noisy"]
    f = a["floor"]
    u, w = s["uniform"], s["weighted"]
    head = ("", "max at samples", "RMS at samples", "max on dense grid", "RMS on dense grid")
    lines = [generated_by_line(command), "", "# Example A on noisy data", "",
             f"G_A on the thesis grid ({s['n_points']} points, 1e-2..1e3 rad/s) times "
             f"(1 + n), n complex Gaussian with RMS {100 * NOISE:g} % (seed {SEED}; measured "
             f"RMS {s['noise_rms']:.4g}, max |n| {s['noise_max']:.4g}). Fit: {a['n_sections']} "
             "sections, integrator, delay (the thesis's order). Errors are against the "
             f"*clean* G_A at the data points and on a {DENSE}x denser log grid "
             f"({s['n_dense']} points).", "",
             "## Plain fit and the safeguard", "",
             "The plain fit's final stage converged: "
             + ("yes" if a["success"] else "no (iteration limit; the best point is kept)")
             + "; its error "
             f"against the noisy data: max {a['fit_max_rel_error_vs_noisy']:.4g}, RMS "
             f"{a['fit_rms_rel_error_vs_noisy']:.4g}. `validation.check_resolution` flags "
             f"{a['n_flagged_pairs']} zero/pole pairs that nearly cancel and are narrower than "
             f"the grid spacing (smallest damping ratio {a['min_zeta_flagged']:.2g}):", ""]
    lines += [f"- {t}" for t in a["flagged_text"]] + [""]
    lines += [f"`validation.prune_sections` removes them and refits the rest on the data: "
              f"{a['n_sections']} -> {a['n_sections_after']} sections, resolved after: "
              f"{'yes' if a['resolved_after'] else 'NO'}; error against the noisy data "
              f"max {a['after_max_rel_error_vs_noisy']:.4g}, RMS "
              f"{a['after_rms_rel_error_vs_noisy']:.4g}.", "",
              markdown_table([_row("plain fit", a, "clean_before"),
                              _row(f"pruned ({a['n_sections_after']} sections)", a,
                                   "clean_after"),
                              _row(f"damping floor ({f['n_sections']} sections)", f, "clean")],
                             head, "lrrrr"), "",
              f"Before the safeguard the model is close to the clean system at the samples "
              f"but not between them (dense max {a['clean_before']['dense']['max']:.3g} vs "
              f"{a['clean_before']['samples']['max']:.3g} at the samples). After it the "
              "error against the clean system is, at the samples, RMS "
              f"{a['clean_after']['samples']['rms']:.3g} and max "
              f"{a['clean_after']['samples']['max']:.3g}, and on the dense grid RMS "
              f"{a['clean_after']['dense']['rms']:.3g} and max "
              f"{a['clean_after']['dense']['max']:.3g}: the RMS is "
              + ("below" if max(a['clean_after']['samples']['rms'],
                                a['clean_after']['dense']['rms']) < s['noise_rms'] else "ABOVE")
              + f" the noise RMS {s['noise_rms']:.3g} and the max "
              + ("below" if max(a['clean_after']['samples']['max'],
                                a['clean_after']['dense']['max']) < s['noise_max'] else "ABOVE")
              + f" the largest noise sample {s['noise_max']:.3g}, at and between the samples.",
              "",
              "### At the thesis's order: the damping floor", "",
              f"`fit(..., min_damping=\"auto\")` (CLI `--min-damping auto`) keeps all "
              f"{f['n_sections']} sections and bounds the damping ratio of every pole and zero "
              f"by the frequency resolution, zeta >= {f['zeta_min']:.4g} (half the relative "
              "spacing: no pole or zero narrower than the spacing), as constraints of every "
              "stage NLP. A near-cancelling pair can then no longer fit the noise at one "
              "sample and hide between samples. Its final stage converged: "
              + ("yes" if f["success"] else "no") + "; resolution check: "
              + ("passed" if f["resolution_ok"] else
                 f"FAILED ({f['n_flagged_pairs']} pairs)")
              + f". Against the clean system: at the samples RMS "
              f"{f['clean']['samples']['rms']:.3g}, max {f['clean']['samples']['max']:.3g}; "
              f"on the dense grid RMS {f['clean']['dense']['rms']:.3g}, max "
              f"{f['clean']['dense']['max']:.3g} (plain fit: "
              f"{a['clean_before']['dense']['max']:.3g}). The RMS is "
              + ("below" if max(f['clean']['samples']['rms'], f['clean']['dense']['rms'])
                 < s['noise_rms'] else "ABOVE")
              + f" the noise RMS {s['noise_rms']:.3g} and the max "
              + ("below" if max(f['clean']['samples']['max'], f['clean']['dense']['max'])
                 < s['noise_max'] else "ABOVE")
              + f" the largest noise sample {s['noise_max']:.3g}, at and between the samples; "
              "the max is "
              + ("below" if max(f['clean']['samples']['max'], f['clean']['dense']['max'])
                 < s['noise_rms'] else "above")
              + f" the noise RMS. Pruning to {a['n_sections_after']} sections gives the lower "
              "max; the floor keeps the requested order. The floor's price on clean data "
              f"(example A, {f['n_sections']} sections): max relative error "
              f"{s['clean_fit']['floor']:.2g} instead of {s['clean_fit']['plain']:.2g}, "
              "because A's lightest modes are narrower than this grid's spacing.", "",
              "![Error against the clean system](clean_error.png)", "",
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
              "![Uniform against variance weights](weights.png)", "",
              "`report.json` holds every number above at full precision.", ""]
    return "\n".join(lines)


def run(n_sections, out, command, force=False):
    check_out_dir(out, force)                     # early: before the long study
    clean, data = noisy_data(NOISE)
    dense = dense_grid(clean.omega, DENSE)
    noise = data.response / clean.response - 1
    main_study, res, pr, before, after = study(data, clean, dense, n_sections, floor=True)
    floor_err = main_study.pop("_floor_errors")
    clean_fit = {k: fit(clean, n_sections=n_sections, integrator=True, delay=True,
                        min_damping=md).max_rel_error
                 for k, md in (("plain", None), ("floor", "auto"))}
    sigma = np.logspace(np.log10(SIGMA_RANGE[0]), np.log10(SIGMA_RANGE[1]), clean.n_points)
    _, data2 = noisy_data(sigma, seed=1, name="G_A + frequency-dependent noise")
    w = 1.0 / sigma ** 2
    w = w / w.mean()
    uni, *_ = study(data2, clean, dense, n_sections, floor=True)
    wtd, *_ = study(data2, clean, dense, n_sections, weights=w, floor=True)
    ua, wa = uni.pop("_floor_errors"), wtd.pop("_floor_errors")
    lo = clean.omega < 1.0
    effect = {
        "uniform_rms_below_1rad": float(np.sqrt(np.mean(ua[0][lo] ** 2))),
        "weighted_rms_below_1rad": float(np.sqrt(np.mean(wa[0][lo] ** 2))),
        "uniform_rms_above_100rad": float(np.sqrt(np.mean(ua[0][clean.omega > 100] ** 2))),
        "weighted_rms_above_100rad": float(np.sqrt(np.mean(wa[0][clean.omega > 100] ** 2))),
    }
    better_lo = effect["weighted_rms_below_1rad"] < effect["uniform_rms_below_1rad"]
    better_hi = effect["weighted_rms_above_100rad"] < effect["uniform_rms_above_100rad"]
    uf, wf = uni["floor"]["clean"], wtd["floor"]["clean"]
    text = (f"Effect (damping-floor fits, {n_sections} sections, clean error at the samples): "
            f"below 1 rad/s, where the data is precise, RMS "
            f"{effect['uniform_rms_below_1rad']:.3g} (uniform) vs "
            f"{effect['weighted_rms_below_1rad']:.3g} (1/sigma^2); above 100 rad/s, where it "
            f"is noisy, {effect['uniform_rms_above_100rad']:.3g} vs "
            f"{effect['weighted_rms_above_100rad']:.3g}. Over all samples RMS "
            f"{uf['samples']['rms']:.3g} vs {wf['samples']['rms']:.3g} (max "
            f"{uf['samples']['max']:.3g} vs {wf['samples']['max']:.3g}), on the dense grid "
            f"RMS {uf['dense']['rms']:.3g} vs {wf['dense']['rms']:.3g}. "
            + ("The variance weights give the lower error in both bands: with uniform "
               "weights the noisy high-frequency points dominate the cost, with 1/sigma^2 the "
               "precise points count most and the noisy ones no more than their noise allows."
               if better_lo and better_hi else
               "The variance weights are better "
               + ("below 1 rad/s" if better_lo else "above 100 rad/s" if better_hi else
                  "in neither band") + " only on this realisation."))
    summary = _clean({
        "command": command, "seed": SEED, "noise_rms_nominal": NOISE,
        "noise_rms": float(np.sqrt(np.mean(np.abs(noise) ** 2))),
        "noise_max": float(np.max(np.abs(noise))), "n_points": clean.n_points,
        "n_dense": int(dense.size), "noisy": main_study, "clean_fit": clean_fit,
        "safeguarded_model": pr.model.to_dict(), "plain_model": res.model.to_dict(),
        "weighted_study": {"sigma_range": list(SIGMA_RANGE), "seed": 1, **effect},
        "uniform": uni, "weighted": wtd, "weights_effect": text,
    })
    with report_folder(out, force) as (tmp, _):
        _figure_clean(tmp, clean, dense, before, after, floor_err)
        _figure_weights(tmp, clean, dense, sigma, ua, wa)
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), _markdown(command, summary))
    return summary


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", type=int, default=17)
    ap.add_argument("--out", default=os.path.join("results", "noisy"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    command = " ".join(["python scripts/noisy_example.py"] + [shlex.quote(a) for a in argv])
    s = run(args.sections, args.out, command, args.force)
    a = s["noisy"]
    for key in ("clean_before", "clean_after"):
        c = a[key]
        print(f"{key}: samples max {c['samples']['max']:.4g} RMS {c['samples']['rms']:.4g}; "
              f"dense max {c['dense']['max']:.4g} RMS {c['dense']['rms']:.4g}")
    print(s["weights_effect"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
