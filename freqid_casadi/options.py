"""Option objects of :func:`~freqid_casadi.fitting.fit.fit` (layer L1): frozen, self-validating.

The solver and loop knobs of the fit live here, each default in one place (the dataclass
field), each check in ``__post_init__`` raising an :class:`~freqid_casadi.errors.OptionError`
that names the field, its value and the fix. Variants are built with
:func:`dataclasses.replace`, e.g. ``replace(IpoptOptions(), hessian="gauss-newton")``.

- :class:`IpoptOptions`: the package's stage solver, IPOPT with true bounds.
- :class:`BarrierLMOptions`: the thesis's log-barrier + Levenberg-Marquardt stage solver.
- :class:`LoopOptions`: the sequential main loop (parametrization, new sections, scaling).
- :class:`FitOptions`: the record of one fit (``FitResult.options``).
- :class:`VectorFittingOptions`: the vector-fitting start of
  :func:`~freqid_casadi.modal.shared.fit_shared` (its ``start="rational"``); that function's
  IPOPT iteration limits are an :class:`IpoptOptions` (``method=``) as for ``fit``.

``fit(..., method=IpoptOptions(...))`` selects the method by the object's type; a string
method means that method's default options.
"""

import math
import numbers
from dataclasses import dataclass, fields

from ._validate import check_choice, check_flag
from .errors import OptionError

__all__ = ["IpoptOptions", "BarrierLMOptions", "LoopOptions", "FitOptions",
           "VectorFittingOptions", "METHODS",
           "HESSIANS", "WARM_STARTS", "GAUGES", "INITS", "DERIVATIVES", "DAMPING_MODES",
           "LEGACY_KEYWORDS", "solver_options", "options_from_keywords", "legacy_message",
           "warn_renamed", "ipopt_limits"]

#: Stage-solver methods of :func:`~freqid_casadi.fitting.fit.fit`.
METHODS = ("ipopt", "barrier-lm")
#: Hessians of the IPOPT stage: the exact one (analytic second derivatives of the
#: residuals), Gauss-Newton ``2 J^T J``, or IPOPT's own limited-memory quasi-Newton.
HESSIANS = ("exact", "gauss-newton", "limited-memory")
#: What a stage takes from the previous one: point and bound multipliers, point, nothing.
WARM_STARTS = ("primal-dual", "primal", "none")
#: Parametrizations of the sections (:mod:`freqid_casadi.core.objective`).
GAUGES = ("dc", "b1", "raw")
#: Initialisations of a new section.
INITS = ("peak", "identity", "relocate")
#: Evaluations of the stage derivatives (None: "affine" for the dc gauge, else "casadi-map").
DERIVATIVES = (None, "affine", "casadi-map")
#: Damping of the barrier-LM inner steps.
DAMPING_MODES = ("thesis", "marquardt")


def _bad(owner, name, value, requirement):
    return OptionError(f"{owner}.{name} must be {requirement}, got {value!r}")


def _choice(owner, name, value, choices):
    if value is None and None in choices:
        return
    check_choice(name, value, [c for c in choices if c is not None], owner=owner)


def _int_at_least(owner, name, value, low):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise _bad(owner, name, value, f"an integer >= {low}")


