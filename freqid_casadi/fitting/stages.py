"""One stage of the main loop: its solver, what it keeps and its record (layer L4).

:class:`StageSolver` builds a stage's functions (:mod:`freqid_casadi.core.objective`) and runs
the chosen stage solver (:mod:`freqid_casadi.solvers`) with the options of
:mod:`freqid_casadi.options`; :func:`keep_better` never lets a failed or worse stage replace
a better point; :class:`StageRecord` says what a stage did, with :class:`Kept` and
:class:`StageKind` as enums (``str`` subclasses: they compare equal to, and serialise as,
their values). :func:`polish` refits every parameter of a model on all data from the
model: the rational start's last stage and the refit of
:func:`~freqid_casadi.fitting.validation.prune_sections`.
"""

import dataclasses
import enum
import math
from dataclasses import dataclass, field

import numpy as np

from .. import _interrupt
from ..core.data import FrequencyData
from ..errors import DataError
from ..core.metrics import error_stats
from ..core.model import RationalDelayModel
from ..core.objective import Parametrization, stage_functions
from ..options import LoopOptions, solver_options
from ..core.resolution import default_delay_max
from ..solvers.barrier_lm import solve_stage_lm
from ..solvers.common import StageProblem, StageResult, Status
from ..solvers.ipopt import solve_stage

__all__ = ["Kept", "StageKind", "StageRecord", "StageSolver", "PolishResult", "polish",
           "polish_start", "choose_charts", "CHART_ZETA"]
# keep_better, stage_record, stage_cost, model_ratio, solver_timing: helpers of the loops
# (freqid_casadi.fitting.mainloop), not public API.


class _ValueEnum(str, enum.Enum):
    """A ``str`` enum whose ``str()`` and format are its value (so f-strings, ``==`` with
    strings and JSON keep the plain words)."""

    def __str__(self):
        return str.__str__(self)

    def __format__(self, spec):
        return str.__format__(self, spec)


class Kept(_ValueEnum):
    """Which point a stage kept (:attr:`StageRecord.kept`)."""

    SOLUTION = "solution"                #: the solver's point
    START = "start"                      #: the stage's start (the solution was worse)
    PREVIOUS = "previous"                #: the previous model with an identity section
    IDENTITY_RETRY = "identity-retry"    #: the retry from the thesis's identity section
    MINIMAX = "minimax"                  #: the minimax polish's point
    MINIMAX_REJECTED = "minimax-rejected"  #: the minimax polish did not lower the max error


class StageKind(_ValueEnum):
    """Which kind of stage a record is (:attr:`StageRecord.kind`)."""

    GAIN_DELAY = "gain-delay"            #: stage 0 of the sequential loop
    SECTION = "section"                  #: a stage that added a section
    FINAL = "final"                      #: the last stage on all data (and the polish)
    RATIONAL_START = "rational-start"    #: the vector-fitting start (no solve)
    MINIMAX = "minimax"                  #: the p-norm continuation of the minimax polish
    ZERO_DELAY = "zero-delay"            #: the same model at h = 0, polished (a candidate)
    DELAY_SEARCH = "delay-search"        #: a nearby delay's rational start, polished
    FAR_ROOTS = "far-roots"              #: roots far above the band at infinity, polished


