"""The sequential main loop (SPEC §2) and the public :func:`fit` (layer L4).

Stage 0 fits the gain (K0 with an integrator) and the delay on a growing low-frequency
window. Stage N appends one section at the frequency of the largest relative error over all
data, grows the window to cover that point, and re-fits all parameters on the window,
warm-started from stage N-1. A last stage fits the full model on all data. Every stage is
one NLP (see :mod:`freqid_casadi.solvers`).
"""

import dataclasses
import math
import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .data import FrequencyData
from .errors import DataError, OptionError, ResolutionWarning, StructureError
from .model import BASES, RationalDelayModel, Structure
from .objective import GAUGES, Parametrization, rel_error_stats, stage_functions
from .scaling import check_finite_result, reference_scales, scale_data, unscale_model
from .solvers.common import Status
from .solvers.ipopt import HESSIANS, solve_least_squares

__all__ = ["fit", "FitResult", "StageRecord", "METHODS", "INITS", "WARM_STARTS", "STARTS",
           "OBJECTIVES", "default_delay_max", "resolution_damping"]

METHODS = ("ipopt", "barrier-lm")
INITS = ("peak", "identity")
WARM_STARTS = ("primal-dual", "primal", "none")
STARTS = ("sequential", "rational", "best")
OBJECTIVES = ("least-squares", "minimax")
DERIVATIVES = (None, "affine", "casadi-map")


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
    kept : str
        Which point the stage kept: "solution", "start" (solution worse than its start),
        "previous" (both worse than the previous model with an identity section) or
        "identity-retry" (the peak-initialised stage ended worse than the infinite-gain
        model on its window, max relative error >= 1, and a second solve from the
        thesis's identity section did better).
    delay : float
        Delay estimate (s) after the stage.
    n_active : int
        Variables at their bounds.
    timing : dict
        IPOPT stages only, seconds summed over the stage's solves: ``t_build`` (NLP
        construction), ``t_solve`` (the solve), ``t_f``, ``t_grad_f``, ``t_hess_l`` (time in
        the objective, gradient and Hessian evaluations); ``t_solve`` minus the three is
        IPOPT's own work. Empty for other solvers.
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
    kept: str
    delay: float
    n_active: int
    timing: dict = field(default_factory=dict)

    def as_dict(self):
        d = dict(self.__dict__)
        d["status"] = self.status.name
        d["timing"] = dict(self.timing)
        return d


@dataclass(frozen=True, eq=False)
class FitResult:
    """Result of :func:`fit`.

    Attributes
    ----------
    model : RationalDelayModel
        The fitted model (stable and minimum phase by construction: beta >= 0).
    stages : tuple of StageRecord
    data : FrequencyData
    rel_error : ndarray of float, shape (M,)
        |(Phi - G_N)/G_N| at every data point.
    max_rel_error, rms_rel_error : float
    success : bool
        True if the final all-data stage converged (IPOPT/LM status).
    wall_time : float
        Seconds for the whole fit.
    method : str
    options : dict
        The options the fit ran with (for reports).
    start : str
        Which start produced the model ("sequential" or "rational").
    objective : str
        "least-squares", or "minimax" if the max-error polish (p-norm continuation) ran.
    resolution : freqid_casadi.validation.ResolutionCheck or None
        The model checked against the data's frequency spacing (None for the first-order
        basis, whose real roots are never narrow); when ``resolution.ok`` is False,
        :func:`fit` also issued a :class:`~freqid_casadi.errors.ResolutionWarning`.
    """

    model: RationalDelayModel
    stages: tuple
    data: FrequencyData
    rel_error: np.ndarray
    max_rel_error: float
    rms_rel_error: float
    success: bool
    wall_time: float
    method: str
    options: dict = field(default_factory=dict)
    start: str = "sequential"
    objective: str = "least-squares"
    resolution: object = None

    @property
    def delay(self):
        return self.model.delay

    @property
    def nit(self):
        """IPOPT/LM iterations summed over all stages."""
        return int(sum(s.nit for s in self.stages))

    def summary(self):
        m = self.model
        return (f"{self.data.name or 'data'}: {m.n_sections} sections (order {m.order}), "
                f"max rel. error {self.max_rel_error:.4g}, RMS {self.rms_rel_error:.4g}, "
                f"delay {m.delay:.6g} s, {self.wall_time:.2f} s, method {self.method}, "
                f"{'converged' if self.success else 'NOT converged'}")


