"""The public :func:`fit` and its :class:`FitResult` (layer L5).

The pipeline, in the order a call runs it (each step one function, in this module unless
named):

1. ``fit``: the keywords checked (integrator, delay, progress, fixed), the progress channel
   opened; ``n_sections="auto"`` goes to :func:`_fit_auto_order`
   (:mod:`~freqid_casadi.fitting.order`: one fit per order, the smallest that explains
   the data).
2. ``integrator="auto"``: :func:`~freqid_casadi.fitting.origin.choose_origin_order` picks
   the poles/zeros at the origin from rational starts (full fits settle a close call).
3. :func:`_fit_resolved` -> ``fixed=`` (:mod:`~freqid_casadi.fitting.fixed`) or
   :func:`_fit_guarded`: the resolution guard (:mod:`~freqid_casadi.fitting.guard`)
   around :func:`_fit_held`.
4. :func:`_fit_held`: :func:`_fit`, then the undetermined delay held
   (:mod:`~freqid_casadi.fitting.delay_hold`) and the free-zeros alternative
   (:func:`_with_alternatives`, :mod:`~freqid_casadi.fitting.alternatives`).
5. :func:`_fit`: the data checked (:mod:`~freqid_casadi.fitting._checks`), the gain sign
   (:mod:`~freqid_casadi.fitting.diagnostics`), the scales (:mod:`~freqid_casadi.core.scaling`);
   the starts and candidates (:func:`_run_starts`: the thesis's sequential loop, SPEC §2,
   and the rational start, :mod:`~freqid_casadi.fitting.mainloop`; the h = 0 candidates,
   screened, and the rescues of an unconverged fit, :mod:`~freqid_casadi.fitting.candidates`);
   the optional minimax polish; the model mapped back to the user's units; the
   diagnostics and the verdict (:mod:`~freqid_casadi.fitting.verdict`: status, message,
   details).

Every stage is one NLP (:mod:`freqid_casadi.fitting.stages`, :mod:`freqid_casadi.solvers`).
"""
import dataclasses
import functools
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .alternatives import ORIGIN_AUTO, free_zeros_alternative, origin_auto
from .candidates import NEAR, Candidate, choose, zero_delay_run
from .core_fits import (choose_on_subset, core_fits, either_sign_fits, settle_on_subset,
                        settled_sign_fit, settles_on_subset, sign_on_subset)
from ._checks import (GAIN_SIGNS, after_fit, check_model_class, not_usable_between_samples,
                      spare_far_pair, validate, verdict, zeta_min_of)
from .._validate import check_choice, check_flag, check_jobs
from ..core.data import FrequencyData
from .delay_hold import hold_undetermined_delay
from .delay_search import delay_search_run
from .far_roots import far_root_run
from .fixed import check_fixed, fit_with_fixed
from .diagnostics import gain_sign_decision
from .guard import guard_resolution, warn_unresolved as _warn_unresolved
from ..errors import FreqidError, OptionError, ResolutionWarning
from .noise_weights import fit_with_noise_weights
from .order import MAX_SECTIONS, choose_order, with_free_zeros, with_order_record
from .mainloop import LoopContext, minimax, rational, sequential
from ..core.metrics import relative_error
from ..core.model import (MAX_ORIGIN_ORDER, ZEROS, RationalDelayModel, Structure,
                          check_origin_order)
from .origin import (describe_origin, origin_diagnostics, recause_poor_fit,
                     restate_roots_below_band, settle_by_results)
from ..options import (INITS, LEGACY_KEYWORDS, METHODS, WARM_STARTS, FitOptions, LoopOptions,
                      legacy_message, solver_options)
from ..core.scaling import (check_finite_result, reference_scales, scale_data, unscale_model,
                      weighted_span)
from ..core.resolution import check_resolution, default_delay_max, resolution_damping
from .._progress import channel, check_progress
from .._malloc import heap_kept
from .._workers import allow_jobs
from .._threads import single_threaded_blas
from .stages import Kept, StageKind, StageRecord, StageSolver
from .start import RationalStartError, rational_start_memo
from .verdict import ROUNDING_RMS, FitStatus, residual_noise

__all__ = ["fit", "FitResult", "FitStatus", "StageRecord", "Kept", "StageKind", "METHODS", "INITS",
           "WARM_STARTS", "STARTS", "OBJECTIVES", "GAIN_SIGNS", "default_delay_max",
           "resolution_damping"]

