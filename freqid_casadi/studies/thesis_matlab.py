"""The thesis's MATLAB code (Appendix A) transcribed line by line into numpy (issue 18).

Demir's thesis prints four files: ``main.m`` (the main loop), ``cost_and_coeffs.m`` (the
gain/delay stage ``integrator_cost_and_coeffs``, the section stage
``res_antires_cost_and_coeffs`` and the RMS ``cost_func``), ``create_jacob.m`` and
``tf_approx.m``. This module does what they do, quirks included, so that a reader can
tell whether the gap between the package's barrier-LM and Table 4.1 comes from the thesis's
method, from the package's corrections or from its settings. It is a study: it is not a
method of :func:`freqid_casadi.fit` and it does not use the package's objective or solvers.

Comments cite ``file l.N`` with the line numbers as printed in Appendix A of
``seeds/001_3cd26a8b62f7bdcb.txt``; the text extraction numbers a few wrapped continuation
lines (``cost_and_coeffs.m`` l.78-101 and l.221-250), so there a cited number can be one or
two above the file's own. Every place where the printed code is ambiguous, damaged or
cannot run as printed is listed in :data:`READINGS` with how it is read here.

Where the code differs from the method of the thesis's text (SPEC §3), the code wins here:
the residual subtracts ``sum(log(beta))`` from every complex residual (it is not the
barrier objective), ``create_jacob`` returns a matrix that is not the derivative of that
residual (:func:`create_jacob` lists the differences), and a SUMT pass keeps its last
*trial* point even when that trial was rejected.
"""

import logging
import os
import time
from dataclasses import dataclass

import numpy as np

from ..errors import OptionError, SolverError
from ..core.model import RationalDelayModel, Structure
from ._thesis_matlab_kernels import (
    coeffs_constraint, cost_func, create_jacob, first_factor, gain_ratio, grow_tol1,
    main_loop_continues, matlab_log, matlab_pinv, stage0_residual, stage0_windows,
    stage_residual, tf_approx, update_damping)
from ._thesis_matlab_stages import (
    SectionStage, _Budget, integrator_stage, new_section, res_antires_stage, stage0_start)

__all__ = [
    "run_thesis_matlab", "ThesisMatlabResult", "StageLog", "TABLE_4_1", "READINGS",
    "integrator_stage", "res_antires_stage", "tf_approx", "create_jacob", "cost_func",
    "stage0_residual", "stage_residual", "matlab_pinv", "gain_ratio", "update_damping",
    "grow_tol1", "stage0_windows", "main_loop_continues", "coeffs_constraint", "matlab_log",
    "first_factor", "stage0_start", "new_section", "SectionStage", "RESULTS_JSON",
    "transcription_rows", "transcription_lines",
]

log = logging.getLogger(__name__)

#: Table 4.1 of the thesis (SPEC §5): sections of the published model, integrator, the
#: published max relative error and delay. The MATLAB ``cost_func`` returns the RMS.
TABLE_4_1 = {
    "A": dict(n_sections=17, integrator=True, max_rel_error=0.2549, delay=0.0106),
    "B": dict(n_sections=9, integrator=False, max_rel_error=0.0027, delay=0.011),
    "C": dict(n_sections=27, integrator=True, max_rel_error=5.9884, delay=0.0261),
}