def default_delay_max(omega):
    """Largest delay the data can resolve: ``pi / max(diff(omega))`` seconds.

    Beyond it the phase ``-h w`` changes by more than pi between neighbouring samples and
    the delay is ambiguous (phase-wrapped minima).
    """
    omega = np.asarray(omega, float)
    if omega.size < 2:
        return math.pi / omega[0]
    return math.pi / float(np.max(np.diff(omega)))


def resolution_damping(omega, fraction=1.0):
    """Damping floor from the frequency resolution: a quadratic's half-power bandwidth
    ``2 zeta w0`` is at least ``fraction`` times the local spacing ``dw``.

    With the relative spacing ``dw/w`` (its median over the data; constant on a log grid)
    this is ``zeta_min = fraction/2 * median(dw/w)``; with ``fraction = 1`` no pole or zero
    of the fit is narrower than the spacing, the criterion of
    :func:`~freqid_casadi.validation.check_resolution`. On the thesis's grid (500 points
    over 5 decades, ``dw/w = 0.0233``) it is 0.0117, above the lightest damping of
    example A (0.0075 at 15 rad/s): on clean data of A the floor costs accuracy (17
    sections: max relative error 2.2e-4 instead of 5e-6), on noisy data it keeps the fit
    from hiding narrow pole/zero pairs between the samples.

    Parameters
    ----------
    omega : array_like of float, shape (M,), rad/s, strictly increasing
    fraction : float > 0

    Returns
    -------
    float
    """
    omega = np.asarray(omega, float)
    if omega.size < 2:
        raise DataError("a damping floor from the resolution needs at least 2 frequencies")
    rel = np.diff(omega) / omega[:-1]
    return 0.5 * float(fraction) * float(np.median(rel))


def _zeta_min(min_damping, omega, method, gauge, basis):
    if min_damping is None:
        return None
    if isinstance(min_damping, str):
        if min_damping != "auto":
            raise OptionError(f"unknown min_damping {min_damping!r}; use None, 'auto' or a "
                              "number in [0, 1)")
        value = resolution_damping(omega)
    elif (isinstance(min_damping, bool) or not isinstance(min_damping, (int, float, np.floating))
          or not (0.0 <= float(min_damping) < 1.0)):
        raise OptionError(f"min_damping must be None, 'auto' or a number in [0, 1), got "
                          f"{min_damping!r}")
    else:
        value = float(min_damping)
    if method != "ipopt":
        raise OptionError("min_damping needs method='ipopt' (the barrier-LM method has "
                          "bounds only)")
    if gauge != "dc" or basis != "second-order":
        raise OptionError("min_damping needs gauge='dc' and basis='second-order' (first-order "
                          "sections have real roots and are never narrow)")
    return value


def _validate(data, response, n_sections, method, basis, tol, gauge, init, hessian,
              warm_start, delay_max, integrator, scale_l):
    if isinstance(data, FrequencyData):
        if response is not None:
            raise DataError("pass either a FrequencyData or (omega, response), not both")
    else:
        if response is None:
            raise DataError("response is missing: call fit(omega, response, ...) or "
                            "fit(FrequencyData(...), ...)")
        data = FrequencyData(data, response)
    if isinstance(n_sections, bool) or not isinstance(n_sections, (int, np.integer)):
        raise StructureError(f"n_sections must be a positive integer, got {n_sections!r}")
    if n_sections < 1:
        raise StructureError(f"n_sections must be >= 1, got {n_sections}")
    if method not in METHODS:
        raise OptionError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if basis not in BASES:
        raise OptionError(f"unknown basis {basis!r}; choose one of {', '.join(BASES)}")
    if gauge not in GAUGES:
        raise OptionError(f"unknown gauge {gauge!r}; choose one of {', '.join(GAUGES)}")
    if init not in INITS:
        raise OptionError(f"unknown init {init!r}; choose one of {', '.join(INITS)}")
    if hessian not in HESSIANS:
        raise OptionError(f"unknown hessian {hessian!r}; choose one of {', '.join(HESSIANS)}")
    if warm_start not in WARM_STARTS:
        raise OptionError(f"unknown warm_start {warm_start!r}; choose one of "
                          f"{', '.join(WARM_STARTS)}")
    if tol is not None and not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise OptionError(f"tol must be a number > 0 (a max relative error), got {tol!r}")
    if delay_max is not None and not (isinstance(delay_max, (int, float))
                                      and math.isfinite(delay_max) and delay_max > 0):
        raise OptionError(f"delay_max must be a finite number > 0 (seconds), got {delay_max!r}")
    if not (isinstance(scale_l, (int, float)) and scale_l >= 1):
        raise OptionError(f"scale_l must be >= 1, got {scale_l!r}")
    structure = Structure(int(n_sections), integrator, True, basis)
    n_params = structure.n_params
    if data.n_points < n_params:
        raise DataError(
            f"too few data points for {n_sections} sections: {data.n_points} points for "
            f"{n_params} parameters; use fewer sections (at most "
            f"{max((data.n_points - 2) // structure.section_size, 0)}) or more data")
    return data


