"""Reproduce the thesis's chapter 4 (Table 4.1, figures 4.1-4.21) in one report folder (layer L5).

:func:`reproduce` fits examples A, B and C at the thesis's orders with the package's method
(IPOPT) and, where it runs in time, the thesis's barrier + Levenberg-Marquardt; fits the
baselines of SPEC §6 (subspace, Fourier) and the unconstrained peers (AAA, vector fitting)
with as many poles as our model; fits ``1/sqrt(s)`` with first-order sections and compares
the closed loop with the continued-fraction and Newton-process approximations (thesis
§4.2); and corrects Moheimani's truncated beam model with K_opt. It writes::

    report.md       first line: the command (report.generated_by_line); Table 4.1 and notes
    report.json     every number of report.md (full precision) and more
    curves.json     the curves of the figures (omega, errors)
    <X>_model.json  our fitted model of example X (RationalDelayModel.load)
    *.png           the figures (list in report.md, with the thesis figure they correspond to)

The folder is built in a temporary sibling folder and renamed into place when complete, so
either the whole report exists or nothing does; an existing folder is replaced only with
``force=True`` (checked before the fits start, and again before the rename).

The command line: :func:`add_cli` and :func:`run_cli` (wired into ``freqid reproduce`` by
:mod:`freqid_casadi.cli`) and :func:`main` (``scripts/reproduce_thesis.py``).
"""

import argparse
import json
import logging
import math
import os
import shlex
import sys
import time
from dataclasses import dataclass

import numpy as np

from . import baselines, systems
from ._io import atomic_write_text
from .errors import FreqidError, OptionError
from .fit import fit
from .options import BarrierLMOptions
from .model import RationalDelayModel, Structure
from .report import (_clean, check_out_dir, generated_by_line, report_folder,
                     markdown_table)

__all__ = ["reproduce", "add_cli", "run_cli", "main", "table_cell", "EXAMPLE_NAMES",
           "THESIS_TABLE_4_1", "TABLE_COLUMNS", "TABLE_QUANTITIES", "ORDERS",
           "FRACTIONAL_SECTIONS", "NEWTON_ITERATIONS", "BARRIER_LM_OPTIONS",
           "BARRIER_LM_TIME_LIMIT", "BARRIER_LM_TIME_CAP", "REPRODUCE_FORMAT"]

log = logging.getLogger(__name__)

REPRODUCE_FORMAT = "freqid_casadi.reproduce_thesis"

#: What :func:`reproduce` can run (``--examples``): the three beams/rod of Table 4.1, the
#: fractional example of thesis §4.2 and Moheimani's beam.
EXAMPLE_NAMES = ("A", "B", "C", "fractional", "moheimani")

#: Sections and integrator of our model per example (the thesis's orders of P_N: 34, 18, 54).
ORDERS = {"A": (17, True), "B": (9, False), "C": (27, True)}

#: Thesis Table 4.1 (SPEC §5): order of P_N, max rel. error of its NLLS method and of the
#: subspace method, its delay estimate (s).
THESIS_TABLE_4_1 = {
    "A": dict(order=34, nlls=0.2549, subspace=2.5724, delay=0.0106),
    "B": dict(order=18, nlls=0.0027, subspace=0.0044, delay=0.011),
    "C": dict(order=54, nlls=5.9884, subspace=7.3382, delay=0.0261),
}

#: First-order sections of our 1/sqrt(s) model: one real pole/zero pair per decade of the
#: 1e-5..1e5 rad/s grid (the thesis does not state its order; same choice as ``freqid
#: example fractional``).
FRACTIONAL_SECTIONS = 10

#: Iterations of the regular Newton process: orders are (3^k - 1)/2 = 1, 4, 13, 40, so
#: k = 3 (order 13) is the nearest order at or above FRACTIONAL_SECTIONS.
NEWTON_ITERATIONS = 3

#: Options of the barrier-LM fits (SPEC §3). The method is included only if its fit of A
#: finishes within BARRIER_LM_TIME_LIMIT seconds (else every example says "not run (time)");
#: B and C then run with the safety cap BARRIER_LM_TIME_CAP (s).
BARRIER_LM_OPTIONS = {"damping": "marquardt", "max_inner": 100}
BARRIER_LM_TIME_LIMIT = 240.0
BARRIER_LM_TIME_CAP = 900.0

#: Columns of Table 4.1.
TABLE_COLUMNS = ("thesis NLLS", "thesis subspace", "ours (IPOPT)", "ours (barrier-LM)",
                 "subspace (ours)", "Fourier (ours)", "AAA", "vector fitting")
_METHOD_KEYS = ("ipopt", "barrier-lm", "subspace", "fourier", "aaa", "vector-fitting")
_METHOD_LABELS = dict(zip(_METHOD_KEYS, TABLE_COLUMNS[2:]))

#: Rows of Table 4.1 per example: (key in the method's JSON entry, label).
TABLE_QUANTITIES = (("n_poles", "poles (order, integrator incl.)"),
                    ("max_rel_error", "max rel. error"),
                    ("rms_rel_error", "RMS rel. error"),
                    ("n_rhp_zeros", "RHP zeros"),
                    ("n_rhp_poles", "RHP poles"),
                    ("delay", "delay h (s)"),
                    ("wall_time", "wall time (s)"))

_NO_DELAY = "none*"
_DASH = "—"

# Moheimani's beam (SPEC §4): kept modes and bandwidth.
_MOHEIMANI_KEPT = 2
_MOHEIMANI_OMEGA_C = 100.0
_MOHEIMANI_MODES = 30


# ----------------------------------------------------------------------------- configuration