@dataclass(frozen=True)
class StageRecord:
    """What one stage of the main loop did.

    Attributes
    ----------
    stage : int
        0 for the gain/delay stage, N for the stage that added section N, and
        ``n_sections + 1`` for the final all-data stage.
    n_sections : int
    window : int
        Number of data points (lowest frequencies) fitted in this stage, L_N.
    omega_c : float
        Frequency (rad/s) where the new section was placed (nan for stage 0 / final).
    max_rel_error_window, rms_rel_error_window : float
    max_rel_error, rms_rel_error : float
        Over all data points, after the stage.
    nit, nfev : int
    wall_time : float
        Seconds, including building the NLP.
    status : Status
    solver_status : str
    success : bool
    kept : Kept
        Which point the stage kept: "solution", "start" (solution worse than its start),
        "previous" (both worse than the previous model with an identity section),
        "identity-retry" (the peak-initialised stage ended worse than the infinite-gain
        model on its window, max relative error >= 1, and a second solve from the
        thesis's identity section did better), "minimax" or "minimax-rejected" (the
        minimax polish, kept or not).
    delay : float
        Delay estimate (s) after the stage.
    n_active : int
        Variables at their bounds.
    timing : dict
        IPOPT stages only, seconds summed over the stage's solves: ``t_build`` (NLP
        construction), ``t_solve`` (the solve), ``t_f``, ``t_grad_f``, ``t_hess_l`` (time in
        the objective, gradient and Hessian evaluations); ``t_solve`` minus the three is
        IPOPT's own work. Empty for other solvers.
    kind : StageKind
        "gain-delay" (stage 0), "section", "final", "rational-start" or "minimax".
    message : str
        The stage solver's message: why it stopped, in plain words.
    details : dict
        The optimiser's numbers behind ``message``: ``termination`` (the relative
        stationarity test's cosines and projection with their allowed values and the RMS
        error's fall per iteration,
        :meth:`~freqid_casadi.solvers.termination.StageMonitor.test_numbers`),
        ``ipopt_status`` (IPOPT's return status), ``ipopt_iterations`` and
        ``polish_steps`` (``nit`` is their sum), ``max_iter`` (the stage's iteration
        limit) and ``method``; empty for stages without a solve.
    """

    stage: int
    n_sections: int
    window: int
    omega_c: float
    max_rel_error_window: float
    rms_rel_error_window: float
    max_rel_error: float
    rms_rel_error: float
    nit: int
    nfev: int
    wall_time: float
    status: Status
    solver_status: str
    success: bool
    kept: Kept
    delay: float
    n_active: int
    timing: dict = field(default_factory=dict)
    kind: StageKind = StageKind.SECTION
    message: str = ""
    details: dict = field(default_factory=dict)

    def as_dict(self):
        """JSON-ready dict of the fields (enums as their names/values)."""
        d = dict(self.__dict__)
        d["status"] = self.status.name
        d["kept"] = Kept(self.kept).value
        d["kind"] = StageKind(self.kind).value
        d["timing"] = dict(self.timing)
        d["details"] = dict(self.details)
        return d


def model_ratio(param, z, omega, phi):
    """``Phi/G_N`` (complex, shape (M,)) of the model of variables ``z`` of ``param``."""
    re, im = param.ratio(np.asarray(z, float), omega, (phi.real, phi.imag))
    return re + 1j * im


def stage_cost(param, data, z):
    """The stage objective: weighted sum of ``|Phi/G_N - 1|^2`` over ``data``."""
    r = model_ratio(param, z, data.omega, data.response) - 1.0
    w = 1.0 if data.weights is None else data.weights
    return float(np.sum(w * np.abs(r) ** 2))


def keep_better(param, wdata, z_start, lam_start, res, previous=None):
    """Keep the best of the solver's point, its start and (optionally) the previous model;
    a failed or worse stage never replaces a better point."""
    cands = [("solution", res.x, res.lam_x), ("start", z_start, lam_start)]
    if previous is not None:
        cands.append(("previous", previous, np.zeros_like(previous)))
    costs = [stage_cost(param, wdata, c[1]) for c in cands]
    costs = [c if np.isfinite(c) else np.inf for c in costs]
    best = int(np.argmin(costs))
    # prefer the solution on ties (it is the converged point)
    if costs[0] <= costs[best]:
        best = 0
    name, x, lam = cands[best]
    return np.asarray(x, float).copy(), np.asarray(lam, float).copy(), Kept(name)


_TIMING_KEYS = ("t_build", "t_solve", "t_f", "t_grad_f", "t_hess_l")


def _max_rms(values):
    stats = error_stats(values)
    return stats.max, stats.rms


def solver_timing(results):
    """Sum of the solver timings (``StageResult.extra``) of one stage's solves."""
    out = {}
    for res in results:
        for k in _TIMING_KEYS:
            if k in (res.extra or {}):
                out[k] = out.get(k, 0.0) + float(res.extra[k])
    return out


