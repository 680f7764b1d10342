"""The sequential main loop, the rational start and the minimax polish (layer L4).

Stage 0 fits the gain (K0 with an integrator) and the delay on a growing low-frequency
window. Stage N appends one section at the frequency of the largest relative error over all
data, grows the window to cover that point, and re-fits all parameters on the window,
warm-started from stage N-1. A last stage fits the full model on all data (SPEC §2). The
rational start fits all sections at once and polishes them; the minimax polish lowers the
max relative error by a continuation in p of the p-norm. Each returns what
:func:`~freqid_casadi.fitting.fit.fit` assembles into a FitResult.
"""

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from .. import _interrupt
from ..core.data import FrequencyData
from ..core.model import Structure
from ..core.objective import Parametrization, stage_functions
from ..options import LoopOptions
from ..solvers.common import StageResult, Status, find_active_constraints
from .stages import (Kept, StageKind, model_ratio, polish, polish_start, solver_timing,
                     stage_cost, stage_record, keep_better)

__all__ = ["LoopContext", "sequential", "rational", "minimax", "start_record", "PNORM_SCHEDULE"]

@dataclass(frozen=True)
class LoopContext:
    """What the loops share.

    Attributes
    ----------
    data : FrequencyData
    callback : callable
        Receives each StageRecord.
    solve : StageSolver
    structure : Structure
    loop : LoopOptions
    warm_start : {"primal-dual", "primal", "none"}
    delay_max : float
        Upper bound of the delay, s.
    final_max_iter : int
    zeta_min : float or None
        Damping floor.
    """

    data: FrequencyData
    callback: object
    solve: object
    structure: Structure
    loop: LoopOptions
    warm_start: str
    delay_max: float
    final_max_iter: int
    zeta_min: object = None


def _gain_delay_stage(ctx):
    """Stage 0: the gain and the delay on a growing low-frequency window (thesis: 1..5
    points). Returns (param, z, lam, record)."""
    data, st = ctx.data, ctx.structure
    omega, phi = data.omega, data.response
    k = st.origin_order
    gain0 = abs(phi[0]) * (omega[0] if k == 1 else float(omega[0]) ** k if k else 1.0)
    param = Parametrization(st.with_sections(0), ctx.loop.gauge, (), gain0, ctx.delay_max,
                            ctx.loop.scaled)
    z = np.zeros(param.n_vars)
    z[1] = gain0 / param._refs()[1]
    lam = np.zeros(param.n_vars)
    l0 = min(5, data.n_points)
    t0 = time.perf_counter()
    nit = nfev = 0
    solves = []
    for length in range(1, l0 + 1):
        res = ctx.solve(param, data.window(length), z, lam)
        solves.append(res)
        nit, nfev = nit + res.nit, nfev + res.nfev
        z, lam = keep_better(param, data.window(length), z, lam, res)[:2]
    record = stage_record(0, param, z, data, l0, math.nan, res, nit, nfev,
                          time.perf_counter() - t0, Kept.SOLUTION, StageKind.GAIN_DELAY,
                          solver_timing(solves))
    return param, z, lam, record


