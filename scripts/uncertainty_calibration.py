"""Calibration of the parameter uncertainty (issue 17) by Monte Carlo, and the actuator delay.

Usage::

    nice -n 10 python scripts/uncertainty_calibration.py [--replicates 1000] [--jobs 2] \
        [--out results/uncertainty] [--force] [--no-actuator]

1. Monte Carlo. A known 2-mode system with a delay (:func:`truth_model`: modes at 5 and
   17 Hz, damping 0.02 and 0.03, zero pairs at 60 rad/s and 300 rad/s, delay 5 ms, gain 1)
   on 400 log-spaced points over 2..600 rad/s, times ``1 + n_i`` with ``n_i`` complex
   Gaussian of RMS 1 % (``E|n_i|^2 = 1e-4``; replicate r uses seed r). Each replicate is
   refitted with ``freqid_casadi.fit(data, n_sections=2, start="rational")`` and its
   :func:`freqid_casadi.uncertainty.covariance.parameter_uncertainty` (noise from the residuals)
   gives 95 % normal intervals of both natural frequencies, dampings, the delay and the
   gain. Reported: the coverage of the truth, the ratio of the mean reported standard
   deviation to the empirical one over the replicates, the bias; and, on replicate 0, the
   residual bootstrap (local and global refits) beside the delta method.
2. Actuator (the package's ``datasets/actuator/0A.txt.xz``, CHANNEL2 -> CHANNEL0, 1000 Hz):
   Welch H1 estimate (scipy.signal.csd/welch, nperseg 4096, Hann, 50 % overlap) kept where
   the coherence exceeds 0.95 within 0.1..19.5 Hz, weights ``gamma^2 / (1 - gamma^2)``
   (inverse relative variance of H1, Bendat & Piersol eq. 9.90) normalised to mean 1;
   fits with 1, 2 and 3 sections (``start="rational"``) and their delays ± std.

Writes ``--out`` atomically: ``report.md`` (first line: the command), ``calibration.json``
(every number), ``calibration.png`` (coverage and std ratios), ``example_bode.png``,
``example_rel_error.png`` (bands of replicate 0) and ``actuator_bode.png``,
``actuator_rel_error.png``.
"""

import argparse
import json
import os
import shlex
import sys
import time

import numpy as np

from freqid_casadi import plots
from freqid_casadi.uncertainty.bands import fit_band_weight
from freqid_casadi.fitting.bootstrap import bootstrap
from freqid_casadi.uncertainty.covariance import parameter_uncertainty
from freqid_casadi.core.data import FrequencyData
from freqid_casadi.fitting.fit import fit
from freqid_casadi.core.model import RationalDelayModel, Structure
from freqid_casadi.plots.uncertainty import bode_band, rel_error_band, render_markdown
from freqid_casadi.report.environment import computed_on, environment
from freqid_casadi.report.folder import generated_by_line, markdown_table, report_folder

NOISE = 0.01
LEVEL = 0.95
OMEGA = np.logspace(np.log10(2.0), np.log10(600.0), 400)
TRACKED = ("omega_1", "zeta_1", "omega_2", "zeta_2", "delay", "gain")
FS = 1000.0
SECTIONS = (1, 2, 3)


def truth_model():
    """The true system: 2 sections, delay 5 ms, DC gain 1 (beta in thesis order)."""
    w1, z1, w2, z2 = 2 * np.pi * 5, 0.02, 2 * np.pi * 17, 0.03
    wz1, wz2 = 60.0, 300.0
    gain = (w1 * w2 / (wz1 * wz2)) ** 2             # DC gain 1
    beta = [0.005, gain, 1, 0.02, wz1, 1, z1, w1, 1, 0.3, wz2, 1, z2, w2]
    return RationalDelayModel(Structure(2), beta)


def truth_values():
    """True values of :data:`TRACKED`."""
    return {"omega_1": 2 * np.pi * 5, "zeta_1": 0.02, "omega_2": 2 * np.pi * 17,
            "zeta_2": 0.03, "delay": 0.005, "gain": 1.0}


def noisy_data(seed):
    """The truth on :data:`OMEGA` times ``1 + n``, ``n`` complex Gaussian of RMS 1 %."""
    rng = np.random.default_rng(seed)
    n = (rng.standard_normal(OMEGA.size) + 1j * rng.standard_normal(OMEGA.size)) / np.sqrt(2)
    g = truth_model().frequency_response(OMEGA)
    return FrequencyData(OMEGA, g * (1 + NOISE * n), f"2-mode system + 1 % noise (seed {seed})")