def stage_record(stage, param, z, data, window, omega_c, res, nit, nfev, wall, kept, kind,
                 timing=None):
    """The :class:`StageRecord` of a stage that ended at ``z`` (errors over all of
    ``data`` and over its first ``window`` points)."""
    err = np.abs(model_ratio(param, z, data.omega, data.response) - 1.0)
    mx, rms = _max_rms(err)
    mxw, rmsw = _max_rms(err[:window])
    return StageRecord(stage=stage, n_sections=param.structure.n_sections, window=int(window),
                       omega_c=float(omega_c), max_rel_error_window=mxw,
                       rms_rel_error_window=rmsw, max_rel_error=mx, rms_rel_error=rms,
                       nit=int(nit), nfev=int(nfev), wall_time=float(wall), status=res.status,
                       solver_status=res.solver_status, success=bool(res.success), kept=Kept(kept),
                       delay=float(param.to_beta(z)[0]),
                       n_active=int(np.count_nonzero(res.active_mask)),
                       timing=solver_timing([res]) if timing is None else timing,
                       kind=StageKind(kind), message=str(res.message),
                       details=stage_details(res))


#: Keys of ``StageResult.extra`` that go to ``StageRecord.details``.
_DETAIL_KEYS = ("termination", "ipopt_status", "ipopt_iterations", "polish_steps", "max_iter",
                "noise_stall")


def stage_details(res):
    """``StageRecord.details`` of a stage result: the optimiser's numbers (see
    :class:`StageRecord`)."""
    extra = res.extra or {}
    out = {k: extra[k] for k in _DETAIL_KEYS if k in extra}
    if out or res.solver_status:
        out["method"] = "ipopt" if "ipopt_status" in out or "termination" in out else (
            "barrier-lm" if "n_outer" in extra else "")
        out.setdefault("solver_status", res.solver_status)
    return out


def _termination(ftol, onto_bounds=False, stall=None, newton=False, abandon=None,
                 noise_stall=None):
    """The stages' :class:`~freqid_casadi.solvers.termination.Termination` for
    ``IpoptOptions.ftol`` (0: the test and its polishes off), the optional stall rule
    ``stall = (window, ftol)``, the final stages' Newton polish, the optional
    ``abandon = (k, rms)`` rule of a screened candidate and the final stages'
    :class:`~freqid_casadi.solvers.termination.NoiseStall` (or None)."""
    from ..solvers.termination import Termination

    kw = {} if stall is None else dict(stall_window=int(stall[0]), stall_ftol=float(stall[1]))
    if abandon is not None:
        kw["abandon"] = (int(abandon[0]), float(abandon[1]))
    if noise_stall is not None:
        kw["noise_stall"] = noise_stall
    if ftol > 0:
        return Termination(ftol=float(ftol), onto_bounds=onto_bounds, newton=newton, **kw)
    return Termination(ftol=0.0, noise_factor=0.0, polish_steps=0, **kw)


def _noise_stall(opts, wdata):
    """The :class:`~freqid_casadi.solvers.termination.NoiseStall` of a final stage on
    ``wdata`` from ``IpoptOptions.noise_stall`` (None when off): its rounding floor is
    :data:`~freqid_casadi.fitting.verdict.ROUNDING_RMS` in the stage's units (relative
    residuals times the square roots of the weights), its noise ratio that of
    :func:`~freqid_casadi.fitting.verdict.residual_noise`."""
    from ..solvers.termination import NoiseStall
    from .verdict import CONSISTENT_RATIO, ROUNDING_RMS, residual_noise

    if opts.noise_stall is None:
        return None
    w = wdata.weights
    scale = 1.0 if w is None else float(np.sqrt(np.mean(w)))
    omega = wdata.omega
    return NoiseStall(window=opts.noise_stall[0], chi2=opts.noise_stall[1],
                      rms_floor=ROUNDING_RMS * scale, max_ratio=CONSISTENT_RATIO,
                      noise_ratio=lambda e: residual_noise(e, omega)["ratio"])