#: How the ambiguous, damaged or non-runnable lines of Appendix A are read:
#: ``(where, what is printed, how it is read here)``.
READINGS = (
    ("main.m l.2, create_jacob.m l.14, tf_approx.m l.8",
     "omega = logspace(-2, 3, 500) is a row, but create_jacob and tf_approx build columns "
     "(zeros(N,1), ones(N,1)) and concatenate the Jacobian columns horizontally",
     "every frequency vector is a column (omega(:)); the printed mix cannot run"),
    ("main.m l.29, l.25, l.56-58",
     "while (g < NN || cost_all > 1e-2) with cost_all = Inf and never assigned in the loop",
     "the printed loop never ends (NN = 9 has no effect); the author must have stopped it "
     "by hand, so it is stopped when g reaches the Table 4.1 number of sections"),
    ("main.m l.40, l.43",
     "cost_and_coeffs_n_noint and tf_approx_noint are called but not printed, also in the "
     "G_A configuration whose stage 0 (l.7, l.11) fits K0/s",
     "with an integrator the loop uses the printed cost_and_coeffs_n / tf_approx (else l.43 "
     "would drop the 1/s fitted at l.7); without one the _noint files are the printed ones "
     "with the first factor exp(-h s) K instead of exp(-h s) K/s, and stage 0 starts at "
     "K = |Phi_1| (the printed |Phi_1 j s_1| = |Phi_1| omega_1 is K0 of K0/s)"),
    ("cost_and_coeffs.m l.41",
     "beta_i_1 = [0. abs(Hi_u(1)*1j*s_(1)) 0 0 0 0]' (six entries)",
     "two entries [0; |Phi_1| omega_1]: l.121 appends four zeros to make the 6-row column "
     "of [h K 0 0 0 0], and with six entries create_jacob takes its section branch (l.51) "
     "with a 0/0 section and pinv stops on NaN"),
    ("main.m l.33",
     "find(abs(H_err) == max(abs(H_err))) can return several indices",
     "the first (lowest-frequency) one; ties do not occur on the benchmark data"),
    ("cost_and_coeffs.m l.147-152, l.296-297",
     "while (Ni+ni <= n+1) with n = w_maxerr (a frequency, main.m l.40)",
     "runs exactly once (Ni = 1, ni = n); the window is 1..w_index_pre (l.156-164)"),
    ("cost_and_coeffs.m l.206-232, l.301",
     "beta_i_2_all is first assigned at l.232 inside the loop but read at l.301",
     "if a barrier problem stops before its first trial step, beta_i_2_all is the pass's "
     "start. MATLAB variables live for the whole call, so there it would be the previous "
     "pass's beta_i_2_all, which is the same vector (l.301-304 built this pass's start from "
     "it); only in a stage's first pass would MATLAB stop on an undefined variable (a pass "
     "with 2 or more iterations made a trial: see pass_nit)"),
    ("cost_and_coeffs.m l.313-325",
     "a negative coefficient or a section with zeta_d + omega_d = 0 returns coeffs = NaN, "
     "which main.m l.43 would then evaluate (NaN model, empty find at l.33: no way on)",
     "the main loop stops there, keeps the previous stage's model and reports status "
     "'nan-coefficients' naming the coefficient"),
    ("cost_and_coeffs.m l.72, l.225",
     "pinv(...) of a matrix with Inf/NaN stops MATLAB with an error",
     "SolverError; the main loop stops with status 'error' and keeps the last good model"),
    ("cost_and_coeffs.m l.199-202, l.217-224, l.276-283, main.m l.41, l.58",
     "bare expressions (4, 55, A, 6, 7, coeffs2, mu;) that only print",
     "omitted (no effect on the numbers)"),
    ("cost_and_coeffs.m l.55, l.195 and everywhere log(beta) is taken",
     "log of a negative coefficient is complex in MATLAB; only h is clipped to 0 (l.234)",
     "matlab_log: complex log, so a trial with a negative coefficient is scored as MATLAB "
     "scores it"),
)


@dataclass(frozen=True)
class StageLog:
    """One stage of the main loop (stage 0: gain and delay).

    Attributes
    ----------
    stage : int
        0 for ``integrator_stage``, else ``g`` after the stage (main.m l.56).
    window : int
        Last data index (1-based) the stage fitted on.
    omega_c : float
        ``w_maxerr`` (rad/s) where the new section was placed (NaN for stage 0).
    nit : int
        LM iterations of the stage.
    wall_time : float
        Seconds (noisy on a loaded machine).
    max_rel_error, rms_rel_error : float
        Over all data after the stage.
    cost : float
        The stage's own ``cost_func`` (RMS relative error on its window).
    capped : bool
        Whether an iteration or time cap (not in the printed code) stopped an LM loop.
    pass_nit : tuple of int
        Iterations of each barrier problem t = 1, 20, ..., 20^9 (stage 0: one entry, the
        three windows together).
    tol1 : float
        tol1 at the end of the stage (NaN for stage 0).
    """

    stage: int
    window: int
    omega_c: float
    nit: int
    wall_time: float
    max_rel_error: float
    rms_rel_error: float
    cost: float
    capped: bool
    pass_nit: tuple
    tol1: float