def estimates(unc):
    """(values, stds) of :data:`TRACKED` from a ParameterUncertainty (modes by frequency)."""
    if len(unc.modes) != 2:
        nan = {k: np.nan for k in TRACKED}
        return nan, dict(nan)
    m1, m2 = unc.modes
    val = {"omega_1": m1.omega_n, "zeta_1": m1.zeta, "omega_2": m2.omega_n, "zeta_2": m2.zeta,
           "delay": unc.delay, "gain": unc.gain}
    std = {"omega_1": m1.omega_n_std, "zeta_1": m1.zeta_std, "omega_2": m2.omega_n_std,
           "zeta_2": m2.zeta_std, "delay": unc.delay_std, "gain": unc.gain_std}
    return val, std


def replicate(seed):
    """Fit one noisy replicate; values and standard deviations of :data:`TRACKED`."""
    data = noisy_data(seed)
    res = fit(data, n_sections=2, start="rational")
    return estimates(parameter_uncertainty(res))


def monte_carlo(n, jobs=2, first_seed=0):
    """Values and stds, arrays of shape (n, len(TRACKED)), and the wall time (s)."""
    from joblib import Parallel, delayed

    t0 = time.perf_counter()
    seeds = range(first_seed, first_seed + n)
    if jobs == 1:
        rows = [replicate(s) for s in seeds]
    else:
        rows = Parallel(n_jobs=jobs)(delayed(replicate)(s) for s in seeds)
    val = np.array([[v[k] for k in TRACKED] for v, _ in rows])
    std = np.array([[s[k] for k in TRACKED] for _, s in rows])
    return val, std, time.perf_counter() - t0


def summarize(val, std, level=LEVEL):
    """Per parameter: coverage of the truth, empirical std, mean reported std, ratio, bias."""
    from scipy import stats

    z = float(stats.norm.ppf(0.5 + level / 2))
    truth = np.array([truth_values()[k] for k in TRACKED])
    ok = np.all(np.isfinite(val) & np.isfinite(std), axis=1)
    v, s = val[ok], std[ok]
    cover = np.abs(v - truth) <= z * s
    out = {}
    for j, name in enumerate(TRACKED):
        emp = float(np.std(v[:, j], ddof=1))
        out[name] = {"truth": float(truth[j]), "coverage": float(cover[:, j].mean()),
                     "empirical_std": emp, "mean_reported_std": float(s[:, j].mean()),
                     "rms_reported_std": float(np.sqrt(np.mean(s[:, j] ** 2))),
                     "std_ratio": float(s[:, j].mean() / emp),
                     "bias": float(v[:, j].mean() - truth[j]),
                     "bias_in_std": float((v[:, j].mean() - truth[j]) / emp)}
    return {"n_replicates": int(val.shape[0]), "n_valid": int(ok.sum()), "level": level,
            "parameters": out}


# --------------------------------------------------------------------------- actuator

def actuator_records():
    """Input (CHANNEL2) and output (CHANNEL0) records of the actuator test, from the copy
    shipped with the package (``freqid_casadi/datasets/actuator``)."""
    from freqid_casadi import experiment

    rec = experiment.actuator_records()
    return rec.channels["CHANNEL2"], rec.channels["CHANNEL0"]