def fit(data_or_omega, response=None, *, n_sections, integrator=False, delay=True,
        basis="second-order", method="ipopt", tol=None, progress=False, weights=None,
        gauge="dc", init="peak", scale_l=1.0, hessian="exact",
        warm_start="primal-dual", scaled=True, delay_max=None, bound_delay=True,
        final_stage=True, max_iter=100, final_max_iter=200, ipopt_options=None,
        lm_options=None, start="sequential", objective="least-squares", derivatives=None,
        min_damping=None):
    """Fit ``G_N(s) = exp(-h s) K [1/s] P_N(s)`` to frequency-response data.

    Parameters
    ----------
    data_or_omega : FrequencyData or array_like of float, shape (M,)
        The data, or the frequencies in rad/s (then ``response`` is required).
    response : array_like of complex, shape (M,), optional
        G(j omega) when ``data_or_omega`` is the frequency array.
    n_sections : int
        Number of sections N >= 1 (order 2N, or 2N+1 with the integrator; N with the
        first-order basis).
    integrator : bool
        Include the factor K0/s.
    delay : bool
        Fit a delay h >= 0 (else h = 0).
    basis : {"second-order", "first-order"}
    method : {"ipopt", "barrier-lm"}
        IPOPT with true bounds (the package's method) or the thesis's log-barrier +
        Levenberg-Marquardt (SPEC §3).
    tol : float, optional
        Stop adding sections once the max relative error over all data is below ``tol``.
    progress : bool or callable
        True writes a line per stage to stderr; a callable receives each StageRecord.
    weights : array_like of float, shape (M,), optional
        Weights of the squared relative residuals (overrides ``data.weights``).
    gauge : {"dc", "b1", "raw"}
        Parametrization of the sections, see :mod:`freqid_casadi.objective`.
    init : {"peak", "identity"}
        New-section initialisation: "peak" places a pole/zero pair at omega_c whose
        value there reproduces the error peak; "identity" is the thesis's a=b=1,
        zeta=0.5, omega=omega_c (optionally scaled by ``scale_l``).
    scale_l : float
        The thesis's l >= 1 for the identity section (affects only the "raw" gauge).
    hessian : {"gauss-newton", "exact", "limited-memory"}
        Hessian used by IPOPT.
    warm_start : {"primal-dual", "primal", "none"}
        What a stage takes from the previous stage: the point and the bound multipliers,
        the point only, or nothing (the stage restarts from the identity-extended initial
        guess of stage 0's gain with all sections at their insertion values).
    scaled : bool
        Scale the variables to about 1 (delay by ``delay_max``, gain by its initial value,
        section frequencies by their insertion frequency).
    delay_max : float, optional
        Upper bound of the delay in seconds. Default :func:`default_delay_max` of the data.
    bound_delay : bool
        If False, the delay has no upper bound (for the ablation).
    final_stage : bool
        End with a stage on all data (default True).
    max_iter : int
        Iteration limit of each intermediate stage (the next stage continues from its
        point, so a stage stopped at the limit is not a failure of the fit).
    final_max_iter : int
        Iteration limit of the final all-data stage, whose status is ``success``.
    ipopt_options, lm_options : dict, optional
        Extra options for the stage solver.
    start : {"sequential", "rational", "best"}
        "sequential" is the thesis's main loop; "rational" fits all sections at once by
        vector fitting with the delay refined from the right-half-plane zeros
        (:mod:`freqid_casadi.start`), then polishes everything by one IPOPT stage on all
        data; "best" runs both (the rational start begins at the sequential delay) and
        keeps the lower max relative error (``FitResult.start`` says which won).
    objective : {"least-squares", "minimax"}
        "minimax" adds a polish of the max relative error: a continuation in p of the
        p-norm of the residuals (p = 4 ... 1024, :data:`PNORM_SCHEDULE`), each stage an
        IPOPT NLP with true bounds; kept only if it lowers the max relative error (and the
        start is below 1).
    derivatives : {None, "affine", "casadi-map"}
        How the stage derivatives are evaluated (both exact, same results to rounding):
        None picks "affine" (numpy over points x sections; "dc" gauge only) or
        "casadi-map" (CasADi AD of the per-point formula mapped over the points; any
        gauge, about 3x slower), see :class:`~freqid_casadi.objective.StageFunctions`.
    min_damping : {None, "auto"} or float
        A floor on the damping ratio of every pole and zero, imposed as constraints of each
        stage NLP (``c1^2 >= 4 zeta_min^2 c2`` per quadratic; dc gauge, second-order
        basis, IPOPT). "auto" ties it to the data's frequency resolution
        (:func:`resolution_damping`): no pole or zero narrower than the local spacing, so
        a pole/zero pair cannot fit noise at one sample and be wrong between samples. For
        noisy data (it biases lightly damped modes narrower than the spacing); the value
        used is in ``FitResult.options["min_damping"]``.

    Returns
    -------
    FitResult

    Raises
    ------
    DataError, StructureError, OptionError
        Bad data or options (checked before any solve).
    """
    with _single_threaded_blas():
        return _fit(data_or_omega, response, n_sections=n_sections, integrator=integrator,
                    delay=delay, basis=basis, method=method, tol=tol, progress=progress,
                    weights=weights, gauge=gauge, init=init, scale_l=scale_l,
                    hessian=hessian, warm_start=warm_start, scaled=scaled,
                    delay_max=delay_max, bound_delay=bound_delay, final_stage=final_stage,
                    max_iter=max_iter, final_max_iter=final_max_iter,
                    ipopt_options=ipopt_options, lm_options=lm_options, start=start,
                    objective=objective, derivatives=derivatives, min_damping=min_damping)