def _real(owner, name, value, low=None, strict=True, allow_inf=False):
    """A real number (not bool), finite unless ``allow_inf``, above ``low``."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) \
        and not math.isnan(value) and (allow_inf or math.isfinite(value))
    if ok and low is not None:
        ok = value > low if strict else value >= low
    if not ok:
        where = "" if low is None else f" {'>' if strict else '>='} {low:g}"
        raise _bad(owner, name, value, f"a finite real number{where}")


def _flags(obj, *names):
    """Each field ``names`` of the frozen ``obj`` as a bool (:func:`check_flag`'s rule)."""
    for name in names:
        value = check_flag(name, getattr(obj, name))
        object.__setattr__(obj, name, value)


_IPOPT_OK = set()          # option sets that IPOPT accepted (a probe costs ~2 ms)


def _check_ipopt(owner, pairs):
    """Raise OptionError unless IPOPT accepts the options ``pairs``: they are given to a
    one-variable NLP that is solved once (IPOPT itself knows its option names, types and
    ranges; its complaints on stdout are captured, not shown)."""
    if pairs in _IPOPT_OK:
        return
    import contextlib
    import ctypes
    import io
    import os
    import sys
    import tempfile

    import casadi as ca

    x = ca.MX.sym("x")
    opts = {"ipopt": {"print_level": 0, "sb": "yes", **dict(pairs)}, "print_time": False}
    if sys.stdout is not None:              # None without a console (pythonw, daemons)
        sys.stdout.flush()
    said = io.StringIO()                    # CasADi prints IPOPT's text through sys.stdout
    with tempfile.TemporaryFile() as log, contextlib.redirect_stdout(said):
        saved = os.dup(1)
        os.dup2(log.fileno(), 1)
        try:
            solver = ca.nlpsol("probe", "ipopt", {"x": x, "f": (x - 1) ** 2}, opts)
            solver(x0=0)
            status = solver.stats().get("return_status")
            error = None
        except RuntimeError as exc:
            status, error = None, str(exc)
        finally:
            ctypes.CDLL(None).fflush(None)             # C stdio output, if any
            os.dup2(saved, 1)
            os.close(saved)
        log.seek(0)
        said = (said.getvalue() + log.read().decode("utf-8", "replace")).strip().splitlines()
    if error is None and status != "Invalid_Option":
        _IPOPT_OK.add(pairs)
        return
    why = (error or "").rstrip().splitlines()[-1:] + said[:1]
    raise OptionError(f"{owner}.ipopt = {dict(pairs)!r} is not accepted by IPOPT ("
                      f"{' '.join(w.split(': ', 1)[-1] for w in why) or status}); use IPOPT "
                      "option names, types and ranges (https://coin-or.github.io/Ipopt/"
                      "OPTIONS.html), e.g. {'tol': 1e-12}")


def _stage_limits(owner, obj):
    _choice(owner, "warm_start", obj.warm_start, WARM_STARTS)
    _int_at_least(owner, "max_iter", obj.max_iter, 1)
    _int_at_least(owner, "final_max_iter", obj.final_max_iter, 1)


@dataclass(frozen=True)
class IpoptOptions:
    """Options of the IPOPT stage solver (the package's method).

    Parameters
    ----------
    hessian : {"exact", "gauss-newton", "limited-memory"}
        Hessian of the Lagrangian given to IPOPT: the exact one (analytic second
        derivatives of the residuals plus the constraints' AD Hessian), the Gauss-Newton
        ``2 J^T J``, or IPOPT's limited-memory quasi-Newton update.
    warm_start : {"primal-dual", "primal", "none"}
        What a stage takes from the previous stage: the point and the bound multipliers,
        the point only, or nothing (the stage restarts from stage 0's gain with all
        sections at their insertion values).
    max_iter : int >= 1
        Iteration limit of each intermediate stage (the next stage continues from its
        point, so a stage stopped at the limit is not a failure of the fit).
    final_max_iter : int >= 1
        Iteration limit of the final all-data stage (whose status is ``success``), of the
        rational start's polish and of each p-norm stage of the minimax polish.
    ftol : float >= 0
        Tolerance of the scale-free stationarity test checked after every IPOPT iteration
        (:class:`~freqid_casadi.solvers.termination.Termination`): a stage stops when the
        Gauss-Newton model promises a relative cost decrease of at most ``ftol`` (raised to
        the rounding level at machine precision). ``0`` turns the test (and its LM polish)
        off: IPOPT's own ``tol`` only, the behaviour before issue 14.
    ipopt : mapping of str to str, int or float, optional
        Extra IPOPT options (e.g. ``{"tol": 1e-12}``), applied over the package's. Stored
        as a sorted tuple of ``(name, value)`` pairs (read-only, hashable, picklable);
        :meth:`ipopt_dict` gives a dict.
    noise_stall : (int, float) or None
        ``(window, chi2)``: a fit's final stage that fails the stationarity test of
        ``ftol`` (at ``final_max_iter``, or stopped by IPOPT's step tolerance) counts as
        converged to the noise when its residual is the data's noise (RMS at most twice
        the noise its point-to-point differences show, and above the rounding level) and
        its last ``window`` iterations lowered the cost by at most ``chi2`` noise
        variances: the model then moves by far less than its standard errors
        (:class:`~freqid_casadi.solvers.termination.NoiseStall`). Its status is then
        "ok" instead of "not-converged"; its model is the same (the choice among its
        candidates reads the stationarity test only) unless a layer that runs for
        converged fits only, the delay hold or the resolution guard, changes it. Default
        ``(10, 0.01)``; ``None``: not-converged, as before (on the validation corpus, 5 of
        the 247 in-class fits, all at their noise).
    """

    hessian: str = "exact"
    warm_start: str = "primal-dual"
    max_iter: int = 100
    final_max_iter: int = 200
    ipopt: tuple = ()
    ftol: float = 1e-12
    noise_stall: tuple = (10, 0.01)

    method = "ipopt"

    def __post_init__(self):
        owner = type(self).__name__
        _choice(owner, "hessian", self.hessian, HESSIANS)
        _stage_limits(owner, self)
        _real(owner, "ftol", self.ftol, low=0.0, strict=False)
        if self.noise_stall is not None:
            stall = self.noise_stall
            if not (isinstance(stall, (tuple, list)) and len(stall) == 2):
                raise _bad(owner, "noise_stall", stall, "(window, chi2), e.g. (10, 0.01), "
                           "or None")
            _int_at_least(owner, "noise_stall[0] (window)", stall[0], 1)
            _real(owner, "noise_stall[1] (chi2)", stall[1], low=0.0)
            object.__setattr__(self, "noise_stall", (int(stall[0]), float(stall[1])))
        items = self.ipopt.items() if hasattr(self.ipopt, "items") else self.ipopt
        try:
            pairs = tuple(sorted((k, v) for k, v in items))
        except (TypeError, ValueError):
            raise _bad(owner, "ipopt", self.ipopt, "a dict of IPOPT option names to values, "
                       "e.g. {'tol': 1e-12}") from None
        for k, v in pairs:
            if not isinstance(k, str) or not isinstance(v, (str, numbers.Real)):
                raise _bad(owner, "ipopt", self.ipopt, "a dict of str names to str or number "
                           f"values (bad entry {k!r})")
        if pairs:
            _check_ipopt(owner, pairs)
        object.__setattr__(self, "ipopt", pairs)

    def ipopt_dict(self):
        """The extra IPOPT options as a new dict (None if there are none)."""
        return dict(self.ipopt) or None


@dataclass(frozen=True)
class BarrierLMOptions:
    """Options of the thesis's log-barrier + Levenberg-Marquardt stage solver (SPEC §3).

    Parameters
    ----------
    warm_start : {"primal-dual", "primal", "none"}
        As :attr:`IpoptOptions.warm_start` ("primal-dual" and "primal" are the same for
        this solver, which takes no multipliers).
    max_iter : int >= 1
        Kept for symmetry with :class:`IpoptOptions`; the barrier-LM stages are capped by
        ``max_inner`` and the ``t`` schedule instead.
    final_max_iter : int >= 1
        Iteration limit of each p-norm stage of the minimax polish (an IPOPT NLP).
    damping : {"thesis", "marquardt"}
        ``(A + sigma I)`` as the thesis, or ``(A + sigma diag(A))``; see
        :func:`~freqid_casadi.solvers.barrier_lm.barrier_lm`.
    t0 : float > 0
        First barrier parameter ``t = 1/mu``.
    t_factor : float > 1
        Growth of ``t`` per outer step.
    t_max : float >= t0
        Last barrier parameter.
    tau : float > 0
        Initial LM damping factor.
    eps1, eps2, eps3 : float >= 0
        Inner stops: gradient, step and cost tolerances.
    max_inner : int >= 1
        Trial steps per inner LM solve (the thesis's ``k_max``).
    """

    warm_start: str = "primal-dual"
    max_iter: int = 100
    final_max_iter: int = 200
    damping: str = "thesis"
    t0: float = 1.0
    t_factor: float = 20.0
    t_max: float = 1e12
    tau: float = 1.0
    eps1: float = 1e-10
    eps2: float = 1e-16
    eps3: float = 0.0
    max_inner: int = 500

    method = "barrier-lm"

    def __post_init__(self):
        owner = type(self).__name__
        _stage_limits(owner, self)
        _choice(owner, "damping", self.damping, DAMPING_MODES)
        _real(owner, "t0", self.t0, 0.0)
        _real(owner, "t_factor", self.t_factor, 1.0)
        _real(owner, "t_max", self.t_max, 0.0)
        if self.t_max < self.t0:
            raise _bad(owner, "t_max", self.t_max, f">= t0={self.t0!r} (at least one outer "
                       "step)")
        _real(owner, "tau", self.tau, 0.0)
        for name in ("eps1", "eps2", "eps3"):
            _real(owner, name, getattr(self, name), 0.0, strict=False)
        _int_at_least(owner, "max_inner", self.max_inner, 1)

    def lm_kwargs(self):
        """Keyword arguments of :func:`~freqid_casadi.solvers.barrier_lm.barrier_lm`."""
        keep = ("damping", "t0", "t_factor", "t_max", "tau", "eps1", "eps2", "eps3",
                "max_inner")
        return {k: getattr(self, k) for k in keep}


@dataclass(frozen=True)
class LoopOptions:
    """Options of the sequential main loop and of the stage parametrization.

    Parameters
    ----------
    gauge : {"dc", "b1", "raw"}
        Parametrization of the sections, see :mod:`freqid_casadi.core.objective`.
    init : {"peak", "identity", "relocate"}
        New-section initialisation: "peak" places a pole/zero pair at omega_c whose value
        there reproduces the error peak; "identity" is the thesis's a = b = 1,
        zeta = 0.5, omega = omega_c (optionally scaled by ``scale_l``); "relocate" is
        "peak" and, when its stage cost is lower, a vector fit of all sections at the
        current delay (:mod:`freqid_casadi.fitting.relocate`), with the section stages ended by a
        stall rule (the all-data stage runs without it).
    scale_l : float >= 1
        The thesis's l for the identity section (affects only the "raw" gauge).
    scaled : bool
        Scale the variables to about 1 (delay by ``delay_max``, gain by its initial
        value, section frequencies by their insertion frequency).
    bound_delay : bool
        If False, the delay has no upper bound (for the ablation).
    delay_max : float > 0 or None
        Upper bound of the delay in seconds; None:
        :func:`~freqid_casadi.fitting.fit.default_delay_max`
        of the data (the value used is ``FitResult.delay_max``).
    final_stage : bool
        End with a stage on all data (also run after a stage stopped at its iteration
        limit only when True).
    derivatives : {None, "affine", "casadi-map"}
        How the stage derivatives are evaluated (both exact, same results to rounding):
        None picks "affine" (numpy over points x sections; "dc" gauge only) or
        "casadi-map" (CasADi AD of the per-point formula mapped over the points).
    root_floor : float in [0, 1)
        Fraction of the lowest data frequency below which a polished overdamped factor's
        root may not go (:func:`~freqid_casadi.fitting.stages.choose_charts`): a pole the data
        push towards 0 (an integrator) stops there, on a bound, instead of creeping.
    hold_delay : bool
        When the fitted delay is undetermined (its standard deviation exceeds half its
        value: it trades against roots above the band), refit with the delay held at the
        value the (N-1)-section fit determines, and keep that fit when it converged within
        10 % of the free fit's max and RMS relative errors
        (:mod:`freqid_casadi.fitting.delay_hold`).
    delay_search : bool
        When a fit with a delay did not converge, also try the rational start at the
        delays around the fitted one, polished, as one more candidate
        (:mod:`freqid_casadi.fitting.delay_search`); the fit keeps it only when it is better.
    far_roots : bool
        When a fit with a delay did not converge, also try it with the roots far above
        the band moved to infinity and their phase into the delay, polished, as one more
        candidate (:mod:`freqid_casadi.fitting.far_roots`); kept only when it is better.
    resolution_guard : bool
        When ``min_damping`` is not given and the fit has poles or zeros narrower than the
        frequency spacing, refit with ``min_damping="auto"`` and keep that fit when it still
        explains the data to their noise (:mod:`freqid_casadi.fitting.guard`: on noisy data,
        no feature narrower than the data resolve unless the data determine it).
    """

    gauge: str = "dc"
    init: str = "relocate"
    scale_l: float = 1.0
    scaled: bool = True
    bound_delay: bool = True
    delay_max: float = None
    final_stage: bool = True
    derivatives: str = None
    root_floor: float = 1e-3
    hold_delay: bool = True
    delay_search: bool = True
    far_roots: bool = True
    resolution_guard: bool = True

    def __post_init__(self):
        owner = type(self).__name__
        _flags(self, "hold_delay", "delay_search", "far_roots", "scaled", "bound_delay",
               "final_stage", "resolution_guard")
        _choice(owner, "gauge", self.gauge, GAUGES)
        _choice(owner, "init", self.init, INITS)
        _real(owner, "scale_l", self.scale_l, 1.0, strict=False)
        if self.delay_max is not None:
            _real(owner, "delay_max (seconds)", self.delay_max, 0.0)
        _choice(owner, "derivatives", self.derivatives, DERIVATIVES)
        _real(owner, "root_floor", self.root_floor, 0.0, strict=False)
        if self.root_floor >= 1:
            raise _bad(owner, "root_floor", self.root_floor, "a fraction in [0, 1) of the "
                       "lowest data frequency, e.g. 1e-3")
        if self.derivatives == "affine" and self.gauge != "dc":
            raise OptionError(f"{owner}.derivatives='affine' needs gauge='dc' (got "
                              f"{self.gauge!r}); use derivatives='casadi-map' or None")


@dataclass(frozen=True)
class VectorFittingOptions:
    """Options of the vector-fitting start of
    :func:`~freqid_casadi.modal.shared.fit_shared` (``start="rational"``, and the rational
    half of ``start="best"``): ``fit_shared(..., vector_fitting=VectorFittingOptions(...))``.

    Parameters
    ----------
    n_iter : int >= 0
        Pole-relocation iterations of the shared-pole vector fitting (and of each
        channel's own poles with ``channel_sections``); 0 keeps the start poles (placed at
        the resonance peaks the channels share) and fits only the residues.
    """

    n_iter: int = 10

    def __post_init__(self):
        _int_at_least(type(self).__name__, "n_iter", self.n_iter, 0)
        object.__setattr__(self, "n_iter", int(self.n_iter))


@dataclass(frozen=True)
class FitOptions:
    """The options one :func:`~freqid_casadi.fitting.fit.fit` ran with (``FitResult.options``).

    Parameters
    ----------
    n_sections : int
    integrator : bool or int
        The poles at the origin fitted (False, True or an int k; with
        ``integrator="auto"`` the k it chose).
    delay : bool
    basis : str
    method : {"ipopt", "barrier-lm"}
        The name of the stage solver (the type of ``solver``).
    tol : float or None
    start : str
    objective : str
    min_damping : None, "auto" or float
        As given to fit (the floor used is ``FitResult.zeta_min``).
    solver : IpoptOptions or BarrierLMOptions
    loop : LoopOptions
    integrator_auto : bool
        Whether ``integrator`` was chosen by ``integrator="auto"``.
    """

    n_sections: int
    integrator: object
    delay: bool
    basis: str
    method: str
    tol: float
    start: str
    objective: str
    min_damping: object
    solver: object
    loop: LoopOptions
    integrator_auto: bool = False

    def as_dict(self):
        """Flat dict of every option (the solver's and loop's fields included), for
        reports; ``ipopt`` becomes a dict."""
        out = {f.name: getattr(self, f.name) for f in fields(self)
               if f.name not in ("solver", "loop")}
        for obj in (self.solver, self.loop):
            out.update({f.name: getattr(obj, f.name) for f in fields(obj)})
        if "ipopt" in out:
            out["ipopt"] = dict(out["ipopt"])
        return out


def solver_options(method):
    """The option object of ``method``: an :class:`IpoptOptions` or
    :class:`BarrierLMOptions` is returned as is, "ipopt" or "barrier-lm" gives that
    method's defaults.

    Parameters
    ----------
    method : {"ipopt", "barrier-lm"} or IpoptOptions or BarrierLMOptions

    Returns
    -------
    IpoptOptions or BarrierLMOptions

    Raises
    ------
    OptionError
        Anything else.
    """
    if isinstance(method, (IpoptOptions, BarrierLMOptions)):
        return method
    if isinstance(method, str) and method in METHODS:
        return IpoptOptions() if method == "ipopt" else BarrierLMOptions()
    raise OptionError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}, or "
                      "pass an IpoptOptions or BarrierLMOptions")