@dataclass(frozen=True)
class _Config:
    """Problem sizes of one run (full: the thesis's; quick: a smoke test)."""

    quick: bool
    window: int                 # data points of A/B/C (500 = all)
    sections: dict              # example -> (n_sections, integrator)
    fractional_points: int
    fractional_sections: int
    newton_iterations: int
    n_fft: int
    lm_time_limit: float        # gate: the fit of A must finish within it
    lm_time_cap: float          # safety cap of the fits of B and C


def _config(quick):
    if quick:
        return _Config(True, 250, {"A": (3, True), "B": (2, False), "C": (3, True)},
                       100, 4, 2, 128, 60.0, 60.0)
    return _Config(False, 500, dict(ORDERS), 500, FRACTIONAL_SECTIONS, NEWTON_ITERATIONS,
                   1024, BARRIER_LM_TIME_LIMIT, BARRIER_LM_TIME_CAP)


_SYSTEMS = {"A": systems.G_A, "B": systems.G_B, "C": systems.G_C}
_TRUE_DELAY = {"A": 0.01, "B": None, "C": 0.02625}


# ----------------------------------------------------------------------------- helpers


def table_cell(value):
    """How a value of the JSON appears in a Markdown table cell of report.md.

    ``None`` is an em dash, a bool ``yes``/``no``, an int as is, a float with 4 significant
    digits, a string as is. The test of the report uses it to check report.md against
    report.json.
    """
    if value is None:
        return _DASH
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        x = float(value)
        return f"{x:.4g}" if math.isfinite(x) else _DASH
    return str(value)


def _rel_error(model, data):
    """|Phi/G_N - 1| (= |(G - G_N)/G_N|, thesis Table 4.1) at the data points."""
    return np.abs(data.response / model.frequency_response(data.omega) - 1.0)


def _entry(model, data, wall_time, *, delay_fitted, extra=None):
    """Numbers of one method on one example (a JSON dict) and its rel. error curve."""
    rel = _rel_error(model, data)
    n_rhp_poles, n_rhp_zeros = baselines.count_rhp(model)
    entry = {
        "n_poles": int(np.asarray(model.poles()).size),
        "max_rel_error": float(np.max(rel)),
        "rms_rel_error": float(np.sqrt(np.mean(rel ** 2))),
        "omega_at_max_rel_error": float(data.omega[int(np.argmax(rel))]),
        "n_rhp_zeros": n_rhp_zeros,
        "n_rhp_poles": n_rhp_poles,
        "minimum_phase": bool(model.is_minimum_phase()),
        "stable": bool(model.is_stable()),
        "delay": float(model.delay) if delay_fitted else _NO_DELAY,
        "wall_time": float(wall_time),
        "status": "ok",
    }
    entry.update(extra or {})
    return entry, rel


def _not_run(reason):
    return {"status": reason, **{k: reason for k, _ in TABLE_QUANTITIES}}


class _TimeLimit(Exception):
    """Raised from the progress callback when a fit exceeds its time limit."""


def _fit_time_limited(data, limit, **kw):
    """``(fit(data, **kw), elapsed s, None)``, or ``(None, elapsed s, last StageRecord)`` if
    the fit was stopped after the first stage that ended past ``limit`` seconds."""
    t0 = time.perf_counter()
    stages = []

    def progress(rec):
        stages.append(rec)
        log.info("  %s stage %d: %d sections, max rel. error %.3e, %.1f s", kw.get("method"),
                 rec.stage, rec.n_sections, rec.max_rel_error, time.perf_counter() - t0)
        if time.perf_counter() - t0 > limit:
            raise _TimeLimit(f"stopped after {time.perf_counter() - t0:.0f} s at stage "
                             f"{rec.stage}")

    try:
        return fit(data, progress=progress, **kw), time.perf_counter() - t0, None
    except _TimeLimit:
        return None, time.perf_counter() - t0, stages[-1]


def _timed(fun, *args, **kw):
    t0 = time.perf_counter()
    out = fun(*args, **kw)
    return out, time.perf_counter() - t0


def _p_n(model):
    """P_N alone: the model's sections with gain 1, no integrator, no delay."""
    st = model.structure
    beta = np.concatenate([[0.0, 1.0], model.beta[2:]])
    return RationalDelayModel(Structure(st.n_sections, False, False, st.basis), beta)


# ----------------------------------------------------------------------------- examples