def _single_threaded_blas():
    """BLAS limited to one thread: the stage matrices are small (n x 2M), and OpenBLAS
    threads oversubscribe the cores when several fits run at once (12x slower measured)."""
    import scipy.linalg  # noqa: F401  (load scipy's BLAS now: limits apply to loaded ones)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _fit(data_or_omega, response, *, n_sections, integrator, delay, basis, method, tol,
         progress, weights, gauge, init, scale_l, hessian, warm_start, scaled, delay_max,
         bound_delay, final_stage, max_iter, final_max_iter, ipopt_options, lm_options,
         start, objective, derivatives, min_damping):
    t_start = time.perf_counter()
    data = _validate(data_or_omega, response, n_sections, method, basis, tol, gauge, init,
                     hessian, warm_start, delay_max, integrator, scale_l)
    if start not in STARTS:
        raise OptionError(f"unknown start {start!r}; choose one of {', '.join(STARTS)}")
    if objective not in OBJECTIVES:
        raise OptionError(f"unknown objective {objective!r}; choose one of "
                          f"{', '.join(OBJECTIVES)}")
    if derivatives not in DERIVATIVES:
        raise OptionError(f"unknown derivatives {derivatives!r}; choose None, 'affine' or "
                          "'casadi-map'")
    if derivatives == "affine" and gauge != "dc":
        raise OptionError(f"derivatives='affine' needs gauge='dc' (got {gauge!r}); use "
                          "derivatives='casadi-map' or None")
    if weights is not None:
        data = data.with_weights(weights)
    # the problem is scale free: fit omega / w_ref and response / g_ref (powers of two, so
    # O(1) data is fitted bit for bit as given) and map the model back (issue 13 item 3)
    w_ref, g_ref = reference_scales(data)
    user_data, data = data, scale_data(data, w_ref, g_ref)
    zeta_min = _zeta_min(min_damping, data.omega, method, gauge, basis)
    dmax = (float(delay_max) * w_ref if delay_max is not None
            else default_delay_max(data.omega))
    user_callback, unscaled = _progress_callback(progress), {}

    def callback(rec):              # the user sees (and FitResult keeps) the same records
        unscaled[id(rec)] = (rec, _unscale_record(rec, w_ref))
        user_callback(unscaled[id(rec)][1])

    ctx = _Context(
        data=data, callback=callback,
        solve=_StageSolver(method, hessian, max_iter, ipopt_options, lm_options,
                           warm_start != "none", bound_delay, derivatives, zeta_min),
        structure=Structure(int(n_sections), integrator, delay, basis), gauge=gauge,
        scaled=scaled, delay_max=dmax, final_max_iter=final_max_iter, zeta_min=zeta_min)
    options = dict(n_sections=int(n_sections), integrator=bool(integrator), delay=bool(delay),
                   basis=basis, method=method, tol=tol, gauge=gauge, init=init,
                   scale_l=scale_l, hessian=hessian, warm_start=warm_start, scaled=scaled,
                   delay_max=dmax / w_ref, bound_delay=bound_delay, final_stage=final_stage,
                   max_iter=max_iter, final_max_iter=final_max_iter, start=start,
                   objective=objective, derivatives=derivatives, min_damping=zeta_min,
                   omega_ref=w_ref, response_ref=g_ref)
    runs = {}
    if start in ("sequential", "best"):
        runs["sequential"] = _sequential(ctx, tol, init, scale_l, warm_start, final_stage)
    if start in ("rational", "best"):
        # the delay update of the rational start only sees a delay that is too small (it
        # shows as right-half-plane zeros), so it always starts from h = 0
        try:
            runs["rational"] = _rational(ctx, 0.0)
        except OptionError:
            if start == "rational":
                raise
    errors = {k: float(np.max(p.to_model(z).relative_error(data)))
              for k, (p, z, _, _) in runs.items()}
    won = min(errors, key=lambda k: (errors[k], k != "sequential"))
    param, z, lam, records = runs[won]
    options["start_max_rel_errors"] = errors
    options["start_used"] = won
    if objective == "minimax":
        z, rec = _minimax(ctx, param, z)
        records.append(rec)
    model_scaled = param.to_model(z)
    rel = model_scaled.relative_error(data)
    check_finite_result(model_scaled.structure, model_scaled.beta, rel)
    model = unscale_model(model_scaled, w_ref, g_ref)
    records = [unscaled[id(r)][1] if id(r) in unscaled else _unscale_record(r, w_ref)
               for r in records]
    mx, rms = rel_error_stats(rel)
    final = [r for r in records if r.kept != "minimax-rejected" and r.solver_status
             != "vector-fitting"] or records
    from .validation import check_resolution   # lazy: validation builds on fit

    # first-order sections have real roots, never narrow: nothing to check
    check = (check_resolution(model, user_data.omega)
             if model.structure.basis == "second-order" and model.n_sections else None)
    if check is not None and not check.ok:
        warnings.warn(
            f"the model has {len(check.flags)} near-cancelling pole/zero pair(s) and "
            f"{len(check.unresolved)} pole(s)/zero(s) narrower than the frequency spacing: "
            "features between the samples that the data does not determine (typical of "
            "noisy data); inspect FitResult.resolution, refit with min_damping='auto' (a "
            "damping floor from the frequency spacing), remove them with "
            "freqid_casadi.validation.prune_sections, or fit fewer sections",
            ResolutionWarning, stacklevel=3)
    data = user_data
    return FitResult(model=model, stages=tuple(records), data=data, rel_error=rel,
                     max_rel_error=mx, rms_rel_error=rms,
                     success=bool(final[-1].success), wall_time=time.perf_counter() - t_start,
                     method=method, options=options, start=won, objective=objective,
                     resolution=check)


