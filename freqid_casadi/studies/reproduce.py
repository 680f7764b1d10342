"""Reproduction of the thesis's chapter 4, the experiments (Table 4.1, figures 4.1-4.21).

:func:`run_reproduction` fits examples A, B and C at the thesis's orders with the package's
method (IPOPT) and, where it runs in time, the thesis's barrier + Levenberg-Marquardt; fits
the baselines of SPEC §6 (subspace, Fourier) and the unconstrained peers (AAA, vector
fitting) with as many poles as our model; fits ``1/sqrt(s)`` with first-order sections and
compares the closed loop with the continued-fraction and Newton-process approximations
(thesis §4.2); and corrects Moheimani's truncated beam model with K_opt. It returns a
:class:`Reproduction` of result dataclasses (numbers as JSON-ready dicts, curves, models);
the report folder (Markdown, JSON, figures) is
:mod:`freqid_casadi.studies.reproduce_report`.

Progress goes to the logger ``freqid_casadi.studies.reproduce`` (INFO).
"""

import logging
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .. import baselines, systems
from ..errors import FreqidError, OptionError
from ..systems.examples import EXAMPLES, FRACTIONAL_SECTIONS, TABLE_4_1
from ..fitting.fit import fit
from ..core.metrics import relative_error
from ..core.model import RationalDelayModel, Structure
from ..options import BarrierLMOptions

__all__ = ["run_reproduction", "Reproduction", "RationalExample", "FractionalStudy",
           "MoheimaniStudy", "parse_examples", "EXAMPLE_NAMES", "THESIS_TABLE_4_1",
           "TABLE_QUANTITIES", "METHOD_KEYS", "ORDERS", "NEWTON_ITERATIONS",
           "BARRIER_LM_OPTIONS", "BARRIER_LM_TIME_LIMIT", "BARRIER_LM_TIME_CAP", "NO_DELAY"]

log = logging.getLogger(__name__)

#: What :func:`run_reproduction` can run (``--examples``): the three beams/rod of Table 4.1,
#: the fractional example of thesis §4.2 and Moheimani's beam.
EXAMPLE_NAMES = ("A", "B", "C", "fractional", "moheimani")

#: Sections and integrator of our model per example (the thesis's orders of P_N: 34, 18, 54),
#: from the catalogue :data:`freqid_casadi.systems.examples.EXAMPLES`.
ORDERS = {k: (EXAMPLES[k].n_sections, EXAMPLES[k].integrator) for k in ("A", "B", "C")}

#: Thesis Table 4.1 (SPEC §5) as the report's JSON gives it: order of P_N, max rel. error of
#: its NLLS method and of the subspace method, its delay estimate (s).
THESIS_TABLE_4_1 = {k: dict(order=t.order, nlls=t.max_rel_error,
                            subspace=t.subspace_max_rel_error, delay=t.delay)
                    for k, t in TABLE_4_1.items()}

#: Iterations of the regular Newton process: orders are (3^k - 1)/2 = 1, 4, 13, 40, so
#: k = 3 (order 13) is the nearest order at or above FRACTIONAL_SECTIONS.
NEWTON_ITERATIONS = 3

#: Options of the barrier-LM fits (SPEC §3). The method is included only if its fit of A
#: finishes within BARRIER_LM_TIME_LIMIT seconds (else every example says "not run (time)");
#: B and C then run with the safety cap BARRIER_LM_TIME_CAP (s).
BARRIER_LM_OPTIONS = {"damping": "marquardt", "max_inner": 100}
BARRIER_LM_TIME_LIMIT = 240.0
BARRIER_LM_TIME_CAP = 900.0

#: Methods of Table 4.1 (JSON keys of ``methods``), after the thesis's two columns.
METHOD_KEYS = ("ipopt", "barrier-lm", "subspace", "fourier", "aaa", "vector-fitting")

#: Rows of Table 4.1 per example: (key in the method's JSON entry, label).
TABLE_QUANTITIES = (("n_poles", "poles (order, integrator incl.)"),
                    ("max_rel_error", "max rel. error"),
                    ("rms_rel_error", "RMS rel. error"),
                    ("n_rhp_zeros", "RHP zeros"),
                    ("n_rhp_poles", "RHP poles"),
                    ("delay", "delay h (s)"),
                    ("wall_time", "wall time (s)"))