def sequential(ctx, tol):
    """The thesis's main loop (SPEC §2).

    Parameters
    ----------
    ctx : LoopContext
    tol : float or None
        Stop adding sections once the max relative error is below ``tol``.

    Returns
    -------
    param : Parametrization
    z, lam : ndarray of float
        The final variables and bound multipliers.
    records : list of StageRecord
    """
    data, solve, callback = ctx.data, ctx.solve, ctx.callback
    init, scale_l, final_stage = ctx.loop.init, ctx.loop.scale_l, ctx.loop.final_stage
    warm_start = ctx.warm_start
    omega, phi = data.omega, data.response
    m = data.n_points
    st = ctx.structure
    param, z, lam, record = _gain_delay_stage(ctx)
    records = [record]
    callback(record)
    l0 = record.window
    window = l0
    init_z = z.copy()
    stall = _stall_rule(init)

    # ---- stages 1..N: one section per stage at the largest error
    for n in range(1, st.n_sections + 1):
        err = np.abs(model_ratio(param, z, omega, phi) - 1.0)
        if tol is not None and np.max(err) < tol:
            break
        idx = int(np.argmax(err))
        omega_c = float(omega[idx])
        window = max(idx + 1, window)
        new_param = param.extend(omega_c)
        window = min(m, max(window, new_param.n_vars))
        new_sec = _new_section(new_param, init, scale_l, omega, phi, err, idx, z, param)
        ident = new_param.new_section(omega_c, 0.5, omega_c, 0.5, omega_c)
        prev_ext = np.concatenate([z, ident])
        z_prev = z
        z_start = np.concatenate([z if warm_start != "none" else _cold_start(init_z, param, z),
                                  new_sec])
        lam_start = np.concatenate([lam, np.zeros(new_sec.size)])
        if ctx.zeta_min is not None:
            z_start = new_param.project_damping(z_start, ctx.zeta_min)
        param = new_param
        if init == "relocate":
            param, z_start, lam_start = _relocate(param, data.window(window), z_start,
                                                  lam_start, ctx.zeta_min)
            prev_ext = _convert(new_param, param, prev_ext)
        wdata = data.window(window)
        t0 = time.perf_counter()
        res = solve(param, wdata, z_start, lam_start if warm_start == "primal-dual" else None,
                    **stall)
        nit, nfev = res.nit, res.nfev
        if res.status == Status.STALLED and _max_window_error(param, data, res.x) >= 1.0:
            # the stall rule is for the creep near a fit (the next relocation re-places the
            # sections); a model still worse than the infinite-gain one somewhere on the
            # data goes on as "peak" does (example B: 0.519 with the stall here, 0.331
            # without; A unchanged; C 1550 instead of 1215 its, 9.2e-7 vs 8.8e-7)
            res = solve(param, wdata, res.x, res.lam_x if warm_start == "primal-dual" else None)
            nit, nfev = nit + res.nit, nfev + res.nfev
        z, lam, kept = keep_better(param, wdata, z_start, lam_start, res, prev_ext)
        if init != "identity" and _max_window_error(param, wdata, z) >= 1.0:
            # worse than the infinite-gain model (relative error 1) on the window: a local
            # minimum of the peak placement; retry from the thesis's identity section
            z_id = _convert(new_param, param, np.concatenate([z_prev, ident]))
            if ctx.zeta_min is not None:
                z_id = param.project_damping(z_id, ctx.zeta_min)
            res_id = solve(param, wdata, z_id,
                           lam_start if warm_start == "primal-dual" else None, **stall)
            nit, nfev = nit + res_id.nit, nfev + res_id.nfev
            if stage_cost(param, wdata, res_id.x) < stage_cost(param, wdata, z):
                res, z, lam = res_id, res_id.x.copy(), res_id.lam_x.copy()
                kept = Kept.IDENTITY_RETRY
        records.append(stage_record(n, param, z, data, window, omega_c, res, nit, nfev,
                                    time.perf_counter() - t0, kept, StageKind.SECTION))
        callback(records[-1])

    # ---- final stage on all data
    if final_stage and (window < m or not records[-1].success):
        t0 = time.perf_counter()
        res = solve(param, data, z, lam if warm_start == "primal-dual" else None,
                    max_iter=ctx.final_max_iter, final=True)
        z, lam, kept = keep_better(param, data, z, lam, res)
        records.append(stage_record(param.structure.n_sections + 1, param, z, data, m,
                                    math.nan, res, res.nit, res.nfev,
                                    time.perf_counter() - t0, kept, StageKind.FINAL))
        callback(records[-1])
    return param, z, lam, records


def rational(ctx, delay0):
    """Global start (:mod:`freqid_casadi.fitting.start`) polished by one stage on all data
    (:func:`~freqid_casadi.fitting.stages.polish`).

    Parameters
    ----------
    ctx : LoopContext
    delay0 : float
        First trial delay of the rational start (s).

    Returns
    -------
    param, z, lam, records
        As :func:`sequential`.

    Raises
    ------
    RationalStartError
        Vector fitting gave no usable model.
    """
    from .start import rational_start

    data, st = ctx.data, ctx.structure
    t0 = time.perf_counter()
    rs = rational_start(data, st, delay_max=ctx.delay_max, delay0=delay0)
    records = [start_record(ctx, rs.model, 0, int(rs.delays.size), "rational start", t0)]
    ctx.callback(records[-1])
    pol, rec = polish_record(ctx, rs.model, StageKind.FINAL)
    return pol.param, pol.x, pol.lam_x, records + [rec]