@dataclass(frozen=True, eq=False)
class ThesisMatlabResult:
    """Result of :func:`run_thesis_matlab`.

    Attributes
    ----------
    model : RationalDelayModel or None
        The coefficients as a model (same beta ``[h, K, theta_1..theta_N]``), None if a
        coefficient is negative or not finite.
    coeffs : ndarray of float, shape (6, N + 1)
        The MATLAB ``coeffs_all``: column 1 ``[h K 0 0 0 0]``, then one column per section.
    rel_error : ndarray of float, shape (M,)
        ``|(G - G_aprx)/G_aprx|`` over all data (main.m l.31).
    max_rel_error, rms_rel_error : float
        Max (Table 4.1's measure) and RMS (``cost_func`` over all data) of ``rel_error``.
    delay, gain : float
        h (s) and K (K0 of K0/s with an integrator).
    n_sections : int
        Sections fitted.
    nit : int
        LM iterations over all stages.
    wall_time : float
        Seconds.
    history : tuple of StageLog
    status : str
        ``"stopped-at-n-sections"`` (the printed loop never ends, see READINGS),
        ``"time-budget"``, ``"nan-coefficients"`` (cost_and_coeffs.m l.313-325) or ``"error"``.
    message : str
    max_inner, time_budget : int or None, float or None
        The caps used (None: as printed).
    last_point : str
        ``"trial"`` (as printed) or ``"accepted"`` (deviation study).
    n_capped : int
        LM loops stopped by ``max_inner``.
    """

    model: object
    coeffs: np.ndarray
    rel_error: np.ndarray
    max_rel_error: float
    rms_rel_error: float
    delay: float
    gain: float
    n_sections: int
    nit: int
    wall_time: float
    history: tuple
    status: str
    message: str
    max_inner: object
    time_budget: object
    last_point: str
    n_capped: int