#: How a method that cannot fit a delay shows its delay.
NO_DELAY = "none*"

# Moheimani's beam (SPEC §4): kept modes and bandwidth.
_MOHEIMANI_KEPT = 2
_MOHEIMANI_OMEGA_C = 100.0
_MOHEIMANI_MODES = 30


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


def _entry(model, data, wall_time, *, delay_fitted, extra=None):
    """Numbers of one method on one example (a JSON dict) and its rel. error curve."""
    err = relative_error(model, data)
    n_rhp_poles, n_rhp_zeros = baselines.count_rhp(model)
    entry = {
        "n_poles": int(np.asarray(model.poles()).size),
        "max_rel_error": err.max,
        "rms_rel_error": err.rms,
        "omega_at_max_rel_error": err.omega_at_max,
        "n_rhp_zeros": n_rhp_zeros,
        "n_rhp_poles": n_rhp_poles,
        "minimum_phase": bool(model.is_minimum_phase()),
        "stable": bool(model.is_stable()),
        "delay": float(model.delay) if delay_fitted else NO_DELAY,
        "wall_time": float(wall_time),
        "status": "ok",
    }
    entry.update(extra or {})
    return entry, err.values


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
        method = kw.get("method", "ipopt")      # a name, or an options object with its name
        log.info("  %s stage %d: %d sections, max rel. error %.3e, %.1f s",
                 getattr(method, "method", method), rec.stage, rec.n_sections,
                 rec.max_rel_error, time.perf_counter() - t0)
        if time.perf_counter() - t0 > limit:
            raise _TimeLimit(f"stopped after {time.perf_counter() - t0:.0f} s at stage "
                             f"{rec.stage}")

    try:
        kw = {"start": "sequential", **kw}      # the thesis's loop, stated
        return fit(data, progress=progress, **kw), time.perf_counter() - t0, None
    except _TimeLimit:
        return None, time.perf_counter() - t0, stages[-1]


def _timed(fun):
    t0 = time.perf_counter()
    return fun(), time.perf_counter() - t0


def _p_n(model):
    """P_N alone: the model's sections with gain 1, no integrator, no delay."""
    st = model.structure
    beta = np.concatenate([[0.0, 1.0], model.beta[2:]])
    return RationalDelayModel(Structure(st.n_sections, False, False, st.basis), beta)



@dataclass(frozen=True, eq=False)
class RationalExample:
    """Example A, B or C: our fits, the baselines, HSVs of P_N and the perturbed plants.

    Attributes
    ----------
    summary : dict
        JSON-ready numbers: ``data``, structure, ``true_delay`` (s), ``thesis`` (Table 4.1),
        ``methods`` (per method of :data:`METHOD_KEYS`: poles, max and RMS relative error,
        RHP zeros and poles, delay in s, wall time in s, status), Hankel singular values
        of P_N and the perturbed plants' differences.
    curves : dict
        ``omega`` (rad/s), ``rel_error`` per method and ``perturbed`` (|G_pert/G - 1|),
        each an ndarray of shape (M,).
    models : dict
        Method key -> fitted model (RationalDelayModel or a baseline's model).
    ours : FitResult
        Our IPOPT fit.
    data : FrequencyData
        The data fitted (windowed in quick mode).
    """

    summary: dict
    curves: dict
    models: dict
    ours: object
    data: object


@dataclass(frozen=True, eq=False)
class FractionalStudy:
    """1/sqrt(s) (thesis §4.2), our model and the classical approximations.

    Attributes
    ----------
    summary : dict
        JSON-ready numbers per method (poles, max closed-loop error E, max rel. error).
    curves : dict
        ``omega`` (rad/s); closed-loop error, relative error and response per method.
    data : FrequencyData
        1/sqrt(s) on the grid.
    """

    summary: dict
    curves: dict
    data: object


@dataclass(frozen=True, eq=False)
class MoheimaniStudy:
    """Moheimani's beam with and without K_opt.

    Attributes
    ----------
    summary : dict
        JSON-ready numbers (m/N): K_opt, K from the data, in-band errors.
    curves : dict
        ``omega`` (rad/s), the responses and the absolute errors.
    """

    summary: dict
    curves: dict