def polish_record(ctx, model, kind):
    """Polish ``model`` on all of the fit's data (one stage, the final stage's iteration
    limit) and report its record (stage ``n_sections + 1``, of kind ``kind``).

    Parameters
    ----------
    ctx : LoopContext
    model : RationalDelayModel
    kind : StageKind

    Returns
    -------
    (PolishResult, StageRecord)
    """
    data, t0 = ctx.data, time.perf_counter()
    pol = polish(model, data, method=ctx.solve.solver, max_iter=ctx.final_max_iter,
                 loop=ctx.loop, delay_max=ctx.delay_max, zeta_min=ctx.zeta_min)
    res = pol.result
    rec = stage_record(model.n_sections + 1, pol.param, pol.x, data, data.n_points, math.nan,
                       res, res.nit, res.nfev, time.perf_counter() - t0, pol.kept, kind)
    ctx.callback(rec)
    return pol, rec


def start_record(ctx, model, stage, n_trials, message, t0):
    """The record of a vector-fitting start (no solve).

    Parameters
    ----------
    ctx : LoopContext
    model : RationalDelayModel
        The start, recorded in the polish's variables (:func:`~.stages.polish_start`).
    stage : int
        The record's stage number.
    n_trials : int
        Vector fits made (the record's iterations and evaluations).
    message : str
    t0 : float
        ``time.perf_counter()`` when the vector fits began.

    Returns
    -------
    StageRecord
        Of kind ``StageKind.RATIONAL_START``.
    """
    param, z0 = polish_start(model, ctx.data, loop=ctx.loop, delay_max=ctx.delay_max,
                             zeta_min=ctx.zeta_min)
    lb, ub = param.bounds()
    wall = time.perf_counter() - t0
    res0 = StageResult(x=z0, cost=np.nan, status=Status.CONVERGED, message=message,
                       success=True, nit=n_trials, nfev=n_trials, wall_time=wall,
                       active_mask=find_active_constraints(z0, lb, ub),
                       lam_x=np.zeros_like(z0), solver_status="vector-fitting")
    return stage_record(stage, param, z0, ctx.data, ctx.data.n_points, math.nan, res0,
                        n_trials, n_trials, wall, Kept.START, StageKind.RATIONAL_START)


#: The p of the minimax polish's p-norm stages.
PNORM_SCHEDULE = (4, 8, 16, 32, 64, 128, 256, 512, 1024)


def minimax(ctx, param, z):
    """Polish of the max relative error by a continuation in p of the p-norm of the
    residuals (:func:`~freqid_casadi.solvers.ipopt.solve_pnorm`, p = 4 ... 1024, each an
    IPOPT NLP with true bounds started from the last), keeping the point with the lowest
    max error. Kept only if it lowers the max error and the start is below 1 (an
    infinite-gain model has relative error exactly 1 everywhere, the trap of a minimax
    stage started above 1).

    Parameters
    ----------
    ctx : LoopContext
    param : Parametrization
    z : ndarray of float, shape (param.n_vars,)
        The least-squares model's variables.

    Returns
    -------
    z : ndarray of float
        The kept variables.
    record : StageRecord
    """
    from ..solvers.ipopt import solve_pnorm

    data = ctx.data
    with _interrupt.guard():        # CasADi expressions: see stages.StageSolver.__call__
        funcs = stage_functions(param, data.omega, data.response, data.weights)
        cons = None
        if ctx.zeta_min is not None and param.structure.n_sections:
            cons = param.damping_constraints(ctx.zeta_min)
    lb, ub = param.bounds()

    def max_err(x):
        return float(np.max(param.to_model(x).relative_error(data)))

    before = max_err(z)
    t0 = time.perf_counter()
    best_x, best_e, best_p = z, before, None
    x, nit, nfev, res = z, 0, 0, None
    for p in PNORM_SCHEDULE:
        with _interrupt.guard():
            res = solve_pnorm(funcs, x, lb, ub, p, max_iter=ctx.final_max_iter,
                              constraints=cons)
        nit, nfev = nit + res.nit, nfev + res.nfev
        if res.status == Status.ERROR:
            break
        x = res.x if cons is None else param.project_damping(res.x, ctx.zeta_min)
        e = max_err(x)
        if np.isfinite(e) and e < best_e:
            best_x, best_e, best_p = x, e, p
    ok = before < 1.0 and best_p is not None and best_e < before
    z_new = best_x if ok else z
    res = dataclasses.replace(res, solver_status=f"p-norm to p={PNORM_SCHEDULE[-1]}"
                              + (f", best at p={best_p}" if best_p else "")
                              + f" (last: {res.solver_status})")
    rec = stage_record(param.structure.n_sections + 2, param, z_new, data, data.n_points,
                       math.nan, res, nit, nfev, time.perf_counter() - t0,
                       Kept.MINIMAX if ok else Kept.MINIMAX_REJECTED, StageKind.MINIMAX)
    ctx.callback(rec)
    return z_new, rec