class StageSolver:
    """Builds the stage's functions and calls the chosen stage solver.

    Parameters
    ----------
    solver : IpoptOptions or BarrierLMOptions
    loop : LoopOptions
    zeta_min : float, optional
        Damping floor imposed as constraints (IPOPT only).
    onto_bounds : bool
        The termination test's ``onto_bounds`` (:func:`polish`).

    Calling it, ``solve(param, wdata, x0, lam0, max_iter=None, stall=None, final=False)``,
    solves the stage on ``wdata`` from ``x0`` (bound multipliers ``lam0`` or None) and
    returns a :class:`~freqid_casadi.solvers.common.StageResult`; ``stall = (window,
    ftol)`` (IPOPT only) also ends the stage when its cost fell by less than the fraction
    ``ftol`` over ``window`` iterations; ``final`` (a fit's final stage) allows the
    termination test's Newton polish (``Termination.newton``).
    """

    def __init__(self, solver, loop, zeta_min=None, onto_bounds=False):
        self.solver = solver
        self.loop = loop
        self.zeta_min = zeta_min
        self.onto_bounds = onto_bounds

    def __call__(self, param, wdata, x0, lam0, max_iter=None, stall=None, final=False,
                 abandon=None):
        # signals deferred while the stage's CasADi expressions and solver are built and
        # run: a KeyboardInterrupt raised inside CasADi's argument conversion (SWIG calls
        # back into Python) is swallowed there; IPOPT and the barrier-LM stop at their next
        # iteration, and Interrupted is raised when the stage returns
        with _interrupt.guard():
            return self._solve(param, wdata, x0, lam0, max_iter, stall, final, abandon)

    def _solve(self, param, wdata, x0, lam0, max_iter, stall, final, abandon=None):
        funcs = stage_functions(param, wdata.omega, wdata.response, wdata.weights,
                                derivatives=self.loop.derivatives)
        lb, ub = param.bounds()
        if not self.loop.bound_delay and param.structure.delay:
            ub[0] = np.inf
        opts = self.solver
        if opts.method == "ipopt":
            cons = None
            if self.zeta_min is not None and param.structure.n_sections:
                cons = param.damping_constraints(self.zeta_min)
                x0 = param.project_damping(x0, self.zeta_min)
            problem = StageProblem.from_stage_functions(funcs, lb, ub, cons)
            res = solve_stage(problem, np.clip(np.asarray(x0, float), lb, ub), lam_x0=lam0,
                              hessian=opts.hessian, max_iter=max_iter or opts.max_iter,
                              warm_start=opts.warm_start != "none",
                              ipopt_options=opts.ipopt_dict(),
                              termination=_termination(
                                  opts.ftol, self.onto_bounds, stall, final, abandon,
                                  _noise_stall(opts, wdata) if final else None))
            if cons is not None:
                # IPOPT meets g >= 0 to its tolerance; make the floor exact
                res = dataclasses.replace(res, x=param.project_damping(res.x, self.zeta_min))
            return res
        # the barrier is infinite on the bounds: move the start strictly inside
        x0 = np.array(x0, float)
        free = lb < ub
        x0[free] = np.maximum(x0[free], lb[free] + 1e-6 * np.maximum(1.0, np.abs(x0[free])))
        return solve_stage_lm(StageProblem.from_stage_functions(funcs, lb, ub), x0,
                              **opts.lm_kwargs())


@dataclass(frozen=True, eq=False)
class PolishResult:
    """Result of :func:`polish`.

    Attributes
    ----------
    model : RationalDelayModel
        The polished model (the start's model if the solve did not lower the cost).
    param : Parametrization
        The parametrization of the solve (references from the start model).
    x : ndarray of float, shape (n,)
        The kept point in ``param``'s variables.
    lam_x : ndarray of float, shape (n,)
        Its bound multipliers (zeros if the start was kept).
    start : ndarray of float, shape (n,)
        The start in ``param``'s variables (clipped into the bounds, damping projected).
    result : StageResult
        The stage solver's result.
    kept : Kept
        ``Kept.SOLUTION`` or ``Kept.START``.
    """

    model: RationalDelayModel
    param: Parametrization
    x: np.ndarray
    lam_x: np.ndarray
    start: np.ndarray
    result: StageResult
    kept: Kept