@dataclass(frozen=True, eq=False)
class Reproduction:
    """Everything :func:`run_reproduction` measured.

    Attributes
    ----------
    quick : bool
        Small problems (not comparable with the thesis).
    examples_run : tuple of str
        The parts run, in the order of :data:`EXAMPLE_NAMES`.
    barrier_lm : dict
        The barrier-LM's options and its time limits (s).
    examples : dict
        ``{"A": RationalExample, ...}`` for the examples of Table 4.1 that were run.
    fractional, moheimani : FractionalStudy or MoheimaniStudy, or None
    """

    quick: bool
    examples_run: tuple
    barrier_lm: dict
    examples: dict
    fractional: Optional[FractionalStudy]
    moheimani: Optional[MoheimaniStudy]


def _run_rational(key, cfg, lm_gate):
    """Example A, B or C (:class:`RationalExample`).

    ``lm_gate`` (a dict shared by the examples) holds ``"skip"``: why barrier-LM is not run
    (set when the fit of A exceeds ``cfg.lm_time_limit``), or None."""
    data = EXAMPLES[key].data()
    if cfg.window < data.n_points:
        data = data.window(cfg.window)
    n_sections, integrator = cfg.sections[key]
    out = {"data": {"name": data.name, "n_points": int(data.n_points),
                    "omega_min": float(data.omega[0]), "omega_max": float(data.omega[-1])},
           "n_sections": n_sections, "integrator": integrator,
           "order_p_n": 2 * n_sections, "true_delay": EXAMPLES[key].true_delay,
           "thesis": THESIS_TABLE_4_1[key], "methods": {}}
    curves = {"omega": data.omega, "rel_error": {}}
    models = {}

    log.info("%s: fit with IPOPT, %d sections", key, n_sections)
    ours = fit(data, n_sections=n_sections, integrator=integrator, delay=True, method="ipopt",
               start="sequential")
    entry, rel = _entry(ours.model, data, ours.wall_time, delay_fitted=True,
                        extra={"success": bool(ours.success), "nit": ours.nit})
    out["methods"]["ipopt"], curves["rel_error"]["ipopt"] = entry, rel
    models["ipopt"] = ours.model
    log.info("%s: IPOPT max rel. error %.4g in %.1f s", key, ours.max_rel_error, ours.wall_time)

    entry, rel, model = _run_barrier_lm(key, cfg, lm_gate, data, n_sections, integrator)
    out["methods"]["barrier-lm"] = entry
    if model is not None:
        curves["rel_error"]["barrier-lm"], models["barrier-lm"] = rel, model
    log.info("%s: barrier-LM %s", key, entry["max_rel_error"])

    _run_peers(key, cfg, data, ours.model.order, out, curves, models)

    hsv = baselines.hankel_singular_values(_p_n(ours.model))
    out["hankel_singular_values_p_n"] = hsv
    out["hsv_above_1e-3"] = int(np.count_nonzero(hsv > 1e-3 * hsv[0]))
    out["hsv_above_1e-6"] = int(np.count_nonzero(hsv > 1e-6 * hsv[0]))
    out["perturbed"], curves["perturbed"] = _perturbed(key, data, curves["rel_error"]["ipopt"])
    return RationalExample(out, curves, models, ours, data)


def _run_barrier_lm(key, cfg, lm_gate, data, n_sections, integrator):
    """The thesis's method on one example, time-limited: (JSON entry, rel. error curve or
    None, model or None)."""
    limit = cfg.lm_time_limit if key == "A" else cfg.lm_time_cap
    if lm_gate.get("skip"):
        entry = _not_run("not run (time)")
        entry["note"] = lm_gate["skip"]
        return entry, None, None
    log.info("%s: fit with barrier-LM (limit %.0f s)", key, limit)
    lm, elapsed, last = _fit_time_limited(
        data, limit, n_sections=n_sections, integrator=integrator, delay=True,
        method=BarrierLMOptions(**BARRIER_LM_OPTIONS))
    if lm is not None:
        entry, rel = _entry(lm.model, data, lm.wall_time, delay_fitted=True,
                            extra={"success": bool(lm.success), "nit": lm.nit,
                                   "time_limit": limit})
        return entry, rel, lm.model
    entry = _not_run("not run (time)" if key == "A" else "stopped (time)")
    entry["note"] = (f"stopped after {elapsed:.0f} s > limit {limit:.0f} s, at stage "
                     f"{last.stage} of {n_sections} with max rel. error "
                     f"{last.max_rel_error:.4g}")
    entry["elapsed"] = elapsed
    entry["last_stage"] = last.as_dict()
    if key == "A":
        lm_gate["skip"] = f"the barrier-LM fit of A did not finish within {limit:.0f} s"
    return entry, None, None