_LOOP_FIELDS = ("gauge", "init", "scale_l", "scaled", "bound_delay", "delay_max",
                "final_stage", "derivatives")
_SOLVER_FIELDS = ("hessian", "warm_start", "max_iter", "final_max_iter")

#: The keywords fit() no longer takes: old name -> (option class, field). ``lm_options``
#: maps to the fields of :class:`BarrierLMOptions` (field None).
LEGACY_KEYWORDS = {**{k: ("LoopOptions", k) for k in _LOOP_FIELDS},
                   **{k: ("IpoptOptions", k) for k in _SOLVER_FIELDS},
                   "ipopt_options": ("IpoptOptions", "ipopt"),
                   "lm_options": ("BarrierLMOptions", None)}


def legacy_message(function, name, value):
    """Text of the TypeError for an old keyword ``name=value`` of ``function``.

    Parameters
    ----------
    function : str
        Name of the function called (e.g. "fit").
    name : str
        The old keyword (a key of :data:`LEGACY_KEYWORDS`).
    value : object
        The value passed.

    Returns
    -------
    str
    """
    cls, field_name = LEGACY_KEYWORDS[name]
    if field_name is None:
        inner = ", ".join(f"{k}={v!r}" for k, v in dict(value or {}).items())
        how = f"method={cls}({inner})"
    elif cls == "LoopOptions":
        how = f"loop={cls}({field_name}={value!r})"
    else:
        how = (f"method={cls}({field_name}={value!r}) (or BarrierLMOptions({field_name}=...) "
               "for method='barrier-lm')" if field_name in ("warm_start", "max_iter",
                                                             "final_max_iter")
               else f"method={cls}({field_name}={value!r})")
    return f"{function}() no longer takes {name}=; pass {how}"