def actuator_frf(u, y, nperseg=4096, min_coherence=0.95, band=(0.1, 19.5)):
    """Welch H1 estimate, coherence-selected band, weights; FrequencyData and extras."""
    from scipy import signal

    f, puu = signal.welch(u, FS, nperseg=nperseg)
    _, puy = signal.csd(u, y, FS, nperseg=nperseg)
    _, pyy = signal.welch(y, FS, nperseg=nperseg)
    h1 = puy / puu
    coh = np.abs(puy) ** 2 / (puu * pyy)
    keep = (f >= band[0]) & (f <= band[1]) & (coh > min_coherence)
    g2 = coh[keep]
    w = g2 / (1 - g2)
    n_avg = int((u.size - nperseg) // (nperseg // 2) + 1)
    data = FrequencyData(2 * np.pi * f[keep], h1[keep], "actuator 0A (H1)", w / w.mean())
    # relative variance of H1 (Bendat & Piersol): (1 - g^2) / (2 n_d g^2)
    variance = np.abs(h1[keep]) ** 2 * (1 - g2) / (2 * n_avg * g2)
    return data, {"n_points": int(keep.sum()), "n_averages": n_avg,
                  "f_min_hz": float(f[keep][0]), "f_max_hz": float(f[keep][-1]),
                  "coherence_min": float(g2.min())}, variance


def actuator_delays(data, variance):
    """Fit 1, 2, 3 sections; delay ± std (residual noise, and H1's coherence variance)."""
    rows, fits = [], {}
    for n in SECTIONS:
        res = fit(data, n_sections=n, start="rational")
        unc = parameter_uncertainty(res)
        unc_h1 = parameter_uncertainty(res, noise_variance=variance)
        fits[n] = (res, unc)
        corr, with_name = delay_correlation(unc)
        rows.append({"delay_max_abs_corr": corr, "delay_max_corr_with": with_name,
                     "poles": [str(complex(p)) for p in res.model.poles()],
                     "zeros": [str(complex(z)) for z in res.model.zeros()],
                     "n_sections": n, "delay": unc.delay, "delay_std": unc.delay_std,
                     "delay_std_h1_variance": unc_h1.delay_std,
                     "delay_at_bound": bool(unc.at_bound[0]),
                     "max_rel_error": res.max_rel_error, "rms_rel_error": res.rms_rel_error,
                     "sigma2": unc.sigma2, "condition_number": unc.condition_number,
                     "modes": [{"omega_n": m.omega_n, "omega_n_std": m.omega_n_std,
                                "zeta": m.zeta, "zeta_std": m.zeta_std} for m in unc.modes]})
    return rows, fits


def delay_correlation(unc):
    """Largest |correlation| of the delay with another free parameter, and its name."""
    free = np.flatnonzero(~unc.at_bound)
    c = unc.covariance
    corr = {unc.param_names[j]: c[0, j] / (unc.std[0] * unc.std[j]) for j in free if j != 0}
    name = max(corr, key=lambda k: abs(corr[k]))
    return float(corr[name]), name


def agreement(rows):
    """Pairwise |h_i - h_j| / sqrt(std_i^2 + std_j^2) of the delays."""
    out = []
    for i in range(len(rows)):
        for j in range(i + 1, len(rows)):
            a, b = rows[i], rows[j]
            d = abs(a["delay"] - b["delay"])
            s = float(np.hypot(a["delay_std"], b["delay_std"]))
            out.append({"pair": f"{a['n_sections']}-{b['n_sections']}", "difference": d,
                        "combined_std": s, "in_std": d / s if s > 0 else float("inf")})
    return out


# --------------------------------------------------------------------------- report

def calibration_figure(summary):
    """Two panels: coverage of the 95 % intervals and std ratio, per parameter."""
    import matplotlib.pyplot as plt

    names = list(summary["parameters"])
    p = summary["parameters"]
    n = summary["n_valid"]
    cov = np.array([p[k]["coverage"] for k in names])
    ratio = np.array([p[k]["std_ratio"] for k in names])
    x = np.arange(len(names))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9.0, 3.6), layout="constrained")
    a1.axhspan(0.92, 0.98, color="C2", alpha=0.2, label="target 92-98 %")
    a1.axhline(LEVEL, color="k", lw=0.8, ls=":")
    err = 1.96 * np.sqrt(cov * (1 - cov) / n)
    a1.errorbar(x, cov, yerr=err, fmt="o", color="C0", capsize=3,
                label=f"coverage ({n} replicates, 95 % binomial bar)")
    a1.set_ylim(0.85, 1.0)
    a1.set_ylabel("fraction of intervals containing the truth")
    a2.axhspan(0.8, 1.2, color="C2", alpha=0.2, label="target within 20 %")
    a2.axhline(1.0, color="k", lw=0.8, ls=":")
    # the empirical std of n samples has a relative standard error of about 1/sqrt(2(n-1))
    a2.errorbar(x, ratio, yerr=1.96 * ratio / np.sqrt(2 * (n - 1)), fmt="s", color="C1",
                capsize=3, label="mean reported std / empirical std")
    a2.set_ylim(0.6, 1.4)
    for ax, title in ((a1, "coverage of the 95 % intervals"), (a2, "standard deviations")):
        ax.set_xticks(x, names, rotation=30)
        ax.set_title(title, fontsize="medium")
        ax.grid(True, axis="y", alpha=0.4)
        ax.legend(fontsize="small", loc="lower left")
    return fig