def _run_rational(key, cfg, lm_gate):
    """Example A, B or C: our fits, the baselines, HSVs of P_N, perturbed plants.

    ``lm_gate`` (a dict shared by the examples) holds ``"skip"``: why barrier-LM is not run
    (set when the fit of A exceeds ``cfg.lm_time_limit``), or None."""
    data = _SYSTEMS[key]()
    if cfg.window < data.n_points:
        data = data.window(cfg.window)
    n_sections, integrator = cfg.sections[key]
    out = {"data": {"name": data.name, "n_points": int(data.n_points),
                    "omega_min": float(data.omega[0]), "omega_max": float(data.omega[-1])},
           "n_sections": n_sections, "integrator": integrator,
           "order_p_n": 2 * n_sections, "true_delay": _TRUE_DELAY[key],
           "thesis": THESIS_TABLE_4_1[key], "methods": {}}
    curves = {"omega": data.omega, "rel_error": {}}
    models = {}

    log.info("%s: fit with IPOPT, %d sections", key, n_sections)
    ours = fit(data, n_sections=n_sections, integrator=integrator, delay=True, method="ipopt")
    entry, rel = _entry(ours.model, data, ours.wall_time, delay_fitted=True,
                        extra={"success": bool(ours.success), "nit": ours.nit})
    out["methods"]["ipopt"], curves["rel_error"]["ipopt"] = entry, rel
    models["ipopt"] = ours.model
    log.info("%s: IPOPT max rel. error %.4g in %.1f s", key, ours.max_rel_error, ours.wall_time)

    limit = cfg.lm_time_limit if key == "A" else cfg.lm_time_cap
    if lm_gate.get("skip"):
        entry = _not_run("not run (time)")
        entry["note"] = lm_gate["skip"]
        out["methods"]["barrier-lm"] = entry
    else:
        log.info("%s: fit with barrier-LM (limit %.0f s)", key, limit)
        lm, elapsed, last = _fit_time_limited(
            data, limit, n_sections=n_sections, integrator=integrator, delay=True,
            method=BarrierLMOptions(**BARRIER_LM_OPTIONS))
        if lm is None:
            label = "not run (time)" if key == "A" else "stopped (time)"
            entry = _not_run(label)
            entry["note"] = (f"stopped after {elapsed:.0f} s > limit {limit:.0f} s, at stage "
                             f"{last.stage} of {n_sections} with max rel. error "
                             f"{last.max_rel_error:.4g}")
            entry["elapsed"] = elapsed
            entry["last_stage"] = last.as_dict()
            if key == "A":
                lm_gate["skip"] = (f"the barrier-LM fit of A did not finish within "
                                   f"{limit:.0f} s")
            out["methods"]["barrier-lm"] = entry
        else:
            entry, rel = _entry(lm.model, data, lm.wall_time, delay_fitted=True,
                                extra={"success": bool(lm.success), "nit": lm.nit,
                                       "time_limit": limit})
            out["methods"]["barrier-lm"], curves["rel_error"]["barrier-lm"] = entry, rel
            models["barrier-lm"] = lm.model
    log.info("%s: barrier-LM %s", key, out["methods"]["barrier-lm"]["max_rel_error"])

    n_poles = ours.model.order                 # 2N (+1 with the integrator)
    peers = {
        "subspace": lambda: baselines.subspace(data, n_poles),
        "fourier": lambda: baselines.fourier(data, n_poles, n_fft=cfg.n_fft),
        "aaa": lambda: baselines.aaa(data, n_poles),
        "vector-fitting": lambda: baselines.vector_fitting(data, n_poles),
    }
    for name, run in peers.items():
        log.info("%s: %s with %d poles", key, name, n_poles)
        try:
            model, wall = _timed(run)
        except (FreqidError, np.linalg.LinAlgError, ValueError) as exc:
            out["methods"][name] = _not_run(f"failed: {' '.join(str(exc).split())}")
            continue
        entry, rel = _entry(model, data, wall, delay_fitted=False,
                            extra={"requested_poles": n_poles})
        out["methods"][name], curves["rel_error"][name] = entry, rel
        models[name] = model

    hsv = baselines.hankel_singular_values(_p_n(ours.model))
    out["hankel_singular_values_p_n"] = hsv
    out["hsv_above_1e-3"] = int(np.count_nonzero(hsv > 1e-3 * hsv[0]))
    out["hsv_above_1e-6"] = int(np.count_nonzero(hsv > 1e-6 * hsv[0]))

    out["perturbed"] = {}
    curves["perturbed"] = {}
    for pct in (5, 10):
        pert = systems.perturbed(key, pct, omega=data.omega)
        diff = np.abs(pert.response / data.response - 1.0)
        out["perturbed"][f"+{pct}%"] = {
            "max_rel_difference": float(np.max(diff)),
            "fraction_of_points_above_model_error":
                float(np.mean(diff > curves["rel_error"]["ipopt"])),
        }
        curves["perturbed"][f"+{pct}%"] = diff
    return out, curves, models, ours, data


def _run_fractional(cfg):
    """1/sqrt(s) (thesis §4.2): ours (first-order basis), continued fraction, Newton, Fourier;
    closed-loop error E = |G_D - G_N/(1 + G_N)|."""
    omega = systems.thesis_grid(cfg.fractional_points, 1e-5, 1e5)
    data = systems.sqrt_inverse(omega)
    g_d = systems.G_D(omega).response
    n = cfg.fractional_sections
    log.info("fractional: fit with IPOPT, %d first-order sections", n)
    ours = fit(data, n_sections=n, integrator=False, delay=False, basis="first-order")
    models, walls = {"ours (first-order basis)": ours.model}, {"ours (first-order basis)":
                                                               ours.wall_time}
    for label, run in (("continued fraction", lambda: baselines.continued_fraction_sqrt(n)),
                       ("Newton process",
                        lambda: baselines.newton_sqrt(cfg.newton_iterations)),
                       ("Fourier", lambda: baselines.fourier(data, n, n_fft=cfg.n_fft))):
        models[label], walls[label] = _timed(run)
    out = {"data": {"name": data.name, "n_points": int(omega.size),
                    "omega_min": float(omega[0]), "omega_max": float(omega[-1])},
           "n_sections": n, "newton_iterations": cfg.newton_iterations, "methods": {}}
    curves = {"omega": omega, "closed_loop_error": {}, "rel_error": {}, "response": {}}
    for label, model in models.items():
        g = model.frequency_response(omega)
        e_cl = np.abs(g_d - g / (1 + g))
        rel = np.abs(data.response / g - 1.0)
        n_rhp_poles, n_rhp_zeros = baselines.count_rhp(model)
        out["methods"][label] = {
            "n_poles": int(np.asarray(model.poles()).size),
            "max_closed_loop_error": float(np.max(e_cl)),
            "omega_at_max_closed_loop_error": float(omega[int(np.argmax(e_cl))]),
            "max_rel_error": float(np.max(rel)),
            "n_rhp_zeros": n_rhp_zeros, "n_rhp_poles": n_rhp_poles,
            "minimum_phase": bool(model.is_minimum_phase()),
            "wall_time": float(walls[label]),
        }
        curves["closed_loop_error"][label] = e_cl
        curves["rel_error"][label] = rel
        curves["response"][label] = g
    return out, curves, data