#: Damping ratio from which a factor may leave the unit-DC chart in :func:`choose_charts`
#: (no resonance peak: its roots act as two corner frequencies).
CHART_ZETA = 1.0 / math.sqrt(2.0)


def choose_charts(model, omega, gauge, zeta_min=None):
    """The charts (:data:`~freqid_casadi.core.gauges.CHARTS`) of :func:`polish`'s variables.

    Each factor is written in the chart that reaches the limits its roots can head for
    at finite variables: a factor without a resonance peak (damping ratio at least
    :data:`CHART_ZETA`) with both roots below the band's geometric centre gets the monic
    chart ``c0 + c1 x + x^2`` (roots tending to 0, an integrator the data ask for, or
    becoming undamped), one with a root below and one above it the unit-linear chart
    ``c0 + x + c2 x^2`` (one root to 0, the other to infinity), every other factor the
    unit-DC chart (roots leaving the band upwards, undamped roots). In the unit-DC chart a
    root tending to 0 has coefficients and gain tending to infinity, a direction a solver
    creeps along without end (measured on the actuator: 1771 IPOPT iterations).

    Parameters
    ----------
    model : RationalDelayModel
    omega : ndarray of float, shape (M,)
        The data's frequencies (rad/s), increasing.
    gauge : str
    zeta_min : float, optional
        A damping floor: no unit-linear chart (the monic one instead).

    Returns
    -------
    tuple of (int, int)
        Per section (numerator, denominator); empty when every factor is unit-DC.
    """
    st = model.structure
    if gauge != "dc" or st.basis != "second-order" or st.zeros != "minimum-phase":
        return ()
    centre = math.sqrt(float(omega[0]) * float(omega[-1]))

    def chart(a, zeta, w):
        if not (w > 0 and zeta >= CHART_ZETA):
            return 0
        roots = sorted(abs(r) for r in np.roots([a, 2 * zeta * w, w * w]))
        mid = 0 if zeta_min is not None else 2      # (a single root, a = 0: not monic)
        if roots[-1] < centre:
            return 1 if a > 0 else mid
        if roots[0] < centre:
            return mid or 1
        return 0

    charts = tuple((chart(*row[:3]), chart(*row[3:])) for row in model.sections())
    return charts if any(map(any, charts)) else ()


def polish_start(model, data, *, loop=None, delay_max=None, zeta_min=None):
    """The parametrization and start of :func:`polish` (the model's variables).

    Each section's reference frequency is its denominator's natural frequency
    ``wd / sqrt(b)`` (``wd`` when ``b = 0``; the lowest data frequency where that is not
    finite and positive); the gain's reference is the model's gain (1 if not positive).

    Parameters
    ----------
    model : RationalDelayModel
    data : FrequencyData
    loop, delay_max, zeta_min
        As in :func:`polish`.

    Returns
    -------
    param : Parametrization
    z0 : ndarray of float, shape (param.n_vars,)
        The model's variables, clipped into the bounds and projected onto the damping
        floor.
    """
    loop = LoopOptions() if loop is None else loop
    if delay_max is None:
        delay_max = max(default_delay_max(data.omega), model.delay)
    beta = np.array(model.beta)
    secs = model.sections()
    refs = []
    for row in secs:
        w = row[-1]
        if model.structure.basis == "second-order" and row[3] > 0:
            w = w / math.sqrt(row[3])
        refs.append(float(w) if np.isfinite(w) and w > 0 else float(data.omega[0]))
    gain_ref = beta[1] if beta[1] > 0 else 1.0
    param = Parametrization(model.structure, loop.gauge, tuple(refs), gain_ref, delay_max,
                            loop.scaled, choose_charts(model, data.omega, loop.gauge, zeta_min),
                            loop.root_floor * float(data.omega[0]))
    lb, ub = param.bounds()
    z0 = np.clip(param.from_beta(beta), lb, ub)
    if zeta_min is not None:
        z0 = param.project_damping(z0, zeta_min)
    return param, z0