@dataclass(frozen=True)
class _Context:
    data: FrequencyData
    callback: object
    solve: object
    structure: Structure
    gauge: str
    scaled: bool
    delay_max: float
    final_max_iter: int
    zeta_min: object = None


def _sequential(ctx, tol, init, scale_l, warm_start, final_stage):
    """The thesis's main loop (SPEC §2). Returns (param, z, lam, records)."""
    data, solve, callback = ctx.data, ctx.solve, ctx.callback
    omega, phi = data.omega, data.response
    m = data.n_points
    st = ctx.structure
    gain0 = abs(phi[0]) * (omega[0] if st.integrator else 1.0)
    param = Parametrization(st.with_sections(0), ctx.gauge, (), gain0, ctx.delay_max,
                            ctx.scaled)

    # ---- stage 0: gain and delay on a growing low-frequency window (thesis: 1..5 points)
    z = np.zeros(param.n_vars)
    z[1] = gain0 / param._refs()[1]
    lam = np.zeros(param.n_vars)
    records = []
    l0 = min(5, m)
    t0 = time.perf_counter()
    nit = nfev = 0
    solves = []
    for length in range(1, l0 + 1):
        res = solve(param, data.window(length), z, lam)
        solves.append(res)
        nit, nfev = nit + res.nit, nfev + res.nfev
        z, lam = _keep_better(param, data.window(length), z, lam, res)[:2]
    records.append(_record(0, param, z, data, l0, math.nan, res, nit, nfev,
                           time.perf_counter() - t0, "solution", _timing(solves)))
    callback(records[-1])
    window = l0
    init_z = z.copy()

    # ---- stages 1..N: one section per stage at the largest error
    for n in range(1, st.n_sections + 1):
        err = np.abs(_ratio(param, z, omega, phi) - 1.0)
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
        wdata = data.window(window)
        t0 = time.perf_counter()
        res = solve(param, wdata, z_start, lam_start if warm_start == "primal-dual" else None)
        z, lam, kept = _keep_better(param, wdata, z_start, lam_start, res, prev_ext)
        nit, nfev = res.nit, res.nfev
        if init == "peak" and _max_window_error(param, wdata, z) >= 1.0:
            # worse than the infinite-gain model (relative error 1) on the window: a local
            # minimum of the peak placement; retry from the thesis's identity section
            z_id = np.concatenate([z_prev, ident])
            if ctx.zeta_min is not None:
                z_id = param.project_damping(z_id, ctx.zeta_min)
            res_id = solve(param, wdata, z_id,
                           lam_start if warm_start == "primal-dual" else None)
            nit, nfev = nit + res_id.nit, nfev + res_id.nfev
            if _cost(param, wdata, res_id.x) < _cost(param, wdata, z):
                res, z, lam, kept = res_id, res_id.x.copy(), res_id.lam_x.copy(), "identity-retry"
        records.append(_record(n, param, z, data, window, omega_c, res, nit, nfev,
                               time.perf_counter() - t0, kept))
        callback(records[-1])

    # ---- final stage on all data
    if final_stage and window < m or records[-1].status == Status.MAX_ITER:
        t0 = time.perf_counter()
        res = solve(param, data, z, lam if warm_start == "primal-dual" else None,
                    max_iter=ctx.final_max_iter)
        z, lam, kept = _keep_better(param, data, z, lam, res)
        records.append(_record(param.structure.n_sections + 1, param, z, data, m, math.nan,
                               res, res.nit, res.nfev, time.perf_counter() - t0, kept))
        callback(records[-1])
    return param, z, lam, records