def _check(data, n_sections, max_inner, time_budget, NN):
    for name, value in (("n_sections", n_sections), ("NN", NN)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise OptionError(f"{name} must be an integer >= 0, got {value!r}")
    if max_inner is not None and (isinstance(max_inner, bool) or not isinstance(
            max_inner, (int, np.integer)) or max_inner < 1):
        raise OptionError(f"max_inner must be None or an integer >= 1, got {max_inner!r}; "
                          "None runs the LM loops as printed")
    if time_budget is not None and not (np.isfinite(time_budget) and time_budget > 0):
        raise OptionError(f"time_budget must be None or > 0 seconds, got {time_budget!r}")
    if not hasattr(data, "omega") or not hasattr(data, "response"):
        raise OptionError(f"data must be a FrequencyData, got {type(data).__name__}")


def _to_model(coeffs, integrator):
    beta = np.concatenate([coeffs[:2, 0], coeffs[:, 1:].reshape(-1, order="F")])
    if not np.all(np.isfinite(beta)) or np.any(beta < 0):
        return None
    return RationalDelayModel(Structure(coeffs.shape[1] - 1, integrator, True), beta)


def _stage_log(stage, window, omega_c, pass_nit, t0, H, G_aprx, cost, capped, tol1):
    err = np.abs((H - G_aprx) / G_aprx)
    return StageLog(stage, int(window), float(omega_c), int(sum(pass_nit)),
                    time.perf_counter() - t0, float(np.max(err)), float(np.sqrt(np.mean(err**2))),
                    float(cost), capped, tuple(int(k) for k in pass_nit), float(tol1))


def run_thesis_matlab(data, *, n_sections, integrator, NN=9, max_inner=None, time_budget=None,
                      last_point="trial"):
    """Run the transcribed Appendix A on ``data`` (main.m with cost_and_coeffs.m).

    Parameters
    ----------
    data : FrequencyData
        M points, omega in rad/s increasing.
    n_sections : int
        Sections at which the main loop is stopped (the printed ``while`` never ends, see
        :data:`READINGS`); Table 4.1: A 17, B 9, C 27.
    integrator : bool
        Model ``exp(-h s) K0/s P_N`` (printed code) or ``exp(-h s) K P_N`` (_noint files).
    NN : int, optional
        main.m l.26 (9). Has no effect as printed (``cost_all`` stays Inf).
    max_inner : int, optional
        Cap on the iterations of each LM loop (one stage-0 window or one barrier problem).
        None (default) runs them as printed, stopped only by their tests and the tenfold
        growth of tol1 every 1000 iterations.
    time_budget : float, optional
        Seconds; once exceeded the running LM loop stops and no further section is added
        (status ``"time-budget"``). None: no limit.
    last_point : {"trial", "accepted"}, optional
        ``"trial"`` (default, as printed): an LM loop hands on its last trial point
        (cost_and_coeffs.m l.121 reads ``beta_i_1``, l.301 ``beta_i_2_all``), even when that
        trial was rejected. ``"accepted"`` is a one-line deviation for study: hand on the
        last accepted point (``beta_i`` / ``beta_i_all``).

    Returns
    -------
    ThesisMatlabResult

    Raises
    ------
    OptionError
        For an invalid ``n_sections``, ``NN``, ``max_inner``, ``time_budget`` or ``data``.
    """
    _check(data, n_sections, max_inner, time_budget, NN)
    if last_point not in ("trial", "accepted"):
        raise OptionError(f"last_point must be 'trial' (as printed) or 'accepted', "
                          f"got {last_point!r}")
    with _single_threaded_blas():
        return _run(data, n_sections, integrator, NN, _Budget(max_inner, time_budget, last_point))


def _single_threaded_blas():
    """BLAS on one thread: the matrices are small and threaded OpenBLAS oversubscribes a
    loaded machine (``real(Jr'*Jr)`` measured 11 ms per call instead of ~0.1 ms)."""
    import scipy.linalg  # noqa: F401  (load scipy's BLAS so that the limit applies to it)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _run(data, n_sections, integrator, NN, budget):
    """The body of :func:`run_thesis_matlab` (main.m l.1-60)."""
    H = np.asarray(data.response, dtype=complex)                        # columns: READINGS
    omega = np.asarray(data.omega, dtype=float)                         # main.m l.2
    t_run = time.perf_counter()
    t0 = time.perf_counter()
    cost, coeffs2, _, nit = integrator_stage(H, omega, 1, 5, integrator=integrator,
                                             budget=budget)             # main.m l.7
    s_ = 1j * omega                                                     # main.m l.9
    G_aprx = tf_approx(s_, coeffs2, None, integrator)                   # main.m l.11
    history = [_stage_log(0, 5, np.nan, (nit,), t0, H, G_aprx, cost, budget.hit is not None,
                          np.nan)]
    cost_all, g, w_index_pre = np.inf, 0, 0                             # main.m l.24-28
    status, message = "stopped-at-n-sections", ""
    while main_loop_continues(g, cost_all, NN) and g < n_sections:     # main.m l.29
        if budget.out_of_time:
            status, message = "time-budget", f"time budget {budget.time_budget} s reached"
            break
        t0, budget.hit = time.perf_counter(), None
        H_err = (H - G_aprx) / G_aprx                                   # main.m l.31
        w_maxerr_index = int(np.nanargmax(np.abs(H_err))) + 1           # main.m l.33
        w_maxerr = omega[w_maxerr_index - 1]                            # main.m l.34
        w_index_pre = max(w_index_pre, w_maxerr_index)                  # main.m l.36-38
        try:
            out = res_antires_stage(H, omega, w_index_pre, w_maxerr, coeffs2,
                                    integrator=integrator, budget=budget)
        except SolverError as exc:                                      # see READINGS
            status, message = "error", f"stage {g + 1}: {exc}"
            break
        nit += out.nit
        if out.rejected:                                                # l.313-325
            status = "nan-coefficients"
            message = (f"stage {g + 1} (window {w_index_pre}, omega_c {w_maxerr:.4g} rad/s, "
                       f"{out.nit} iterations): cost_and_coeffs returns NaN: {out.rejected}; "
                       f"the model of stage {g} is kept")
            break
        coeffs2 = out.coeffs                                            # main.m l.40
        G_aprx = tf_approx(s_, coeffs2, None, integrator)               # main.m l.43
        g += 1                                                          # main.m l.56
        history.append(_stage_log(g, w_index_pre, w_maxerr, out.pass_nit, t0, H, G_aprx,
                                  out.cost, budget.hit is not None, out.tol1))
        log.info("stage %d: window %d, max rel. error %.4g, %d iterations %s", g, w_index_pre,
                 history[-1].max_rel_error, out.nit, out.pass_nit)
    return _result(coeffs2, H, G_aprx, integrator, nit, t_run, history, status, message,
                   budget)


def _result(coeffs, H, G_aprx, integrator, nit, t_run, history, status, message, budget):
    rel = np.abs((H - G_aprx) / G_aprx)
    if status == "stopped-at-n-sections":
        message = (f"stopped at {coeffs.shape[1] - 1} sections: the printed main loop "
                   "(main.m l.29) never ends")
    return ThesisMatlabResult(
        model=_to_model(coeffs, integrator), coeffs=coeffs, rel_error=rel,
        max_rel_error=float(np.max(rel)), rms_rel_error=cost_func(H, G_aprx),
        delay=float(coeffs[0, 0]), gain=float(coeffs[1, 0]), n_sections=coeffs.shape[1] - 1,
        nit=int(nit), wall_time=time.perf_counter() - t_run, history=tuple(history),
        status=status, message=message, max_inner=budget.max_inner, time_budget=budget.time_budget,
        last_point=budget.last_point, n_capped=budget.n_capped)


#: Where ``scripts/thesis_matlab.py`` writes the transcription's numbers (from the
#: repository root), read by the reproduction and ablation reports.
RESULTS_JSON = os.path.join("results", "thesis_matlab", "thesis_matlab.json")


def transcription_rows(path=RESULTS_JSON):
    """The transcription's numbers per example, read from the report of
    ``python scripts/thesis_matlab.py`` (a run takes about 20 minutes), for other reports.

    Parameters
    ----------
    path : str
        The ``thesis_matlab.json`` file.

    Returns
    -------
    dict or None
        ``{"command": str, "rows": {example: {n_sections, max_rel_error, rms_rel_error,
        delay, iterations, wall_time, status, published_max_rel_error}}}``; None when the
        file is absent or not readable.
    """
    import json

    try:
        with open(path, encoding="utf-8") as fh:
            d = json.load(fh)
        rows = {}
        for key, ex in d["examples"].items():
            t = ex["transcription"]
            rows[key] = {k: t.get(k) for k in ("n_sections", "max_rel_error", "rms_rel_error",
                                               "delay", "iterations", "wall_time", "status")}
            rows[key]["published_max_rel_error"] = TABLE_4_1[key]["max_rel_error"]
        return {"command": d["command"], "rows": rows}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def transcription_lines(info, ours=None):
    """Markdown section of the transcription's rows beside the published numbers (and
    ours: ``{example: max_rel_error}``), with a conclusion computed from them.

    Parameters
    ----------
    info : dict or None
        :func:`transcription_rows`.
    ours : dict, optional
        Our max relative error per example.

    Returns
    -------
    list of str
    """
    from ..report.formatting import markdown_table, number

    head = ["## The thesis's own MATLAB code (Appendix A, transcribed)", ""]
    if not info:
        return head + ["Not available here: run `python scripts/thesis_matlab.py` "
                       "(`results/thesis_matlab/`, about 20 minutes).", ""]
    ours = ours or {}
    rows, repro = [], []
    for key, r in info["rows"].items():
        ok = (r["max_rel_error"] is not None and r["n_sections"] == TABLE_4_1[key]["n_sections"]
              and r["max_rel_error"] <= r["published_max_rel_error"])
        repro.append(key) if ok else None
        rows.append((key, number(r["published_max_rel_error"]), number(r["max_rel_error"]),
                     number(r["rms_rel_error"]), f"{r['n_sections']} / "
                     f"{TABLE_4_1[key]['n_sections']}", number(r["delay"], 6),
                     number(r["iterations"]), number(ours.get(key)),
                     "yes" if ok else "NO"))
    table = markdown_table(rows, ("example", "published max", "transcription max",
                                  "transcription RMS", "sections reached", "delay (s)",
                                  "LM iterations", "ours (IPOPT) max", "reproduces"),
                           "lrrrlrrrl")
    return head + [f"From `{info['command']}` (`results/thesis_matlab/report.md`).", "", table,
                   "", f"The printed algorithm reproduces {len(repro)} of {len(rows)} "
                   f"published rows ({', '.join(repro) or 'none'}).", ""]