def _cold_start(init_z, param, z):
    """Cold start for warm_start='none': stage-0 gain/delay, sections as inserted."""
    out = z.copy()
    out[:2] = init_z[:2]
    for k, wr in enumerate(param.omega_ref):
        sec = param.new_section(wr, 0.5, wr, 0.5, wr)
        out[2 + k * sec.size: 2 + (k + 1) * sec.size] = sec
    return out


def _new_section(param, init, scale_l, omega, phi, err, idx, z, old_param):
    """Initial variables of the section added at omega[idx]."""
    omega_c = float(omega[idx])
    if init == "identity":
        return param.new_section(omega_c, 0.5, omega_c, 0.5, omega_c, scale_l)
    # "peak": a pole/zero pair at omega_c whose value there matches |Phi/G| (SPEC issue 3.5)
    rho = abs(model_ratio(old_param, z, omega[idx:idx + 1], phi[idx:idx + 1])[0])
    half = err[idx] / 2.0
    lo = idx
    while lo > 0 and err[lo - 1] > half:
        lo -= 1
    hi = idx
    while hi < omega.size - 1 and err[hi + 1] > half:
        hi += 1
    width = (omega[min(hi + 1, omega.size - 1)] - omega[max(lo - 1, 0)]) / (2 * omega_c)
    zeta0 = float(np.clip(width / 2, 1e-3, 0.5))
    if param.structure.basis == "first-order":
        # a real zero/pole pair around omega_c with gain ratio rho
        r = math.sqrt(max(rho, 1e-6))
        return param.new_section(omega_c * r, 0, omega_c / r, 0, omega_c)
    if rho >= 1:
        zn, zd = min(zeta0 * rho, 2.0), zeta0
    else:
        zn, zd = zeta0, min(zeta0 / max(rho, 1e-12), 2.0)
    return param.new_section(omega_c, zn, omega_c, zd, omega_c)


def _stall_rule(init):
    """``{"stall": (window, ftol)}`` for the section stages of init="relocate"
    (:data:`~freqid_casadi.fitting.relocate.STALL_RULE`; the stage solver applies it with IPOPT
    only), else ``{}``."""
    from .relocate import STALL_RULE

    return {"stall": STALL_RULE} if init == "relocate" else {}


def _relocate(param, wdata, z_start, lam_start, zeta_min):
    """``(param, z_start, lam_start)`` of a stage with init="relocate": the vector-fit
    relocation of all sections (:mod:`freqid_casadi.fitting.relocate`, its own reference
    frequencies) when its stage cost is lower, with zero multipliers (the previous ones
    belong to other sections); else unchanged."""
    from .relocate import relocated_start

    found = relocated_start(param, wdata, z_start, zeta_min)
    if found is None:
        return param, z_start, lam_start
    return found[0], found[1], np.zeros_like(lam_start)


def _convert(old, new, z):
    """The variables in ``new`` of the model of variables ``z`` in ``old``."""
    return z if new is old else new.from_beta(old.to_beta(z))


def _max_window_error(param, data, z):
    return float(np.max(np.abs(model_ratio(param, z, data.omega, data.response) - 1.0)))