def options_from_keywords(method="ipopt", **keywords):
    """Translate the old flat keywords of fit() into ``(solver, loop)`` option objects.

    Parameters
    ----------
    method : {"ipopt", "barrier-lm"}
    **keywords
        Any of :data:`LEGACY_KEYWORDS` (``lm_options`` a dict of BarrierLMOptions fields,
        ``ipopt_options`` a dict of IPOPT options).

    Returns
    -------
    solver : IpoptOptions or BarrierLMOptions
    loop : LoopOptions

    Raises
    ------
    OptionError
        An unknown keyword, or a value the option objects reject.
    """
    unknown = sorted(set(keywords) - set(LEGACY_KEYWORDS))
    if unknown:
        raise OptionError(f"unknown option(s) {', '.join(map(repr, unknown))}; choose from "
                          f"{', '.join(LEGACY_KEYWORDS)}")
    loop = LoopOptions(**{k: v for k, v in keywords.items() if k in _LOOP_FIELDS})
    common = {k: v for k, v in keywords.items() if k in _SOLVER_FIELDS}
    if solver_options(method).method == "ipopt":
        extra = keywords.get("ipopt_options") or {}
        return IpoptOptions(**common, ipopt=extra), loop
    common.pop("hessian", None)
    return BarrierLMOptions(**common, **dict(keywords.get("lm_options") or {})), loop