def _run_moheimani():
    """Moheimani's simply-supported beam: 2-mode truncation with and without K_opt."""
    data = systems.moheimani_beam(n_modes=_MOHEIMANI_MODES)
    omega_i, F_i = systems.moheimani_modes(_MOHEIMANI_MODES)
    n, wc = _MOHEIMANI_KEPT, _MOHEIMANI_OMEGA_C
    k_opt = systems.moheimani_kopt(n, wc, _MOHEIMANI_MODES)
    g_r = baselines.modal_model(omega_i[:n], F_i[:n], name="G_r")
    k_data = baselines.feedthrough_from_data(lambda w: systems.moheimani_at(1j * w),
                                             g_r, wc, points=omega_i[:n])
    g_k = baselines.modal_model(omega_i[:n], F_i[:n], feedthrough=k_opt, name="G_r + K_opt")
    omega, g = data.omega, data.response
    err_r = np.abs(g - g_r.frequency_response(omega))
    err_k = np.abs(g - g_k.frequency_response(omega))
    band = omega <= wc
    out = {"n_modes": _MOHEIMANI_MODES, "n_kept": n, "omega_c": wc,
           "omega_modes_kept": omega_i[:n], "k_opt": k_opt, "k_from_data": k_data,
           "max_abs_error_in_band_without_k": float(np.max(err_r[band])),
           "max_abs_error_in_band_with_k": float(np.max(err_k[band])),
           "rms_abs_error_in_band_without_k": float(np.sqrt(np.mean(err_r[band] ** 2))),
           "rms_abs_error_in_band_with_k": float(np.sqrt(np.mean(err_k[band] ** 2)))}
    curves = {"omega": omega, "truth": g, "G_r": g_r.frequency_response(omega),
              "G_r + K_opt": g_k.frequency_response(omega),
              "error_without_k": err_r, "error_with_k": err_k}
    return out, curves


# ----------------------------------------------------------------------------- figures