def bootstrap_comparison(seed=0, n_boot=200, jobs=2):
    """Delta method vs residual bootstrap (local and global refits) on one replicate."""
    data = noisy_data(seed)
    res = fit(data, n_sections=2, start="rational")
    unc = parameter_uncertainty(res)
    t0 = time.perf_counter()
    local = bootstrap(res, n_boot=n_boot, seed=seed, n_jobs=1)
    t1 = time.perf_counter()
    glob = bootstrap(res, n_boot=n_boot // 2, seed=seed, n_jobs=jobs, refit="fit")
    t2 = time.perf_counter()
    rows = []
    for k in TRACKED:
        rows.append({"parameter": k, "delta": estimates(unc)[1][k],
                     "bootstrap_local": estimates(local)[1][k],
                     "bootstrap_fit": estimates(glob)[1][k]})
    return {"rows": rows, "n_boot_local": n_boot, "n_boot_fit": n_boot // 2,
            "time_local_s": t1 - t0, "time_fit_s": t2 - t1,
            "failed_fit": int(np.sum(~np.all(np.isfinite(glob.samples), axis=1)))}, res, unc


def _fmt(x, digits=4):
    return f"{x:.{digits}g}"


def calibration_section(summary, wall, jobs, boot):
    """Markdown of the Monte Carlo part."""
    p = summary["parameters"]
    rows = [[k, _fmt(v["truth"], 6), f"{100 * v['coverage']:.1f} %",
             _fmt(v["empirical_std"], 3), _fmt(v["mean_reported_std"], 3),
             f"{v['std_ratio']:.3f}", f"{v['bias_in_std']:+.2f}",
             "yes" if 0.92 <= v["coverage"] <= 0.98 and abs(v["std_ratio"] - 1) <= 0.2
             else "**no**"] for k, v in p.items()]
    n = summary["n_valid"]
    lines = [
        "## 1. Calibration by Monte Carlo", "",
        f"{summary['n_replicates']} replicates ({n} with two modes found), each refitted with "
        "`fit(data, n_sections=2, start=\"rational\")`; 95 % normal intervals from "
        "`parameter_uncertainty` (noise from the residuals). Wall time "
        f"{wall:.1f} s with {jobs} joblib workers under `nice -n 10` (shared, loaded 2-core "
        "machine: timings are noisy).", "",
        markdown_table(rows, ["parameter", "truth", "coverage", "empirical std",
                              "mean reported std", "ratio", "bias / std", "in target"],
                       "lrrrrrrl"), "",
        f"Targets: coverage in 92-98 %, ratio within 20 %. With {n} replicates the coverage "
        f"has a binomial standard error of {100 * np.sqrt(0.95 * 0.05 / n):.1f} points and "
        f"the empirical std a relative one of {100 / np.sqrt(2 * (n - 1)):.1f} %.", "",
        "![calibration](calibration.png)", "",
        "### Delta method and residual bootstrap (replicate 0)", "",
        markdown_table([[r["parameter"], _fmt(r["delta"], 3), _fmt(r["bootstrap_local"], 3),
                         _fmt(r["bootstrap_fit"], 3)] for r in boot["rows"]],
                       ["parameter", "delta std", f"bootstrap std (local refit, "
                        f"{boot['n_boot_local']})", f"bootstrap std (fc.fit refit, "
                        f"{boot['n_boot_fit']})"], "lrrr"), "",
        f"Bootstrap wall times: local refits {boot['time_local_s']:.1f} s (1 process), "
        f"fc.fit refits {boot['time_fit_s']:.1f} s ({jobs} workers); "
        f"{boot['failed_fit']} fc.fit refits failed or did not match.", "",
        "![bands](example_bode.png) ![rel. error band](example_rel_error.png)", ""]
    return lines


def actuator_section(info, rows, pairs):
    """Markdown of the actuator part."""
    table = [[r["n_sections"], f"{1e3 * r['delay']:.3f}", f"{1e3 * r['delay_std']:.3f}",
              f"{1e3 * r['delay_std_h1_variance']:.3f}", _fmt(r["max_rel_error"], 3),
              _fmt(r["rms_rel_error"], 3), f"{r['condition_number']:.2g}",
              f"{r['delay_max_abs_corr']:+.3f} ({r['delay_max_corr_with']})"] for r in rows]
    agree = [[a["pair"], f"{1e3 * a['difference']:.3f}", f"{1e3 * a['combined_std']:.3f}",
              f"{a['in_std']:.2f}", "yes" if a["in_std"] <= 1 else "**no**"] for a in pairs]
    return [
        "## 2. Actuator delay at 1, 2 and 3 sections", "",
        "Records `freqid_casadi/datasets/actuator/0A.txt.xz` (see its SOURCE.md): commanded "
        "displacement CHANNEL2 -> measured displacement CHANNEL0, 1000 Hz. Welch H1 "
        f"(nperseg 4096, Hann, 50 % overlap, {info['n_averages']} averages), kept where the "
        f"coherence exceeds 0.95 within 0.1-19.5 Hz: {info['n_points']} points, "
        f"{info['f_min_hz']:.3f}-{info['f_max_hz']:.2f} Hz, min coherence "
        f"{info['coherence_min']:.4f}; weights gamma^2/(1 - gamma^2) normalised to mean 1. "
        "Each fit `fit(data, n_sections=n, start=\"rational\")`.", "",
        markdown_table(table, ["sections", "delay (ms)", "std (ms), residuals",
                               "std (ms), H1 coherence variance", "max rel. error",
                               "RMS rel. error", "condition",
                               "largest correlation of the delay"], "rrrrrrrl"), "",
        "Zeros and poles of each fit (rad/s) are in calibration.json. A correlation of the "
        "delay near ±1 means the data determine only a combination of the delay and that "
        "parameter (a real zero or pole far above the band adds a phase ~ omega/r, like a "
        "delay of 1/r): its std is then large, as it should be.", "",
        "The first std takes the noise level from the weighted residuals (the default: it "
        "includes the model error); the second uses the H1 variance from the coherence, "
        "|H|^2 (1 - gamma^2)/(2 n_d gamma^2) (Bendat & Piersol), which ignores the model "
        "error and is smaller when the residuals exceed the measurement noise.", "",
        markdown_table(agree, ["pair", "|difference| (ms)", "combined std (ms)",
                               "difference / std", "agree within 1 std"], "lrrrl"), "",
        "![actuator bode](actuator_bode.png) ![actuator error](actuator_rel_error.png)", ""]


def run(n, jobs, out, command, force=False, actuator=True):
    """Run both parts and write the report folder ``out``; returns the JSON summary."""
    val, std, wall = monte_carlo(n, jobs)
    summary = summarize(val, std)
    boot, res0, unc0 = bootstrap_comparison(jobs=jobs)
    js = {"command": command, "calibration": summary, "wall_time_s": wall, "jobs": jobs,
          "bootstrap": boot, "truth": truth_values(), "environment": environment()}
    md = [generated_by_line(command), "", "# Calibration of the parameter uncertainty "
          "(issue 17)", "", "A known 2-mode system with a 5 ms delay (modes 5 Hz / zeta 0.02 "
          "and 17 Hz / zeta 0.03, zero pairs at 60 and 300 rad/s) on 400 log-spaced points "
          "over 2-600 rad/s, with 1 % complex Gaussian noise (E|n|^2 = 1e-4).", "",
          computed_on(js["environment"]), ""]
    md += calibration_section(summary, wall, jobs, boot)
    md += ["### Modal table of replicate 0", "", render_markdown(unc0)]
    figures = {"calibration.png": calibration_figure(summary),
               "example_bode.png": bode_band(unc0, res0.data),
               "example_rel_error.png": rel_error_band(unc0, res0.data)}
    if actuator:
        u, y = actuator_records()
        data, info, variance = actuator_frf(u, y)
        rows, fits = actuator_delays(data, variance)
        pairs = agreement(rows)
        js["actuator"] = {"frf": info, "rows": rows, "agreement": pairs}
        md += actuator_section(info, rows, pairs)
        res2, unc2 = fits[2]
        weight = fit_band_weight(unc2, data, k=2.0, order=2)
        js["actuator"]["band_weight_2_sections"] = {"gain": weight.gain,
                                                    "success": bool(weight.success)}
        figures["actuator_bode.png"] = bode_band(unc2, data, title="actuator, 2 sections")
        figures["actuator_rel_error.png"] = rel_error_band(unc2, data,
                                                           title="actuator, 2 sections")
    with report_folder(out, force) as (tmp, _):
        with open(os.path.join(tmp, "report.md"), "w", encoding="utf-8") as fh:
            fh.write("\n".join(md) + "\n")
        with open(os.path.join(tmp, "calibration.json"), "w", encoding="utf-8") as fh:
            json.dump(js, fh, indent=1, default=float)
        for name, fig in figures.items():
            plots.save_figure(fig, os.path.join(tmp, name))
    return js


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--replicates", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="results/uncertainty")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--no-actuator", action="store_true")
    args = ap.parse_args(argv)
    command = "nice -n 10 python scripts/uncertainty_calibration.py " + " ".join(
        shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    import matplotlib

    matplotlib.use("Agg")
    js = run(args.replicates, args.jobs, args.out, command.strip(), args.force,
             not args.no_actuator)
    for k, v in js["calibration"]["parameters"].items():
        print(f"{k:8s} coverage {v['coverage']:.3f} std ratio {v['std_ratio']:.3f}")
    print(f"Monte Carlo wall time {js['wall_time_s']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