def warn_renamed(function, old, new, stacklevel=3):
    """Issue the FutureWarning of a keyword that keeps working under its old spelling.

    Parameters
    ----------
    function : str
        Name of the function called (e.g. "fit_shared").
    old : str
        The old spelling as passed, e.g. ``"max_iter=200"``.
    new : str
        The spelling to use, e.g. ``"method=IpoptOptions(max_iter=200)"``.
    stacklevel : int
        As for :func:`warnings.warn`, counted from the caller of this function.
    """
    import warnings

    warnings.warn(f"{function}({old}) is deprecated; pass {new} (the same setting)",
                  FutureWarning, stacklevel=stacklevel + 1)


def ipopt_limits(function, method, default, used):
    """The IpoptOptions ``method`` of a function that takes only some of its fields.

    Parameters
    ----------
    function : str
        Name of the function, for the message.
    method : IpoptOptions, "ipopt" or None
        None or "ipopt": ``default``.
    default : IpoptOptions
    used : tuple of str
        The fields ``function`` reads; every other field must keep its default.

    Returns
    -------
    IpoptOptions

    Raises
    ------
    OptionError
        Not an IpoptOptions, or a field ``function`` does not read was changed.
    """
    if method is None or (isinstance(method, str) and method == "ipopt"):
        return default
    if not isinstance(method, IpoptOptions):
        fields_text = ", ".join(f"{k}={getattr(default, k)!r}" for k in used)
        raise OptionError(f"{function} solves with IPOPT: method must be an IpoptOptions (or "
                          f"None), got {method!r:.80}; pass method=IpoptOptions("
                          f"{fields_text})")
    plain = IpoptOptions()
    changed = [f.name for f in fields(IpoptOptions) if f.name not in used
               and getattr(method, f.name) != getattr(plain, f.name)]
    if changed:
        name = changed[0]
        raise OptionError(f"{function} uses only {', '.join(used)} of IpoptOptions, got "
                          f"{name}={getattr(method, name)!r}; leave IpoptOptions.{name} at "
                          "its default")
    return method