def _rational(ctx, delay0):
    """Global start (:mod:`freqid_casadi.start`) polished by one stage on all data."""
    from .solvers.common import StageResult, find_active_constraints
    from .start import rational_start

    data, st = ctx.data, ctx.structure
    t0 = time.perf_counter()
    rs = rational_start(data, st, delay_max=ctx.delay_max, delay0=delay0)
    beta = np.array(rs.model.beta)
    secs = rs.model.sections()
    col = 5 if st.basis == "second-order" else 3
    refs = [float(w) if np.isfinite(w) and w > 0 else float(data.omega[0]) for w in secs[:, col]]
    gain_ref = beta[1] if beta[1] > 0 else 1.0
    param = Parametrization(st, ctx.gauge, tuple(refs), gain_ref, ctx.delay_max, ctx.scaled)
    z0 = param.from_beta(beta)
    lb, ub = param.bounds()
    z0 = np.clip(z0, lb, ub)
    if ctx.zeta_min is not None:
        z0 = param.project_damping(z0, ctx.zeta_min)
    n_trials = int(rs.delays.size)
    res0 = StageResult(x=z0, cost=np.nan, status=Status.CONVERGED,
                       message="rational start", success=True, nit=n_trials,
                       nfev=n_trials, wall_time=time.perf_counter() - t0,
                       active_mask=find_active_constraints(z0, lb, ub),
                       lam_x=np.zeros_like(z0), solver_status="vector-fitting")
    records = [_record(0, param, z0, data, data.n_points, math.nan, res0, n_trials, n_trials,
                       time.perf_counter() - t0, "start")]
    ctx.callback(records[-1])
    t0 = time.perf_counter()
    res = ctx.solve(param, data, z0, None, max_iter=ctx.final_max_iter)
    z, lam, kept = _keep_better(param, data, z0, np.zeros_like(z0), res)
    records.append(_record(st.n_sections + 1, param, z, data, data.n_points, math.nan, res,
                           res.nit, res.nfev, time.perf_counter() - t0, kept))
    ctx.callback(records[-1])
    return param, z, lam, records


PNORM_SCHEDULE = (4, 8, 16, 32, 64, 128, 256, 512, 1024)