def _line_styles(k):
    return dict(color=f"C{k}", lw=1.6 if k == 0 else 1.0,
                ls=("-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1)))[k % 6])


def _fig_methods(key, curves, omega, thesis_max):
    from . import plots

    fig, ax = plots._new_figure(figsize=(7.2, 4.8))
    for k, (name, rel) in enumerate(curves.items()):
        ax.loglog(omega, rel, label=f"{_METHOD_LABELS[name]} (max {np.max(rel):.3g})",
                  **_line_styles(k))
    ax.axhline(thesis_max, color="k", ls=":", lw=0.9, label=f"thesis NLLS max ({thesis_max})")
    ax.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax.set_ylabel(r"relative error $|(G - G_N)/G_N|$")
    ax.set_title(f"Example {key}: relative error of each method")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="x-small", framealpha=0.9)
    return fig


def _fig_hsv(key, hsv):
    from . import plots

    fig, ax = plots._new_figure()
    k = np.arange(1, hsv.size + 1)
    ax.semilogy(k, hsv, "o-", color="C0", ms=4, lw=0.8)
    ax.set_xlabel("index i")
    ax.set_ylabel(r"Hankel singular value $\sigma_i$ of $P_N$")
    ax.set_title(f"Example {key}: Hankel singular values of $P_N$ (order {hsv.size})")
    plots._finish_axes(ax)
    return fig


def _fig_perturbed(key, omega, model_rel, pert):
    from . import plots

    fig, ax = plots._new_figure()
    ax.loglog(omega, model_rel, color="C0", lw=1.4,
              label=r"identified model $|(G - G_N)/G_N|$")
    for k, (label, diff) in enumerate(pert.items()):
        ax.loglog(omega, diff, color=f"C{k + 1}", lw=1.0, ls="--",
                  label=rf"perturbed plant {label}: $|G_{{pert}}/G - 1|$")
    ax.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax.set_ylabel("relative error")
    ax.set_title(f"Example {key}: perturbed plants vs the model's error")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


def _fig_subspace_pz(key, model):
    from . import plots

    fig, ax = plots._new_figure()
    p, z = np.asarray(model.poles()), np.asarray(model.zeros())
    ax.axvline(0, color="0.4", ls="--", lw=0.7, zorder=0)
    ax.plot(p.real, p.imag, "x", color="C3", ms=7, mew=1.3, label=f"poles ({p.size})")
    ax.plot(z.real, z.imag, "o", color="C0", ms=7, mfc="none", mew=1.3,
            label=f"zeros ({z.size}, {int(np.count_nonzero(z.real > 0))} in the RHP)")
    pts = np.concatenate([p, z])
    lim = float(np.max(np.abs(pts))) * 1.05 if pts.size else 1.0
    # symmetric log axes: the roots span several decades; a wide linear region around 0
    # keeps the tick labels -thresh, 0, +thresh apart
    thresh = 10.0 ** math.floor(math.log10(max(lim * 1e-4, 1e-6)))
    ax.set_xscale("symlog", linthresh=thresh, linscale=2.0)
    ax.set_yscale("symlog", linthresh=thresh, linscale=2.0)
    ax.set_xlabel("real part (rad/s, symmetric log scale)")
    ax.set_ylabel("imaginary part (rad/s, symmetric log scale)")
    ax.set_title(f"Example {key}: poles and zeros of the subspace model")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


def _fig_fractional_bode(curves, data):
    from . import plots

    fig, (ax_m, ax_p) = plots._new_figure(2, 1, figsize=(6.4, 5.6), sharex=True)
    omega = curves["omega"]
    ax_m.semilogx(omega, 20 * np.log10(np.abs(data.response)), "k-", lw=2.4, alpha=0.35,
                  label=r"$1/\sqrt{s}$")
    ax_p.semilogx(omega, np.rad2deg(np.angle(data.response)), "k-", lw=2.4, alpha=0.35)
    for k, (label, g) in enumerate(curves["response"].items()):
        st = _line_styles(k)
        ax_m.semilogx(omega, 20 * np.log10(np.abs(g)), label=label, **st)
        ax_p.semilogx(omega, np.rad2deg(np.unwrap(np.angle(g))), **st)
    ax_m.set_ylabel("magnitude (dB)")
    ax_p.set_ylabel("phase (degrees)")
    ax_p.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax_p.set_ylim(-100, 10)
    for ax in (ax_m, ax_p):
        plots._finish_axes(ax)
    ax_m.legend(loc="best", fontsize="small", framealpha=0.9)
    fig.suptitle(r"$1/\sqrt{s}$ and its rational approximations")
    return fig


def _fig_fractional_error(curves):
    from . import plots

    fig, ax = plots._new_figure(figsize=(7.2, 4.8))
    omega = curves["omega"]
    for k, (label, e) in enumerate(curves["closed_loop_error"].items()):
        ax.loglog(omega, e, label=f"{label} (max {np.max(e):.3g})", **_line_styles(k))
    ax.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax.set_ylabel(r"$E(j\omega) = |G_D - G_{N,\mathrm{closed\ loop}}|$")
    ax.set_title(r"closed loop $G_D = 1/(1 + \sqrt{s})$: error of each approximation")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


def _fig_moheimani_bode(curves, out):
    from . import plots

    fig, ax = plots._new_figure()
    omega = curves["omega"]
    for k, (label, lw) in enumerate((("truth", 2.0), ("G_r", 1.0), ("G_r + K_opt", 1.0))):
        name = f"{_MOHEIMANI_MODES}-mode model (truth)" if label == "truth" else \
            (f"{_MOHEIMANI_KEPT}-mode truncation $G_r$" if label == "G_r"
             else f"$G_r + K_{{opt}}$ ($K_{{opt}}$ = {out['k_opt']:.3g} m/N)")
        ax.loglog(omega, np.abs(curves[label]), label=name, **_line_styles(k))
    ax.axvline(out["omega_c"], color="0.3", ls=":", lw=0.9,
               label=rf"$\omega_c$ = {out['omega_c']:g} rad/s")
    ax.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax.set_ylabel("|G(jω)| (m/N)")
    ax.set_title("Moheimani's simply-supported beam")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


def _fig_moheimani_error(curves, out):
    from . import plots

    fig, ax = plots._new_figure()
    omega = curves["omega"]
    ax.loglog(omega, curves["error_without_k"], label=r"$|G - G_r|$ (without $K_{opt}$)",
              **_line_styles(1))
    ax.loglog(omega, curves["error_with_k"], label=r"$|G - G_r - K_{opt}|$ (with $K_{opt}$)",
              **_line_styles(2))
    ax.axvline(out["omega_c"], color="0.3", ls=":", lw=0.9,
               label=rf"$\omega_c$ = {out['omega_c']:g} rad/s")
    ax.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax.set_ylabel("absolute error (m/N)")
    ax.set_title("Moheimani's beam: truncation error with and without $K_{opt}$")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


# ----------------------------------------------------------------------------- the table


def _table(examples):
    """Table 4.1 as JSON: columns and rows (example, quantity, one value per column)."""
    rows = []
    for key, ex in examples.items():
        t = THESIS_TABLE_4_1[key]
        n_poles_thesis = t["order"] + (1 if ex["integrator"] else 0)
        thesis_nlls = {"n_poles": n_poles_thesis, "max_rel_error": t["nlls"],
                       "rms_rel_error": None, "n_rhp_zeros": 0, "n_rhp_poles": 0,
                       "delay": t["delay"], "wall_time": None}
        thesis_sub = {"n_poles": None, "max_rel_error": t["subspace"], "rms_rel_error": None,
                      "n_rhp_zeros": None, "n_rhp_poles": None, "delay": _NO_DELAY,
                      "wall_time": None}
        for q, label in TABLE_QUANTITIES:
            values = [thesis_nlls[q], thesis_sub[q]]
            values += [ex["methods"][m][q] for m in _METHOD_KEYS]
            rows.append({"example": key, "quantity": q, "label": label, "values": values})
    return {"columns": list(TABLE_COLUMNS), "rows": rows}


def _render_table(table):
    rows = [[r["example"], r["label"]] + [table_cell(v) for v in r["values"]]
            for r in table["rows"]]
    return markdown_table(rows, ["example", "quantity"] + table["columns"],
                          "ll" + "r" * len(table["columns"]))


# ----------------------------------------------------------------------------- Markdown


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


def _render(summary):
    s = summary
    lines = [generated_by_line(s["command"]), "",
             "# Reproduction of the thesis's chapter 4 (Table 4.1, figures 4.1–4.21)", ""]
    if s["quick"]:
        lines += ["**Quick mode**: small problems (windowed data, few sections) to test the "
                  "report; the numbers are NOT comparable with the thesis.", ""]
    lines += [f"Total wall time {table_cell(s['wall_time'])} s. Every number below is in "
              "`report.json` at full precision; the plotted curves are in `curves.json`.", ""]
    ex = s["examples"]
    if ex:
        lines += ["## Table 4.1", "",
                  "Max relative error = max over the data of |(G − G_N)/G_N| (thesis Table "
                  "4.1); RMS = the root mean square of the same curve (the thesis's MATLAB "
                  "`cost_func` returns the RMS, SPEC §5). Every method has as many poles as "
                  "our model: order of P_N, plus the integrator for A and C "
                  "(AAA may stop with fewer poles once its tolerance is met; the count "
                  "reached is in the table).", "",
                  _render_table(s["table_4_1"]), "",
                  f"\\* `{_NO_DELAY}`: the method cannot fit a delay; it fitted the data as "
                  "given (the delay stays in the data's phase and must be absorbed by the "
                  "rational model). The thesis gives no wall times, RMS errors or RHP counts "
                  "for its methods (its NLLS models are minimum phase by construction, hence "
                  "0); a dash marks a number the thesis does not state.", ""]
        lm = [f"{k}: {v['methods']['barrier-lm'].get('note', v['methods']['barrier-lm'])}"
              for k, v in ex.items() if v["methods"]["barrier-lm"]["status"] != "ok"]
        b = s["barrier_lm"]
        lines += [f"Barrier-LM (the thesis's method, SPEC §3): lm_options {b['options']}. "
                  f"It is included only if its fit of A finishes within "
                  f"{table_cell(b['time_limit_A'])} s; B and C then run with a cap of "
                  f"{table_cell(b['time_cap_B_C'])} s each"
                  + (f". Not run or stopped: {'; '.join(lm)}." if lm
                     else ". It finished on every example."), ""]

        lines += ["## Subspace: ours vs the thesis's", "",
                  markdown_table(
                      [[k, table_cell(THESIS_TABLE_4_1[k]["subspace"]),
                        table_cell(v["methods"]["subspace"]["max_rel_error"]),
                        table_cell(v["methods"]["subspace"]["n_poles"])]
                       for k, v in ex.items()],
                      ["example", "thesis subspace max rel. error",
                       "our subspace max rel. error", "poles"], "lrrr"), ""]

        lines += ["## Minimum phase (zeros of each model)", "",
                  "yes = no zero with Re > 0; in brackets the number of RHP zeros / RHP "
                  "poles. Ours are minimum phase and stable by construction (β ≥ 0).", ""]
        mrows = []
        for k, v in ex.items():
            row = [k]
            for m in _METHOD_KEYS:
                e = v["methods"][m]
                row.append(e["status"] if e["status"] != "ok" else
                           f"{table_cell(e['minimum_phase'])} ({e['n_rhp_zeros']} / "
                           f"{e['n_rhp_poles']})")
            mrows.append(row)
        lines += [markdown_table(mrows, ["example"] + [_METHOD_LABELS[m]
                                                       for m in _METHOD_KEYS]), ""]

        for k, v in ex.items():
            ours = v["methods"]["ipopt"]
            d = v["data"]
            lines += [f"## Example {k}", "",
                      f"Data: {d['name']}, {d['n_points']} points, {table_cell(d['omega_min'])}"
                      f" to {table_cell(d['omega_max'])} rad/s. Ours: {v['n_sections']} "
                      f"second-order sections (order of P_N {v['order_p_n']}), "
                      f"{'with' if v['integrator'] else 'no'} integrator, with delay; "
                      f"max rel. error {table_cell(ours['max_rel_error'])} "
                      f"(thesis {table_cell(v['thesis']['nlls'])}), delay "
                      f"{table_cell(ours['delay'])} s (true "
                      f"{table_cell(v['true_delay']) if v['true_delay'] else 'none in G'}, "
                      f"thesis {table_cell(v['thesis']['delay'])}), "
                      f"final stage converged: {table_cell(ours['success'])}.", "",
                      f"Hankel singular values of P_N: {len(v['hankel_singular_values_p_n'])}"
                      f", of which {v['hsv_above_1e-3']} above 1e-3 σ1 and "
                      f"{v['hsv_above_1e-6']} above 1e-6 σ1 (σ1 = "
                      f"{table_cell(v['hankel_singular_values_p_n'][0])}).", ""]
            prow = [[p, table_cell(e["max_rel_difference"]),
                     table_cell(e["fraction_of_points_above_model_error"])]
                    for p, e in v["perturbed"].items()]
            lines += [markdown_table(prow, ["perturbed plant", "max |G_pert/G − 1|",
                                            "fraction of points where it exceeds the "
                                            "model's error"], "lrr"), ""]
            for fig in _FIGURE_NOTES:
                fname = f"{k}_{fig}.png"
                if fname in s["figures"]:
                    tf = _THESIS_FIGS.get((k, fig))
                    note = _FIGURE_NOTES[fig] + (f" (thesis fig. {tf})" if tf else "")
                    lines += [f"![{note}]({fname})", "", f"*{fname}: {note}.*", ""]

    if s.get("fractional"):
        f = s["fractional"]
        lines += ["## 1/√s (thesis §4.2, figs 4.20–4.21)", "",
                  f"Data: 1/√s on {f['data']['n_points']} points, "
                  f"{table_cell(f['data']['omega_min'])} to "
                  f"{table_cell(f['data']['omega_max'])} rad/s. Ours: {f['n_sections']} "
                  "first-order sections, no delay; continued fraction (Matsuda & Fujii) of "
                  f"the same order; Newton process (Carlson & Halijak) with "
                  f"{f['newton_iterations']} iterations (orders are (3^k − 1)/2, the nearest "
                  "at or above ours); Fourier method (Gu, Khargonekar & Lee) of the same "
                  "order. E(jω) = |G_D − G_N/(1 + G_N)| with G_D = 1/(1 + √s).", ""]
        frows = [[label, table_cell(e["n_poles"]), table_cell(e["max_closed_loop_error"]),
                  table_cell(e["max_rel_error"]), table_cell(e["minimum_phase"]),
                  table_cell(e["wall_time"])] for label, e in f["methods"].items()]
        lines += [markdown_table(frows, ["method", "poles", "max E(jω)",
                                         "max rel. error (open loop)", "minimum phase",
                                         "wall time (s)"], "lrrrlr"), "",
                  "![1/√s and its approximations](fractional_bode.png)", "",
                  "*fractional_bode.png: 1/√s and the approximations (thesis fig. 4.20).*",
                  "",
                  "![closed-loop error](fractional_closed_loop_error.png)", "",
                  "*fractional_closed_loop_error.png: E(jω) for each method "
                  "(thesis fig. 4.21).*", ""]

    if s.get("moheimani"):
        m = s["moheimani"]
        lines += ["## Moheimani's beam with and without K_opt", "",
                  f"{m['n_modes']}-mode simply-supported beam as the truth, "
                  f"{m['n_kept']}-mode truncation G_r, ω_c = {table_cell(m['omega_c'])} rad/s "
                  "(SPEC §4).", "",
                  markdown_table([
                      ["K_opt, closed form (m/N)", table_cell(m["k_opt"])],
                      ["K from the data, (1/2ω_c) ∫ Re(G − G_r) dω (m/N)",
                       table_cell(m["k_from_data"])],
                      ["max |G − G_r| for ω ≤ ω_c (m/N)",
                       table_cell(m["max_abs_error_in_band_without_k"])],
                      ["max |G − G_r − K_opt| for ω ≤ ω_c (m/N)",
                       table_cell(m["max_abs_error_in_band_with_k"])],
                      ["RMS |G − G_r| for ω ≤ ω_c (m/N)",
                       table_cell(m["rms_abs_error_in_band_without_k"])],
                      ["RMS |G − G_r − K_opt| for ω ≤ ω_c (m/N)",
                       table_cell(m["rms_abs_error_in_band_with_k"])]],
                      ["quantity", "value"], "lr"), "",
                  "![beam](moheimani_bode.png)", "",
                  "*moheimani_bode.png: magnitude of the truth, G_r and G_r + K_opt.*", "",
                  "![beam error](moheimani_error.png)", "",
                  "*moheimani_error.png: |G − G_r| with and without K_opt.*", ""]

    lines += ["## Files", "", ", ".join(f"`{f}`" for f in s["files"]), ""]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- main entry


def _parse_examples(examples, quick):
    if examples is None:
        return ("A", "fractional", "moheimani") if quick else EXAMPLE_NAMES
    if isinstance(examples, str):
        examples = [e.strip() for e in examples.split(",") if e.strip()]
    examples = tuple(examples)
    bad = [e for e in examples if e not in EXAMPLE_NAMES]
    if bad or not examples:
        raise OptionError(f"examples must be a comma-separated subset of "
                          f"{','.join(EXAMPLE_NAMES)}, got {bad or examples!r}")
    return tuple(e for e in EXAMPLE_NAMES if e in examples)


def reproduce(out_dir, *, command, force=False, quick=False, examples=None):
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
        Small problems (example A windowed to 250 points with 3 sections; 1/sqrt(s) on 100
        points with 4 sections; short barrier-LM limit) for tests, finishing in about a
        minute. The numbers are not comparable with the thesis.
    examples : str or sequence of str, optional
        Subset of :data:`EXAMPLE_NAMES` (comma-separated string or sequence). Default: all;
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

    Notes
    -----
    SPEC §4-§6; thesis Table 4.1 and figures 4.1-4.21. Baselines use as many poles as our
    model (order of P_N, plus the integrator) and no delay (they fit the data as given).
    """
    t0 = time.perf_counter()
    path = check_out_dir(out_dir, force)            # before the long fits
    names = _parse_examples(examples, quick)
    cfg = _config(quick)
    from . import plots

    summary = {"format": REPRODUCE_FORMAT, "version": 1,
               "command": " ".join(str(command).split()), "quick": bool(quick),
               "examples_run": list(names),
               "barrier_lm": {"options": dict(BARRIER_LM_OPTIONS),
                              "time_limit_A": cfg.lm_time_limit,
                              "time_cap_B_C": cfg.lm_time_cap},
               "examples": {}, "fractional": None, "moheimani": None}
    all_curves = {}
    with report_folder(out_dir, force) as (tmp, _):
        figures = []

        def save(fig, name):
            plots.save_figure(fig, os.path.join(tmp, name))
            figures.append(name)

        lm_gate = {"skip": None}
        for key in (n for n in names if n in _SYSTEMS):
            out, curves, models, ours, data = _run_rational(key, cfg, lm_gate)
            summary["examples"][key] = out
            all_curves[key] = curves
            ours.model.save(os.path.join(tmp, f"{key}_model.json"))
            thesis_max = THESIS_TABLE_4_1[key]["nlls"]
            lm_res = curves["rel_error"].get("barrier-lm")
            save(plots.bode(ours, title=f"Example {key}: G and G_N (ours, IPOPT)"),
                 f"{key}_bode.png")
            save(_fig_rel_error(key, data, curves, thesis_max, lm_res), f"{key}_rel_error.png")
            save(plots.pole_zero(ours.model, zoom="auto"), f"{key}_pole_zero.png")
            save(_fig_hsv(key, out["hankel_singular_values_p_n"]), f"{key}_hsv.png")
            save(_fig_methods(key, curves["rel_error"], data.omega, thesis_max),
                 f"{key}_methods.png")
            if "subspace" in models:
                save(_fig_subspace_pz(key, models["subspace"]), f"{key}_subspace_pole_zero.png")
            save(_fig_perturbed(key, data.omega, curves["rel_error"]["ipopt"],
                                curves["perturbed"]), f"{key}_perturbed.png")
        if summary["examples"]:
            summary["table_4_1"] = _table(summary["examples"])
        if "fractional" in names:
            out, curves, data = _run_fractional(cfg)
            summary["fractional"] = out
            all_curves["fractional"] = curves
            save(_fig_fractional_bode(curves, data), "fractional_bode.png")
            save(_fig_fractional_error(curves), "fractional_closed_loop_error.png")
        if "moheimani" in names:
            out, curves = _run_moheimani()
            summary["moheimani"] = out
            all_curves["moheimani"] = curves
            save(_fig_moheimani_bode(curves, out), "moheimani_bode.png")
            save(_fig_moheimani_error(curves, out), "moheimani_error.png")

        summary["figures"] = figures
        summary["files"] = (["report.md", "report.json", "curves.json"]
                            + [f"{k}_model.json" for k in summary["examples"]] + figures)
        summary["wall_time"] = time.perf_counter() - t0
        summary = _clean(summary)
        atomic_write_text(os.path.join(tmp, "curves.json"),
                          json.dumps(_clean(_curves_json(all_curves)), allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.json"),
                          json.dumps(summary, indent=1, allow_nan=False) + "\n")
        atomic_write_text(os.path.join(tmp, "report.md"), _render(summary))
    log.info("report written to %s in %.0f s", path, summary["wall_time"])
    return summary


def _fig_rel_error(key, data, curves, thesis_max, lm_rel):
    from . import plots

    fig, ax = plots._new_figure()
    omega = data.omega
    rel = curves["rel_error"]["ipopt"]
    ax.loglog(omega, rel, color="C0", lw=1.3, label=f"ours, IPOPT (max {np.max(rel):.3g})")
    if lm_rel is not None:
        ax.loglog(omega, lm_rel, color="C1", lw=1.0, ls="--",
                  label=f"ours, barrier-LM (max {np.max(lm_rel):.3g})")
    ax.axhline(thesis_max, color="k", ls=":", lw=0.9, label=f"thesis NLLS max ({thesis_max})")
    ax.set_xlabel(r"frequency $\omega$ (rad/s)")
    ax.set_ylabel(r"relative error $|(G - G_N)/G_N|$")
    ax.set_title(f"Example {key}: relative error of our models")
    plots._finish_axes(ax)
    ax.legend(loc="best", fontsize="small", framealpha=0.9)
    return fig


def _curves_json(curves):
    """Complex arrays as {"real": ..., "imag": ...}; the rest as lists."""
    if isinstance(curves, dict):
        return {k: _curves_json(v) for k, v in curves.items()}
    arr = np.asarray(curves)
    if np.iscomplexobj(arr):
        return {"real": arr.real.tolist(), "imag": arr.imag.tolist()}
    return arr.tolist()


# ----------------------------------------------------------------------------- CLI


def _add_arguments(p):
    p.add_argument("--out", default=os.path.join("results", "thesis"), metavar="DIR",
                   help="report folder to create (default results/thesis; must not exist "
                        "unless --force)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing report folder (after the new one is complete)")
    p.add_argument("--quick", action="store_true",
                   help="tiny problems (about a minute) to test the report; numbers not "
                        "comparable with the thesis")
    p.add_argument("--examples", metavar="LIST",
                   help=f"comma-separated subset of {','.join(EXAMPLE_NAMES)} (default: all; "
                        "with --quick: A,fractional,moheimani)")
    return p


def add_cli(subparsers):
    """Add the ``reproduce`` command to an argparse subparsers object; return its parser.

    Options: ``--out DIR`` (default results/thesis), ``--force``, ``--quick``,
    ``--examples LIST``. Run it with :func:`run_cli`.
    """
    p = subparsers.add_parser(
        "reproduce", help="reproduce the thesis's Table 4.1 and figures 4.1-4.21",
        description="Fit the thesis's examples with our method and the baselines and write "
                    "a report folder (report.md, report.json, figures).")
    return _add_arguments(p)


def run_cli(args, command):
    """Run the ``reproduce`` command from parsed ``args``; print a summary; return 0.

    Errors (:class:`~freqid_casadi.errors.FreqidError`, ``OSError``) propagate to the caller,
    which reports them (``freqid`` prints one ``error:`` line and returns 2).
    """
    summary = reproduce(args.out, command=command, force=args.force, quick=args.quick,
                        examples=args.examples)
    for row in (summary.get("table_4_1") or {}).get("rows", []):
        if row["quantity"] == "max_rel_error":
            cells = ", ".join(f"{c}={table_cell(v)}"
                              for c, v in zip(summary["table_4_1"]["columns"], row["values"]))
            print(f"{row['example']}: max rel. error: {cells}")
    print(f"report: {os.path.abspath(args.out)} ({summary['wall_time']:.0f} s)")
    return 0


def main(argv=None, prog="scripts/reproduce_thesis.py"):
    """Entry point of ``scripts/reproduce_thesis.py``; returns the exit code.

    The first line of report.md is ``python <prog> <arguments>``. A FreqidError or OSError
    prints one ``error:`` line and returns 2.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _add_arguments(argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0]))
    args = parser.parse_args(argv)
    command = " ".join(["python", prog] + [shlex.quote(a) for a in argv])
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s",
                            stream=sys.stderr)
    try:
        return run_cli(args, command)
    except (FreqidError, OSError) as exc:
        sys.stderr.write(f"error: {' '.join(str(exc).split())}\n")
        return 2