def _run_peers(key, cfg, data, n_poles, out, curves, models):
    """The baselines with ``n_poles`` poles (our model's order), into out/curves/models."""
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


def _perturbed(key, data, model_rel):
    """The thesis's perturbed plants (+5 %, +10 %) against the model's error: (JSON, curves)."""
    out, curves = {}, {}
    for pct in (5, 10):
        pert = systems.perturbed(key, pct, omega=data.omega)
        diff = np.abs(pert.response / data.response - 1.0)
        out[f"+{pct}%"] = {
            "max_rel_difference": float(np.max(diff)),
            "fraction_of_points_above_model_error": float(np.mean(diff > model_rel)),
        }
        curves[f"+{pct}%"] = diff
    return out, curves


def _run_fractional(cfg):
    """1/sqrt(s) (thesis §4.2): ours (first-order basis), continued fraction, Newton, Fourier;
    closed-loop error E = |G_D - G_N/(1 + G_N)| (:class:`FractionalStudy`)."""
    omega = systems.thesis_grid(cfg.fractional_points, 1e-5, 1e5)
    data = systems.sqrt_inverse(omega)
    g_d = systems.G_D(omega).response
    n = cfg.fractional_sections
    log.info("fractional: fit with IPOPT, %d first-order sections", n)
    ours = fit(data, n_sections=n, integrator=False, delay=False, basis="first-order",
               start="sequential")
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
        rel = relative_error(model, data).values
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
    return FractionalStudy(out, curves, data)


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
    return MoheimaniStudy(out, curves)


def parse_examples(examples, quick):
    """The parts to run, in the order of :data:`EXAMPLE_NAMES`.

    Parameters
    ----------
    examples : str, sequence of str or None
        A comma-separated string or a sequence of names of :data:`EXAMPLE_NAMES`; None:
        all, or with ``quick`` A, fractional and moheimani.
    quick : bool

    Returns
    -------
    tuple of str

    Raises
    ------
    OptionError
        If a name is unknown or none is given.
    """
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


def run_reproduction(examples=None, *, quick=False):
    """Run the thesis's comparisons.

    Parameters
    ----------
    examples : str or sequence of str, optional
        Subset of :data:`EXAMPLE_NAMES` (see :func:`parse_examples`). Default: all; with
        ``quick``: A, fractional and moheimani.
    quick : bool
        Small problems (example A windowed to 250 points with 3 sections; 1/sqrt(s) on 100
        points with 4 sections; short barrier-LM limit) for tests, finishing in about a
        minute. The numbers are not comparable with the thesis.

    Returns
    -------
    Reproduction

    Raises
    ------
    OptionError
        If ``examples`` names an unknown example.

    Notes
    -----
    SPEC §4-§6; thesis Table 4.1 and figures 4.1-4.21. Baselines use as many poles as our
    model (order of P_N, plus the integrator) and no delay (they fit the data as given).
    """
    names = parse_examples(examples, quick)
    cfg = _config(quick)
    lm_gate = {"skip": None}
    rational = {key: _run_rational(key, cfg, lm_gate) for key in names if key in ORDERS}
    return Reproduction(
        quick=bool(quick), examples_run=names,
        barrier_lm={"options": dict(BARRIER_LM_OPTIONS), "time_limit_A": cfg.lm_time_limit,
                    "time_cap_B_C": cfg.lm_time_cap},
        examples=rational,
        fractional=_run_fractional(cfg) if "fractional" in names else None,
        moheimani=_run_moheimani() if "moheimani" in names else None)