def _minimax(ctx, param, z):
    """Polish of the max relative error by a continuation in p of the p-norm of the
    residuals (:func:`~freqid_casadi.solvers.ipopt.solve_pnorm`, p = 4 ... 1024, each an
    IPOPT NLP with true bounds started from the last), keeping the point with the lowest
    max error. Kept only if it lowers the max error and the start is below 1 (an
    infinite-gain model has relative error exactly 1 everywhere, the trap of a minimax
    stage started above 1)."""
    from .solvers.ipopt import solve_pnorm

    data = ctx.data
    funcs = stage_functions(param, data.omega, data.response, data.weights)
    lb, ub = param.bounds()
    cons = None
    if ctx.zeta_min is not None and param.structure.n_sections:
        cons = param.damping_constraints(ctx.zeta_min)

    def max_err(x):
        return float(np.max(param.to_model(x).relative_error(data)))

    before = max_err(z)
    t0 = time.perf_counter()
    best_x, best_e, best_p = z, before, None
    x, nit, nfev, res = z, 0, 0, None
    for p in PNORM_SCHEDULE:
        res = solve_pnorm(funcs, x, lb, ub, p, max_iter=ctx.final_max_iter, constraints=cons)
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
    rec = _record(param.structure.n_sections + 2, param, z_new, data, data.n_points,
                  math.nan, res, nit, nfev, time.perf_counter() - t0,
                  "minimax" if ok else "minimax-rejected")
    ctx.callback(rec)
    return z_new, rec


def _unscale_record(rec, w_ref):
    """A stage record of the scaled problem in the user's units (rad/s, s)."""
    return dataclasses.replace(rec, omega_c=rec.omega_c * w_ref, delay=rec.delay / w_ref)


def _cold_start(init_z, param, z):
    """Cold start for warm_start='none': stage-0 gain/delay, sections as inserted."""
    out = z.copy()
    out[:2] = init_z[:2]
    for k, wr in enumerate(param.omega_ref):
        sec = param.new_section(wr, 0.5, wr, 0.5, wr)
        out[2 + k * sec.size: 2 + (k + 1) * sec.size] = sec
    return out


def _ratio(param, z, omega, phi):
    re, im = param.ratio(np.asarray(z, float), omega, (phi.real, phi.imag))
    return re + 1j * im


def _new_section(param, init, scale_l, omega, phi, err, idx, z, old_param):
    """Initial variables of the section added at omega[idx]."""
    omega_c = float(omega[idx])
    if init == "identity":
        return param.new_section(omega_c, 0.5, omega_c, 0.5, omega_c, scale_l)
    # "peak": a pole/zero pair at omega_c whose value there matches |Phi/G| (SPEC issue 3.5)
    rho = abs(_ratio(old_param, z, omega[idx:idx + 1], phi[idx:idx + 1])[0])
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


def _max_window_error(param, data, z):
    return float(np.max(np.abs(_ratio(param, z, data.omega, data.response) - 1.0)))


def _cost(param, data, z):
    r = _ratio(param, z, data.omega, data.response) - 1.0
    w = 1.0 if data.weights is None else data.weights
    return float(np.sum(w * np.abs(r) ** 2))


def _keep_better(param, wdata, z_start, lam_start, res, previous=None):
    """Keep the best of the solver's point, its start and (optionally) the previous model;
    a failed or worse stage never replaces a better point."""
    cands = [("solution", res.x, res.lam_x), ("start", z_start, lam_start)]
    if previous is not None:
        cands.append(("previous", previous, np.zeros_like(previous)))
    costs = [_cost(param, wdata, c[1]) for c in cands]
    costs = [c if np.isfinite(c) else np.inf for c in costs]
    best = int(np.argmin(costs))
    # prefer the solution on ties (it is the converged point)
    if costs[0] <= costs[best]:
        best = 0
    name, x, lam = cands[best]
    return np.asarray(x, float).copy(), np.asarray(lam, float).copy(), name


_TIMING_KEYS = ("t_build", "t_solve", "t_f", "t_grad_f", "t_hess_l")


def _timing(results):
    """Sum of the solver timings (``StageResult.extra``) of one stage's solves."""
    out = {}
    for res in results:
        for k in _TIMING_KEYS:
            if k in (res.extra or {}):
                out[k] = out.get(k, 0.0) + float(res.extra[k])
    return out


def _record(stage, param, z, data, window, omega_c, res, nit, nfev, wall, kept, timing=None):
    model_ratio = _ratio(param, z, data.omega, data.response)
    err = np.abs(model_ratio - 1.0)
    mx, rms = rel_error_stats(err)
    mxw, rmsw = rel_error_stats(err[:window])
    return StageRecord(stage=stage, n_sections=param.structure.n_sections, window=int(window),
                       omega_c=float(omega_c), max_rel_error_window=mxw,
                       rms_rel_error_window=rmsw, max_rel_error=mx, rms_rel_error=rms,
                       nit=int(nit), nfev=int(nfev), wall_time=float(wall), status=res.status,
                       solver_status=res.solver_status, success=bool(res.success), kept=kept,
                       delay=float(param.to_beta(z)[0]),
                       n_active=int(np.count_nonzero(res.active_mask)),
                       timing=_timing([res]) if timing is None else timing)