#: IPOPT's initial barrier parameter in :func:`polish` (as the warm-started stages').
POLISH_MU_INIT = 1e-6


def _from_a_model(solver):
    """IPOPT options of a solve started from a model: a small initial barrier parameter
    (:data:`POLISH_MU_INIT`) unless the user set one. IPOPT's default (0.1, for a start
    far from the solution) weighs the barrier above the whole relative cost (scaled to 1):
    a variable whose optimum is on its bound (a root at ``root_floor``) is pushed away for
    hundreds of iterations (measured on the actuator: 201 iterations, not converged, with
    0.1; 60 with 1e-6)."""
    if solver.method != "ipopt" or "mu_init" in dict(solver.ipopt):
        return solver
    return dataclasses.replace(solver, ipopt=solver.ipopt + (("mu_init", POLISH_MU_INIT),))


def polish(model, data, *, method="ipopt", loop=None, delay_max=None, zeta_min=None,
           max_iter=None, stall=None, abandon=None):
    """Refit every parameter of ``model`` on all of ``data``, started from ``model``.

    One stage NLP on all data (as the main loop's final stage), kept only if it lowers
    the stage cost (:func:`keep_better`): the last stage of the rational start and the
    refit of :func:`~freqid_casadi.fitting.validation.prune_sections`. Unlike the main loop's
    stages, its overdamped factors are written in the charts of :func:`choose_charts`
    (a root the data push out of the band below stops on the floor
    ``LoopOptions.root_floor``, a bound), IPOPT starts with a small barrier parameter
    (:data:`POLISH_MU_INIT`) and a point held just inside a bound is tried on it
    (``Termination.onto_bounds``).

    Parameters
    ----------
    model : RationalDelayModel
    data : FrequencyData
        The data (and its weights) to fit.
    method : {"ipopt", "barrier-lm"} or IpoptOptions or BarrierLMOptions
        The stage solver, as :func:`~freqid_casadi.fitting.fit.fit`'s ``method``.
    loop : LoopOptions, optional
        Gauge, scaling, delay bound and derivatives of the stage.
    delay_max : float, optional
        Upper bound of the delay (s); default the larger of
        :func:`~freqid_casadi.core.resolution.default_delay_max` and the model's delay.
    zeta_min : float, optional
        Damping floor imposed as constraints (IPOPT, dc gauge).
    max_iter : int, optional
        Iteration limit; default the solver options' ``final_max_iter``.
    stall : (int, float), optional
        ``(window, ftol)``: also stop when the cost fell by less than the fraction ``ftol``
        over ``window`` iterations (IPOPT only; :class:`StageSolver`).
    abandon : (int, float), optional
        ``(k, rms)``: stop at iteration ``k`` if the RMS residual is still above ``rms``
        (IPOPT only; ``result.extra["abandoned"]`` then True): a screened candidate.

    Returns
    -------
    PolishResult

    Raises
    ------
    DataError
        ``data`` is not a FrequencyData or ``model`` not a RationalDelayModel.
    OptionError
        Bad ``method`` or ``loop``.
    """
    if not isinstance(data, FrequencyData) or not isinstance(model, RationalDelayModel):
        raise DataError("polish(model, data) takes a RationalDelayModel and the "
                        "FrequencyData to fit")
    solver = _from_a_model(solver_options(method))
    loop = LoopOptions() if loop is None else loop
    param, z0 = polish_start(model, data, loop=loop, delay_max=delay_max, zeta_min=zeta_min)
    solve = StageSolver(solver, loop, zeta_min, onto_bounds=True)
    res = solve(param, data, z0, None, max_iter=max_iter or solver.final_max_iter,
                stall=stall, final=stall is None, abandon=abandon)
    z, lam, kept = keep_better(param, data, z0, np.zeros_like(z0), res)
    return PolishResult(model=param.to_model(z), param=param, x=z, lam_x=lam, start=z0,
                        result=res, kept=kept)