STARTS = ("sequential", "rational", "best")
OBJECTIVES = ("least-squares", "minimax")


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
        True when the final model is at a (local) optimum within tolerance: the final
        all-data stage converged (IPOPT's tolerance, or the scale-free relative
        stationarity test of :mod:`freqid_casadi.solvers.termination`, which a fit at
        machine precision passes, or, on noisy data, converged to the noise: its last
        iterations moved the model by far less than its standard errors with the
        residual at the noise, ``IpoptOptions.noise_stall``; ``details["final_stage"]
        ["noise_stall"]`` then holds the numbers) and the model is better than an
        infinite gain (RMS relative error < 1). ``message`` says why not. Whether the
        model explains the data is ``status``.
    status : FitStatus
        The verdict (a ``str`` enum, :mod:`freqid_casadi.fitting.verdict`): "ok"
        (converged and the residual is consistent with the noise, estimated from the
        weights' shape and the residual's point-to-point scatter, or at rounding level),
        "poor-fit" (converged, but the residual has structure well above the noise; a
        ``poor-fit`` diagnostic says why: model class, order, sign or delay) or
        "not-converged" (the final stage did not converge).
    wall_time : float
        Seconds for the whole :func:`fit` call (with ``integrator="auto"``, its
        contenders' fits; with ``n_sections="auto"``, every order tried).
    method : str
        "ipopt" or "barrier-lm" (the type of ``options.solver``).
    options : FitOptions
        The options the fit ran with: fit's keywords and the typed ``solver``
        (IpoptOptions or BarrierLMOptions) and ``loop`` (LoopOptions) objects.
    start : str
        Which start produced the model ("sequential" or "rational").
    objective : str
        "least-squares", or "minimax" if the max-error polish (p-norm continuation) ran.
    resolution : freqid_casadi.core.resolution.ResolutionCheck or None
        The model checked against the data's frequency spacing (None for the first-order
        basis, whose real roots are never narrow); when ``resolution.ok`` is False,
        :func:`fit` also issued a :class:`~freqid_casadi.errors.ResolutionWarning`.
    start_max_rel_errors : dict of str to float
        Max relative error over all data of the model of each start that ran
        ("sequential", "rational"), before the minimax polish.
    delay_max : float
        Upper bound of the delay used (s): ``LoopOptions.delay_max`` or
        :func:`default_delay_max` of the data.
    zeta_min : float or None
        The damping floor used (``min_damping`` resolved; None without one).
    diagnostics : tuple of Diagnostic
        What the checks before and after the fit found about the data and the model
        class (:mod:`freqid_casadi.fitting.diagnostics`): ``negative-gain``,
        ``non-minimum-phase``, ``delay-undetermined``, ``no-better-than-trivial``. A
        record of severity "error" makes ``success`` False.
    candidate_max_rel_errors : dict of str to float
        Max relative error of every candidate :func:`fit` chose from: the starts and,
        with a delay, each start's model at h = 0 ("<start> at h=0"; absent when its
        screen abandoned it or the data's phase ruled it out,
        :func:`~freqid_casadi.fitting.candidates.zero_delay_run`) and, for a start
        that did not converge, its delay search ("<start>, delay search",
        :mod:`freqid_casadi.fitting.delay_search`) and its roots far above the band at infinity
        ("<start>, far roots", :mod:`freqid_casadi.fitting.far_roots`), see
        :func:`~freqid_casadi.fitting.candidates.choose`.
    message : str
        One plain sentence led by the status: the errors and the next step (e.g.
        "not-converged: the final stage reached its iteration limit (200) ...; pass
        method=IpoptOptions(final_max_iter=2000) to continue").
    details : dict
        The numbers behind ``status`` and ``message``: ``final_stage`` (the final
        stage's ``StageRecord.details``: termination test's cosines and projection,
        IPOPT's return status, iterations and limit) and ``noise`` (the residual's
        consistency check, :func:`~freqid_casadi.fitting.verdict.residual_noise`:
        ``noise_rms``, ``ratio``, ``runs_z``, ``worst_omega``).
    alternatives : dict of str to FitResult
        Better models outside the class asked for: ``"zeros=free"``, the fit with
        ``zeros="free"`` (stable poles, zeros anywhere), computed when the
        ``non-minimum-phase`` diagnostic finds that the data need right-half-plane zeros
        (the diagnostic then gives both errors and the switch). The result's own model
        stays minimum phase.
    fixed : dict of str to float
        The parameters held at known values (fit's ``fixed``: "delay" in s, "dc_gain");
        empty when none. The covariance (:attr:`uncertainty`) treats them as known.
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
    options: FitOptions = None
    start: str = "sequential"
    objective: str = "least-squares"
    resolution: object = None
    start_max_rel_errors: dict = field(default_factory=dict)
    candidate_max_rel_errors: dict = field(default_factory=dict)
    delay_max: float = math.nan
    zeta_min: float = None
    diagnostics: tuple = ()
    message: str = ""
    fixed: dict = field(default_factory=dict)
    status: FitStatus = FitStatus.NOT_CONVERGED
    details: dict = field(default_factory=dict)
    alternatives: dict = field(default_factory=dict)

    @property
    def delay(self):
        return self.model.delay

    def options_dict(self):
        """Flat dict of the options (:meth:`FitOptions.as_dict`) with the values the fit
        used: ``delay_max`` and ``min_damping`` resolved, ``start_max_rel_errors`` and
        ``start_used``; for reports and JSON."""
        out = self.options.as_dict() if self.options is not None else {}
        out.update(delay_max=self.delay_max, min_damping=self.zeta_min,
                   start_max_rel_errors=dict(self.start_max_rel_errors),
                   start_used=self.start)
        return out

    @functools.cached_property
    def uncertainty(self):
        """How well the data determine the model: the covariance of its physical
        parameters (delay, log gain, each factor's natural frequency and damping) from the
        weighted Jacobian of the relative residual at the optimum, with the noise variance
        from the residuals (or the data's weights), propagated to every mode, the gain and
        the delay (``delay_std``, ``gain_std``, ``modes[k].omega_n_std``, ``zeta_std``);
        parameters at a bound are reported as at the bound. Computed on first access
        (:func:`freqid_casadi.uncertainty.covariance.parameter_uncertainty`).

        Returns
        -------
        freqid_casadi.uncertainty.covariance.ParameterUncertainty
        """
        from ..uncertainty.covariance import parameter_uncertainty

        return parameter_uncertainty(self)

    @property
    def nit(self):
        """IPOPT/LM iterations summed over all stages."""
        return int(sum(s.nit for s in self.stages))

    @property
    def modes(self):
        """The model's modes (:func:`freqid_casadi.core.modes.modes`), one residue each, by
        increasing frequency, with ``omega_n_std`` and ``zeta_std`` from
        :attr:`uncertainty` (None where the covariance cannot be formed).

        A :class:`~freqid_casadi.core.modes.Modes`: a tuple that is also callable, so
        ``res.modes`` and ``res.modes()`` (the spelling of earlier versions) are the same,
        as on :attr:`SharedFitResult.modes <freqid_casadi.modal.shared.SharedFitResult>`.

        Returns
        -------
        Modes
            Tuple of freqid_casadi.core.modes.Mode.
        """
        from ..uncertainty.covariance import with_std
        from ..core.modes import Modes, modes

        found = modes(self.model)
        try:
            return Modes(with_std(found, self.uncertainty))
        except (FreqidError, np.linalg.LinAlgError, ArithmeticError):
            return found

    def summary(self):
        """Lines led by the status: the message (which starts with it), then the model's numbers,
        then one per diagnostic."""
        m = self.model
        line = (f"{self.data.name or 'data'}: {m.n_sections} sections (order {m.order}), "
                f"max rel. error {self.max_rel_error:.4g}, RMS {self.rms_rel_error:.4g}, "
                f"delay {m.delay:.6g} {self.data.time_unit}, "
                f"{self.wall_time:.2f} s, method {self.method}")
        return "\n".join([self.message, line] + [f"  {d.severity}: {d}" for d in self.diagnostics])


def _public(function):
    """Wrap :func:`fit` so that a keyword it no longer takes raises a TypeError naming
    the option object it moved to (:data:`~freqid_casadi.options.LEGACY_KEYWORDS`), and
    its result's ``wall_time`` counts the whole call (the automatic integrator's
    contenders, the layers after the core fit, every order of ``n_sections="auto"``);
    ``__wrapped__`` keeps the real signature for :func:`inspect.signature`. (One frame
    for both: the warnings' ``stacklevel`` counts it.)"""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        for name in kwargs:
            if name in LEGACY_KEYWORDS:
                raise TypeError(legacy_message(function.__name__, name, kwargs[name]))
        t_start = time.perf_counter()
        result = function(*args, **kwargs)
        return dataclasses.replace(result, wall_time=time.perf_counter() - t_start)

    return wrapper


@_public
def fit(data_or_omega, response=None, *, n_sections, integrator="auto", delay=True,
        basis="second-order", method="ipopt", tol=None, weights=None, start="best",
        objective="least-squares", min_damping=None, progress=False, loop=None,
        gain_sign="auto", zeros="minimum-phase", fixed=None, n_jobs=1):
    """Fit ``G_N(s) = exp(-h s) K s^(-k) P_N(s)`` to frequency-response data.

    Parameters
    ----------
    data_or_omega : FrequencyData or array_like of float, shape (M,)
        The data, or the frequencies in rad/s (then ``response`` is required); a
        python-control ``FrequencyResponseData`` (SISO) or a scikit-rf one-port
        ``Network`` is converted (:func:`~freqid_casadi.core.data.as_frequency_data`).
    response : array_like of complex, shape (M,), optional
        G(j omega) when ``data_or_omega`` is the frequency array.
    n_sections : int, "auto" or range
        Number of sections N >= 1 (order 2N, or 2N+1 with the integrator; N with the
        first-order basis). "auto": the smallest N whose residual is consistent with the
        noise and whose modes N + 1 sections keep (:mod:`freqid_casadi.fitting.order`), N
        from 1 up to :data:`~freqid_casadi.fitting.order.MAX_SECTIONS`; a range (e.g.
        ``range(1, 9)``: at most 8 sections) sets the orders tried. An ``order-chosen``
        diagnostic says why the search stopped.
    integrator : "auto", bool or int
        The poles at the origin, the factor ``s^(-k)``: True (k = 1, the factor K0/s),
        False (k = 0), an integer k with ``|k| <= 3`` (k poles at the origin: 2 for a
        motor's current-to-angle response; a negative k for -k zeros there: -2 for an
        accelerance, -1 for a band-pass), or "auto" (default): k chosen from the rational
        starts of a few candidates (:mod:`freqid_casadi.fitting.origin`), recorded in
        ``details["integrator"]`` and ``options.integrator`` (``options.integrator_auto``
        True); an ``integrator`` diagnostic states a choice other than 0, or says "pass
        integrator=..." with the errors of each choice when the data do not decide. Above
        :data:`~freqid_casadi.fitting.core_fits.SETTLE_ABOVE` frequencies the starts see
        a subset of the points, the k they leave undecided are fitted on it when it
        represents them (:func:`~freqid_casadi.fitting.core_fits.settle_on_subset`), and
        the kept k on all.
    delay : bool
        Fit a delay h >= 0 (else h = 0).
    basis : {"second-order", "first-order"}
    method : {"ipopt", "barrier-lm"} or IpoptOptions or BarrierLMOptions
        The stage solver: IPOPT with true bounds (the package's method) or the thesis's
        log-barrier + Levenberg-Marquardt (SPEC §3). A string means that method's default
        options; an option object (:mod:`freqid_casadi.options`) selects the method by its
        type and carries its knobs (Hessian, warm start, iteration limits, extra IPOPT or
        LM options).
    tol : float, optional
        Stop adding sections once the max relative error over all data is below ``tol``.
    weights : array_like of float, shape (M,), optional
        Weights of the squared relative residuals (overrides ``data.weights``); only their
        ratios matter (the fit divides them by the largest, then by a power of two near
        the mean of that ratio; uniform weights of any size fit exactly like none). At least
        as many points as parameters need a weight > 0; points of weight 0 below the first
        weighted one are left out of the loop's windows (their error is still reported).
        ``"noise"``: estimated from the data (:mod:`freqid_casadi.fitting.noise_weights`):
        a fit without weights, then the fit weighed by the inverse relative variance its
        residual shows (for an analyser's noise floor, whose relative level varies over
        the band as ``1 / |G|``); twice the time, a ``noise-weights`` diagnostic with the
        numbers of both.
    start : {"best", "sequential", "rational"}
        "best" (default, as ``fit_shared`` and ``freqid fit``) runs the rational start,
        then the sequential loop unless the rational start already explains the data to
        their noise (``details["start_skipped"]`` then says so), and keeps the better
        (below). "sequential" is the thesis's main loop (pass it to
        reproduce the thesis's numbers); "rational" fits all sections at once by
        vector fitting with the delay refined from the right-half-plane zeros
        (:mod:`freqid_casadi.fitting.start`), then polishes everything by one IPOPT stage on all
        data; "best" keeps, among the models within 10 % of the lowest max
        relative error, a converged one if any, then the lower RMS error
        (:func:`~freqid_casadi.fitting.candidates.choose`; ``FitResult.start`` says which won).
        With a delay, every start also tries the same model at h = 0, polished without
        the delay, so a fit with a delay is never worse than that fit at h = 0 (not
        needed, so not tried, for a rational start that explains the data to their
        noise).
    objective : {"least-squares", "minimax"}
        "minimax" adds a polish of the max relative error: a continuation in p of the
        p-norm of the residuals (p = 4 ... 1024, :data:`PNORM_SCHEDULE`), each stage an
        IPOPT NLP with true bounds; kept only if it lowers the max relative error (and the
        start is below 1).
    min_damping : {None, "auto"} or float
        A floor on the damping ratio of every pole and zero, imposed as constraints of each
        stage NLP (``c1^2 >= 4 zeta_min^2 c2`` per quadratic; dc gauge, second-order
        basis, IPOPT). "auto" ties it to the data's frequency resolution
        (:func:`resolution_damping`): no pole or zero narrower than the local spacing, so
        a pole/zero pair cannot fit noise at one sample and be wrong between samples. For
        noisy data (it biases lightly damped modes narrower than the spacing); the value
        used is ``FitResult.zeta_min``.
    progress : bool, "lines" or callable
        True draws a progress bar on a terminal and elsewhere writes a line per 30 s of a
        long run; "lines" writes one line per stage to stderr; a callable receives each
        StageRecord (the same channel as fit_shared, sweep, stabilization, fit_many and
        bootstrap).
    loop : LoopOptions, optional
        Knobs of the main loop (gauge, new-section init, scaling, delay bound, final
        stage, derivative evaluation); default ``LoopOptions()``.
    gain_sign : {"auto", "positive", "negative"}
        Sign of the gain K. "auto" takes the sign under which the rational start explains
        the data far better (both signs tried, vector fitting only:
        :func:`~freqid_casadi.fitting.diagnostics.rational_gain_sign`), not the phase at
        the lowest bins (which a delay and a pole below the band turn past
        -90 deg); when neither start does, both signs are fitted and the lower RMS is
        kept (``details["gain_sign"]`` gives both; above 16 384 frequencies both are
        fitted on 4096 of them when that subset tells them apart, and the kept sign on
        all: :func:`~freqid_casadi.fitting.core_fits.sign_on_subset`). A negative gain (a
        sign-inverted sensor or transmissibility) is fitted as ``-(fit of -Phi)`` and
        stated by a ``negative-gain`` diagnostic.
    zeros : {"minimum-phase", "free"}
        "minimum-phase" (the thesis's class): every zero in the closed left half plane.
        "free": the numerators are unbounded (zeros anywhere, e.g. non-collocated sensors
        or accelerances whose excess phase no delay explains), the poles stay stable by
        their bounds; needs the IPOPT method, the dc gauge and no damping floor.
    fixed : dict, optional
        Known parameters held exactly (:mod:`freqid_casadi.fitting.fixed`):
        ``{"delay": h}`` (s, >= 0) is removed from the variables (the fit runs on
        ``Phi exp(j w h)`` without a delay; the model's delay is ``h`` exactly);
        ``{"dc_gain": k}``, the low-frequency gain (``K0`` of ``K0/s`` with an integrator,
        ``G(0)`` without; signed, a negative ``k`` means ``gain_sign="negative"``), is held
        by an equality in a final stage on all data (gain variable fixed in the dc gauge,
        every other parameter refitted). Both may be given. ``FitResult.fixed`` records
        them; the covariance reports them as fixed. Other keys: OptionError.
    n_jobs : int
        Worker processes for the independent fits of the starts and candidates: one per
        contender of ``integrator="auto"`` when the starts leave several, and one per gain
        sign when the rational starts do not decide the sign (``gain_sign="auto"``); and
        the rational starts of the integrator's choice and of the non-minimum-phase check,
        one per k, when the first took at least 0.1 s. 1 (default) runs them here, one
        after the other; -1 uses every core. The workers are forked (Linux, and only when
        this process runs no other thread; elsewhere the fits run here): the result is
        the same, bit for bit, whatever ``n_jobs``.

    Returns
    -------
    FitResult

    Raises
    ------
    DataError, StructureError, OptionError
        Bad data or options (checked before any solve).
    TypeError
        A keyword fit() no longer takes (``gauge=``, ``hessian=``, ...): the message names
        the option object and field it moved to.
    """
    if isinstance(weights, str):
        return _fit_noise_weighted(locals())
    if isinstance(n_sections, (str, range)):
        return _fit_auto_order(locals())
    auto = _is_auto(integrator)
    integrator = "auto" if auto else check_origin_order(integrator, OptionError)
    delay = check_flag("delay", delay)
    progress = check_progress(progress, "each StageRecord")
    n_jobs = check_jobs(n_jobs, every_core=True)
    fixed, gain_sign = check_fixed(fixed, delay=delay, gain_sign=gain_sign)
    kw = dict(integrator=integrator, basis=basis, method=method, tol=tol, start=start,
              objective=objective, min_damping=min_damping, loop=loop, gain_sign=gain_sign,
              zeros=zeros)
    with single_threaded_blas(), heap_kept(), rational_start_memo(), origin_auto(auto), \
            allow_jobs(n_jobs), channel(progress, _stage_line) as emit:
        if auto:
            data = validate(data_or_omega, response, n_sections, basis, tol, False, weights)
            check_choice("zeros", zeros, ZEROS)
            k, record = choose_on_subset(data, n_sections, delay, basis, zeros)
            ks = record["contenders"]
            if len(ks) == 1 or fixed:
                results = {}
                for j in ks:         # several (the starts do not decide): quiet, the fits do
                    with warnings.catch_warnings():
                        if len(ks) > 1:
                            warnings.simplefilter("ignore")
                        results[j] = _fit_resolved(data_or_omega, response, n_sections,
                                                   delay, fixed, weights,
                                                   emit if j == k else False,
                                                   dict(kw, integrator=check_origin_order(j)))
                if len(ks) > 1:
                    record = settle_by_results(record, results, data)
                    kept = results[record["chosen"]]
                    _warn_unresolved(kept, 4)                             # its warning
                return _with_origin_record(results[record["chosen"]], record,
                                           origin_diagnostics(record, data))
            # many points: the contenders' fits on every k-th point settle the choice when
            # that subset represents each one's residual; the kept k is fitted on all
            settled = settle_on_subset(_quiet_fit, _sign_guess, data, record, n_jobs,
                                       dict(kw, n_sections=n_sections, delay=delay))
            if settled is not None:
                result = _fit_resolved(data_or_omega, response, n_sections, delay, fixed,
                                       weights, emit, dict(kw, integrator=check_origin_order(
                                           settled["chosen"])))
                return _with_origin_record(result, settled, origin_diagnostics(settled, data))
            # several contenders (the starts do not decide): each one's fit of the starts
            # and candidates settles the choice (quiet); the layers after it (the delay hold,
            # the zeros="free" alternative, the resolution guard) run for the chosen one only,
            # from its fit
            core = core_fits(_quiet_fit, _sign_guess, (data_or_omega, response), ks, k,
                             emit, n_jobs, dict(kw, n_sections=n_sections, delay=delay,
                                                weights=weights))
            record = settle_by_results(record, core, data)
            chosen = record["chosen"]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = _fit_resolved(data_or_omega, response, n_sections, delay, fixed,
                                       weights, False,
                                       dict(kw, integrator=check_origin_order(chosen)),
                                       first=core[chosen])
            _warn_unresolved(result, 4)                                   # its warning
            return _with_origin_record(result, record, origin_diagnostics(record, data))
        return _fit_resolved(data_or_omega, response, n_sections, delay, fixed, weights,
                             emit, kw)


def _quiet_fit(data_or_omega, response, kw):
    """:func:`_fit` with its warnings ignored (a contender's fit; the kept one warns)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _fit(data_or_omega, response, **kw)


def _is_auto(integrator):
    """Whether ``integrator`` is "auto" (another string is an OptionError)."""
    if isinstance(integrator, str):
        if integrator != "auto":
            raise OptionError(f"integrator must be 'auto', True, False or an integer k with "
                              f"|k| <= {MAX_ORIGIN_ORDER}, got {integrator!r}; e.g. "
                              "integrator=2 for two poles at the origin")
        return True
    return False


def _with_origin_record(result, record, found):
    """``result`` of ``integrator="auto"``: the choice in ``details["integrator"]`` and
    ``options`` (``integrator_auto``), its diagnostic first, the summary line saying it."""
    options = result.options
    if options is not None:
        options = dataclasses.replace(options, integrator_auto=True)
    message = result.message
    if record["chosen"] != 0 or record["ambiguous"]:
        message = (f"{message}; integrator='auto' chose {describe_origin(record['chosen'])}"
                   + (" (ambiguous: see the integrator diagnostic)" if record["ambiguous"]
                      else ""))
    diagnostics, message = recause_poor_fit(
        tuple(found) + restate_roots_below_band(result.diagnostics, record), message,
        result.model.n_sections, getattr(result.data, "unit", "rad/s"))
    return dataclasses.replace(result, options=options, message=message, details=dict(
        result.details, integrator=record), diagnostics=diagnostics)


def _fit_resolved(data_or_omega, response, n_sections, delay, fixed, weights, emit, kw,
                  first=None):
    """The fit once the poles at the origin are known (``kw["integrator"]``); ``first``:
    its :func:`_fit`, already run (not with ``fixed``)."""
    if fixed:
        data = validate(data_or_omega, response, n_sections, kw["basis"], kw["tol"],
                        kw["integrator"], weights)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", category=ResolutionWarning)
            result = fit_with_fixed(
                lambda d, dl: _fit_held(d, None, n_sections=n_sections, delay=dl,
                                        progress=emit, weights=None, **kw),
                data, fixed, delay=delay, loop=kw["loop"], method=kw["method"])
        _warn_unresolved(result, 5)
        return result
    return _fit_guarded(data_or_omega, response, n_sections=n_sections, delay=delay,
                        progress=emit, weights=weights, first=first, **kw)


def _fit_noise_weighted(args):
    """``fit(..., weights="noise")`` (``args``: fit's keywords): :func:`~freqid_casadi.
    fitting.noise_weights.fit_with_noise_weights`."""
    args = dict(args)
    spelt, data, response = (args.pop(k) for k in ("weights", "data_or_omega", "response"))
    return fit_with_noise_weights(lambda d, r, w: fit(d, r, weights=w, **args), data,
                                  response, spelt)


def _fit_auto_order(args):
    """``fit(..., n_sections="auto" | range)``: :func:`~freqid_casadi.fitting.order.
    choose_order` over fits at each order (``args``: fit's keywords)."""
    args = dict(args)
    n = args.pop("n_sections")
    orders = range(1, MAX_SECTIONS + 1) if n == "auto" else n
    if not isinstance(orders, range) or orders.step != 1 or len(orders) == 0 \
            or orders.start < 1:
        raise OptionError(f"n_sections must be a positive integer, 'auto' or a range of "
                          f"orders such as range(1, 9), got {n!r}")
    data, response = args.pop("data_or_omega"), args.pop("response")
    choice = choose_order(lambda k: fit(data, response, n_sections=k, **args),
                          max_sections=orders[-1], min_sections=orders[0])
    if args.get("zeros", "minimum-phase") != "minimum-phase":
        return with_order_record(choice)

    def fit_free(k):
        with warnings.catch_warnings():       # a search the user did not ask for: quiet
            warnings.simplefilter("ignore")
            return fit(data, response, n_sections=k, **dict(args, zeros="free",
                                                            progress=False))
    return with_free_zeros(choice, fit_free, max_sections=orders[-1],
                           min_sections=orders[0])


def _fit_guarded(data_or_omega, response, *, progress, weights, first=None, **kw):
    """:func:`_fit_held`, then :func:`~freqid_casadi.fitting.guard.guard_resolution` (the
    floored refit quiet); the fit's ResolutionWarning is issued here, for the fit that is
    kept, when that one is not resolved."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=ResolutionWarning)
        result = _fit_held(data_or_omega, response, progress=progress, weights=weights,
                           first=first, **kw)

    def refit(min_damping):
        return _fit_held(data_or_omega, response, progress=False, weights=weights,
                         **dict(kw, min_damping=min_damping))

    result, _ = guard_resolution(result, refit, kw["min_damping"])
    _warn_unresolved(result, 6)
    return result


def _fit_held(data_or_omega, response, *, progress, weights, first=None, **kw):
    """:func:`_fit` (or ``first``, its result already run), then
    :func:`~freqid_casadi.fitting.delay_hold.hold_undetermined_delay` (its refits quiet, on
    the fit's data with its weights, held in turn)."""
    result = (first if first is not None else
              _fit(data_or_omega, response, progress=progress, weights=weights, **kw))

    def refit(data, n_sections, delay):
        return _fit_held(data, None, progress=False, weights=None,
                         **dict(kw, n_sections=n_sections, delay=delay))

    return _with_alternatives(hold_undetermined_delay(result, refit), data_or_omega,
                              response, weights, kw)


def _with_alternatives(result, data_or_omega, response, weights, kw):
    """:func:`~freqid_casadi.fitting.alternatives.free_zeros_alternative` of ``result``:
    the ``zeros="free"`` fit, with ``integrator="auto"`` at the k of the diagnostic's
    best free-zeros start."""
    def refit(k):
        integrator = check_origin_order(k) if ORIGIN_AUTO.get() else kw["integrator"]
        return _fit_held(data_or_omega, response, progress=False, weights=weights,
                         **dict(kw, zeros="free", integrator=integrator))
    return free_zeros_alternative(result, refit, kw)


def _fit(data_or_omega, response, *, n_sections, integrator, delay, basis, method, tol,
         progress, weights, start, objective, min_damping, loop, gain_sign, zeros,
         sign=None):
    # sign: +1 or -1 fits that sign without a gain-sign record (_fit_either_sign's fits)
    t_start = time.perf_counter()
    solver = solver_options(method)
    loop = LoopOptions() if loop is None else loop
    if not isinstance(loop, LoopOptions):
        raise OptionError(f"loop must be a LoopOptions or None, got {type(loop).__name__}; "
                          "pass loop=LoopOptions(gauge=..., init=..., ...)")
    data = validate(data_or_omega, response, n_sections, basis, tol, integrator, weights)
    check_choice("start", start, STARTS)
    check_choice("objective", objective, OBJECTIVES)
    check_model_class(gain_sign, zeros, solver.method, loop.gauge, min_damping)
    found = ()
    if sign is None:
        sign, found, guess = _sign_decision(data, n_sections, integrator, delay, basis,
                                            zeros, gain_sign)
        if guess:
            return _fit_either_sign(sign, dict(
                n_sections=n_sections, integrator=integrator, delay=delay, basis=basis,
                method=method, tol=tol, progress=progress, weights=weights, start=start,
                objective=objective, min_damping=min_damping, loop=loop,
                gain_sign=gain_sign, zeros=zeros), data_or_omega, response, data)
    user_data = data
    if sign == -1:                  # a negative gain: fit -Phi, the model gets gain_sign -1
        data = FrequencyData(data.omega, -data.response, data.name, data.weights)
    # the problem is scale free: fit omega / w_ref and response / g_ref (powers of two, so
    # O(1) data is fitted bit for bit as given) and map the model back (issue 13 item 3)
    w_ref, g_ref = reference_scales(data)
    data = scale_data(data, w_ref, g_ref)
    fit_data = weighted_span(data)  # the loop starts at the first point with a weight > 0
    zeta_min = zeta_min_of(min_damping, fit_data.omega, solver.method, loop.gauge, basis)
    dmax = (float(loop.delay_max) * w_ref if loop.delay_max is not None
            else default_delay_max(fit_data.omega))
    user_callback = progress if callable(progress) else (lambda rec: None)
    unscaled = {}

    def callback(rec):              # the user sees (and FitResult keeps) the same records
        unscaled[id(rec)] = (rec, _unscale_record(rec, w_ref))
        user_callback(unscaled[id(rec)][1])

    ctx = LoopContext(
        data=fit_data, callback=callback,
        solve=StageSolver(solver, loop, zeta_min),
        structure=Structure(int(n_sections), integrator, delay, basis, zeros), loop=loop,
        warm_start=solver.warm_start, delay_max=dmax, final_max_iter=solver.final_max_iter,
        zeta_min=zeta_min)
    options = FitOptions(n_sections=int(n_sections), integrator=integrator,
                         delay=bool(delay), basis=basis, method=solver.method, tol=tol,
                         start=start, objective=objective, min_damping=min_damping,
                         solver=solver, loop=loop)
    param, z, records, won, errors, cand_errors, skipped = _run_starts(ctx, start, tol,
                                                                       fit_data)
    if objective == "minimax":
        z, rec = minimax(ctx, param, z)
        records.append(rec)
    model_scaled = param.to_model(z)
    stats = relative_error(model_scaled, data)
    check_finite_result(model_scaled.structure, model_scaled.beta, stats.values)
    model = unscale_model(model_scaled, w_ref, g_ref)
    if sign == -1:
        model = RationalDelayModel(dataclasses.replace(model.structure, gain_sign=-1),
                                   model.beta)
    records = [unscaled[id(r)][1] if id(r) in unscaled else _unscale_record(r, w_ref)
               for r in records]
    scaled_omega, scaled_response = data.omega, data.response
    data = user_data     # stats stay the scaled problem's (no overflow at extreme omega)
    check = _resolution_check(model, data.omega)
    with np.errstate(all="ignore"):     # extreme user scales: a check may give up, not warn
        residual = scaled_response / model_scaled.frequency_response(scaled_omega) - 1.0
        noise = residual_noise(residual, data.omega, data.weights)     # once, for both
        found += after_fit(model, data, stats, dmax / w_ref, noise=noise)
    success, status, message, details, found = verdict(
        _final_stages(records)[-1], stats, residual, data, found, int(n_sections), start, noise)
    message = spare_far_pair(not_usable_between_samples(message, check, min_damping), model, data)
    details = dict(details, start_skipped=skipped) if skipped else details
    return FitResult(model=model, stages=tuple(records), data=data, rel_error=stats.values,
                     max_rel_error=stats.max, rms_rel_error=stats.rms,
                     success=success, message=message, wall_time=time.perf_counter() - t_start,
                     method=solver.method, options=options, start=won, objective=objective,
                     resolution=check, start_max_rel_errors=errors,
                     candidate_max_rel_errors=cand_errors, delay_max=dmax / w_ref,
                     zeta_min=zeta_min, diagnostics=found, status=status, details=details)


def _fit_either_sign(guess, kw, data_or_omega, response, data):
    """Both gain signs fitted, the lower RMS kept (``guess``, the low-frequency phase's
    sign, on a tie; :func:`~freqid_casadi.fitting.core_fits.either_sign`), when the
    rational starts did not decide the sign: a band far from the static gain (a
    transmission measurement at 140-220 GHz, a reflection) shows a phase there that a
    delay, poles below the band and zeros at the origin have turned; the sign is then a
    model choice the fits make, and the result says so. Above
    :data:`~freqid_casadi.fitting.core_fits.SETTLE_ABOVE` points (``data``: validated)
    the two signs are fitted on a subset and the kept one on all points
    (:func:`~freqid_casadi.fitting.core_fits.sign_on_subset`)."""
    settled = sign_on_subset(_quiet_fit, data, kw, guess)
    if settled is not None:
        return settled_sign_fit(_quiet_fit, (data_or_omega, response), kw, settled)
    return either_sign_fits(_quiet_fit, (data_or_omega, response), kw, guess)


def _sign_decision(data, n_sections, integrator, delay, basis, zeros, gain_sign):
    """:func:`~freqid_casadi.fitting.diagnostics.gain_sign_decision` of the validated
    ``data`` for the model :func:`_fit` fits: ``(sign, diagnostics, guess)``."""
    return gain_sign_decision(data, integrator, gain_sign, Structure(
        int(n_sections), integrator, delay, basis, zeros))


def _sign_guess(data_or_omega, response, kw):
    """The gain sign :func:`_fit` with keywords ``kw`` guesses before it fits both signs
    (:func:`_fit_either_sign`), or None when the rational starts decide the sign or the
    fit settles it on a subset of many points (the core fits' plan,
    :func:`~freqid_casadi.fitting.core_fits.core_fits`)."""
    data = validate(data_or_omega, response, kw["n_sections"], kw["basis"], kw["tol"],
                    kw["integrator"], kw["weights"])
    if settles_on_subset(data.n_points):    # the fit settles the sign on a subset itself
        return None
    sign, _, guess = _sign_decision(data, kw["n_sections"], kw["integrator"], kw["delay"],
                                    kw["basis"], kw["zeros"], kw["gain_sign"])
    return sign if guess else None


def _run_starts(ctx, start, tol, data):
    """Run the starts ``start`` asks for and keep one (:func:`candidates.choose`, the h = 0
    model of each start a candidate too); returns ``(param, z, records, won, errors,
    cand_errors)``."""
    runs, skipped = {}, None
    if start in ("rational", "best"):
        # the delay update of the rational start only sees a delay that is too small (it
        # shows as right-half-plane zeros), so it always starts from h = 0
        try:
            runs["rational"] = rational(ctx, 0.0)
        except RationalStartError:
            if start == "rational":
                raise
    explained = "rational" in runs and explains_data(runs["rational"], data)
    if start == "sequential" or (start == "best" and not explained):
        runs = {"sequential": sequential(ctx, tol), **runs}    # (first: choose()'s ties)
    elif start == "best":
        skipped = ("the rational start explains the data to their noise: the sequential "
                   "loop was not run; pass start='sequential' to run it")
    cands = [Candidate.of(name, run, data) for name, run in runs.items()]
    for cand in list(cands):
        if cand.name == "rational" and explained:
            continue            # at the noise already: no model at h = 0 can do better
        zero = zero_delay_run(ctx, cand.run, min(c.rank_max for c in cands))
        if zero is not None:
            cands.append(Candidate.of(f"{cand.name} at h=0", zero, data, cand.start))
    # rescues of an unconverged fit, each from the candidate the fit would then keep (the
    # starts' delays are close: a delay search from each would probe the same delays)
    searched = functools.partial(delay_search_run, with_rational_start="rational" not in runs)
    for label, rescue in (("delay search", searched), ("far roots", far_root_run)):
        first = choose(cands) if cands else None
        if first is not None and not first.success:
            found = rescue(ctx, first.run)             # (reports its own records)
            if found is not None:
                cands.append(Candidate.of(f"{first.start}, {label}", found, data,
                                          first.start))
    cand_errors = {c.name: c.max_rel_error for c in cands}
    errors = {k: v for k, v in cand_errors.items() if k in runs}
    kept = choose(cands)
    won = kept.start
    param, z, lam, records = kept.run
    if kept.name.endswith(" at h=0"):
        ctx.callback(records[-1])
    return param, z, records, won, errors, cand_errors, skipped


def explains_data(run, data):
    """True when the loop's ``run`` (``(param, z, lam, records)``) converged and its
    relative residual on ``data`` is at the data's noise: its RMS at rounding level
    (exact data), or within :data:`~freqid_casadi.fitting.candidates.NEAR` of the noise
    level :func:`~freqid_casadi.fitting.verdict.residual_noise` estimates from the
    residual itself. No other start or candidate can then do meaningfully better (a
    model's RMS does not fall below the noise), and ``start="best"`` keeps it without
    running the sequential loop.

    Stricter than the verdict's "consistent with the noise" (RMS up to twice the noise):
    measured on example A with 2 % noise at 17 sections under ``min_damping="auto"``, the
    rational start ends at RMS 0.0272 (1.45 times the noise, "consistent") where the
    sequential loop reaches 0.0187."""
    param, z, _, records = run
    if not records or not records[-1].success:
        return False
    with np.errstate(all="ignore"):
        residual = data.response / param.to_model(z).frequency_response(data.omega) - 1.0
    if not np.all(np.isfinite(residual)):
        return False
    check = residual_noise(residual, data.omega, data.weights)
    return bool(check["rms"] <= ROUNDING_RMS or check["ratio"] <= NEAR)


def _final_stages(records):
    """The stage records a fit's verdict reads: all but a rejected minimax stage and the
    rational starts (all of them when nothing else is left)."""
    return [r for r in records if r.kept != Kept.MINIMAX_REJECTED
            and r.kind != StageKind.RATIONAL_START] or records


def _resolution_check(model, omega):
    """The model checked against the frequency spacing (None for first-order sections,
    whose real roots are never narrow); :func:`~.guard.warn_unresolved` warns of a failed one."""
    if model.structure.basis != "second-order" or not model.n_sections:
        return None
    return check_resolution(model, omega)


def _unscale_record(rec, w_ref):
    """A stage record of the scaled problem in the user's units (rad/s, s)."""
    return dataclasses.replace(rec, omega_c=rec.omega_c * w_ref, delay=rec.delay / w_ref)


def _stage_line(rec):
    """One line of text for a stage record (``progress="lines"`` and the bar's summary)."""
    where = "" if math.isnan(rec.omega_c) else f" at {rec.omega_c:.4g} rad/s"
    label = {StageKind.RATIONAL_START: ("rational start" if rec.message == "rational start"
                                        else f"{rec.message} (vector fits)"),
             StageKind.MINIMAX: rec.kept, StageKind.FINAL: "final",
             StageKind.DELAY_SEARCH: "delay search, polish",
             StageKind.FAR_ROOTS: "far roots at infinity, polish",
             StageKind.ZERO_DELAY: "at h = 0"}.get(rec.kind, f"stage {rec.stage:2d}")
    return (f"{label}: {rec.n_sections:2d} sections{where}, window {rec.window}, "
            f"max rel. error {rec.max_rel_error:.3e} (window {rec.max_rel_error_window:.3e}), "
            f"{rec.nit} it, {rec.wall_time:.2f} s")