def _progress_callback(progress):
    if callable(progress):
        return progress
    if not progress:
        return lambda rec: None

    def write(rec):
        where = "" if math.isnan(rec.omega_c) else f" at {rec.omega_c:.4g} rad/s"
        label = ("rational start" if rec.solver_status == "vector-fitting" else
                 rec.kept if rec.kept.startswith("minimax") else
                 "final" if rec.stage > rec.n_sections else f"stage {rec.stage:2d}")
        sys.stderr.write(
            f"{label}: {rec.n_sections:2d} sections{where}, window {rec.window}, "
            f"max rel. error {rec.max_rel_error:.3e} (window {rec.max_rel_error_window:.3e}), "
            f"{rec.nit} it, {rec.wall_time:.2f} s, {rec.solver_status}\n")
        sys.stderr.flush()

    return write


STAGE_TERMINATION = {"stage": {}, "final": {}}


class _StageSolver:
    """Builds the stage's CasADi functions once and calls the chosen solver."""

    def __init__(self, method, hessian, max_iter, ipopt_options, lm_options, warm, bound_delay,
                 derivatives=None, zeta_min=None):
        self.derivatives = derivatives
        self.zeta_min = zeta_min
        self.method = method
        self.hessian = hessian
        self.max_iter = max_iter
        self.ipopt_options = ipopt_options
        self.lm_options = lm_options or {}
        self.warm = warm
        self.bound_delay = bound_delay

    def __call__(self, param, wdata, x0, lam0, max_iter=None):
        from .solvers.common import Termination

        final = max_iter is not None
        term = Termination(**STAGE_TERMINATION["final" if final else "stage"])
        funcs = stage_functions(param, wdata.omega, wdata.response, wdata.weights,
                                derivatives=self.derivatives)
        lb, ub = param.bounds()
        if not self.bound_delay and param.structure.delay:
            ub[0] = np.inf
        if self.method == "ipopt":
            cons = None
            if self.zeta_min is not None and param.structure.n_sections:
                cons = param.damping_constraints(self.zeta_min)
                x0 = param.project_damping(x0, self.zeta_min)
            res = solve_least_squares(funcs, x0, lb, ub, lam_x0=lam0,
                                      hessian=self.hessian,
                                      max_iter=max_iter or self.max_iter,
                                      warm_start=self.warm,
                                      ipopt_options=self.ipopt_options, constraints=cons,
                                      termination=term)
            if cons is not None:
                # IPOPT meets g >= 0 to its tolerance; make the floor exact
                res = dataclasses.replace(res, x=param.project_damping(res.x, self.zeta_min))
            return res
        return _solve_barrier_lm(funcs, x0, lb, ub, self.lm_options)


def _solve_barrier_lm(funcs, x0, lb, ub, lm_options):
    """The thesis's SUMT + LM on the same residual/Jacobian Functions as the IPOPT path.

    Fixed variables (``lb == ub``, e.g. the delay of a structure without delay) are removed;
    the start is moved strictly inside the bounds (the barrier is infinite on them). The
    barrier method has no upper bounds: the delay's data-derived bound is not imposed.
    """
    from .solvers.barrier_lm import barrier_lm
    from .solvers.common import StageResult, find_active_constraints

    x0 = np.asarray(x0, float)
    free = lb < ub
    xf = x0.copy()

    def full(v):
        xf[free] = v
        return xf

    def fun(v):
        return funcs.residual(full(v))

    def jac(v):
        return funcs.residual_jacobian(full(v))[1][:, free]

    v0 = np.maximum(x0[free], lb[free] + 1e-6 * np.maximum(1.0, np.abs(x0[free])))
    res = barrier_lm(fun, jac, v0, lb=lb[free], **lm_options)
    x = x0.copy()
    x[free] = res.x
    lam = np.zeros_like(x)
    lam[free] = res.lam_x
    return StageResult(x=x, cost=res.cost, status=res.status, message=res.message,
                       success=res.success, nit=res.nit, nfev=res.nfev,
                       wall_time=res.wall_time,
                       active_mask=find_active_constraints(x, lb, ub, rtol=1e-6),
                       lam_x=lam, solver_status=res.solver_status, extra=res.extra)
