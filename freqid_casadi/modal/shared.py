"""Many FRFs of one structure with one set of poles: :func:`fit_shared` (layer L4).

Channel ``c`` (one FRF, e.g. one sensor) is fitted by
``G_c(s) = exp(-h_c s) K_c [1/s] prod_k N_ck(s) / D_k(s)``: the denominator sections
``D_k`` (the structure's poles) are shared, the numerator sections, gains and delays are the
channel's own. The cost is the sum over channels of the relative least-squares error
``sum_i w_ci |Phi_ci / G_c(j w_i) - 1|^2``. Every stage is one IPOPT NLP with true bounds
(:mod:`freqid_casadi.modal._nlp`: exact block-arrowhead Hessian, cost per iteration linear
in the number of channels).

Channel sections (``channel_sections=k``, the counterpart of the "upper and lower
residuals" of experimental modal analysis, e.g. PolyMAX or sdypy-EMA): each channel's model
also has k sections of its own, ``N'_cj(s) / D'_cj(s)`` with its own poles and zeros (stable,
and minimum phase unless the channel's zeros are "free", by the same bounds), standing in
for what that channel sees of the modes outside the band. They are channel-block variables
(the Hessian stays block-arrowhead); the channels are coupled only through the shared poles,
and only those are modes (:attr:`SharedFitResult.modes`, ``poles``).

Two starts (:mod:`freqid_casadi.modal._stages`), both tried by the default
``start="best"`` (see :func:`fit_shared`):

``"rational"``
    vector fitting with one common pole set over all channels
    (:mod:`freqid_casadi.modal._start`; a channel delay of more than half a turn at the
    highest frequency, estimated from its group delay, is removed first), with channel
    sections one vector fitting per
    channel for its own poles (the shared ones fixed), right-half-plane zeros of
    minimum-phase channels reflected (their group delay moved to the delay), then one IPOPT
    polish on all data;
``"sequential"``
    the package's main loop: a pole pair added at the frequency of the largest relative
    error over all channels, the window grown to cover it, all parameters re-fitted,
    warm-started; then the channel sections, one per channel and stage, each at the
    frequency of that channel's largest error; a last stage on all data.
"""

import dataclasses
import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from .. import _interrupt
from ..core.data import FrequencyData, external_frequency_data
from ..core.gauges import dc_to_thesis
from ..errors import DataError, OptionError
from .._progress import channel, check_progress
from .._validate import check_choice, check_flag
from ..core.resolution import default_delay_max
from ..core.scaling import normalised_weights
from ..core.model import RationalDelayModel, Structure
from ..core.modes import Modes
from ..fitting.verdict import ROUNDING_RMS, FitStatus, NoiseCheck, residual_noise, status_of
from ..fitting.start import significant_group_delay
from ..options import IpoptOptions, VectorFittingOptions, ipopt_limits, warn_renamed
from ..solvers.common import TERMINATION_MESSAGES, Status
from ._nlp import SharedProblem
from ._zeros import offer_free_zeros, turns_phase
from ._stages import (SharedStage, lawson_rounds, logger, rational_start, sequential_start,
                      stage_line)

__all__ = ["fit_shared", "SharedFitResult", "SharedStage", "DELAYS", "ZEROS", "SHARED_STARTS",
           "DEFAULT_METHOD", "check_largest_order", "turns_phase"]

DELAYS = ("per-channel", "shared", False)
ZEROS = ("minimum-phase", "free")
SHARED_STARTS = ("best", "rational", "sequential")
#: Points summed over the channels above which ``start="best"`` keeps the rational start
#: without the sequential loop (which re-solves the whole problem once per section: about
#: 200 s against the rational start's 26 s on 9 channels x 47 873 points at 4 sections).
BEST_SEQUENTIAL_LIMIT = 100_000
#: Most reweighted fits of ``balance_channels``.
BALANCE_ROUNDS = 10
#: The IPOPT iteration limits of :func:`fit_shared` when ``method`` is not given: 200 per
#: stage, 400 in the final all-data stage (also the rational start's polish and each round
#: of ``balance_channels``), i.e. the old ``max_iter=200``.
DEFAULT_METHOD = IpoptOptions(max_iter=200, final_max_iter=400)
#: The fields of IpoptOptions that fit_shared uses (its stages have their own exact Hessian,
#: warm start and termination test).
_USED_FIELDS = ("max_iter", "final_max_iter")


@dataclass(frozen=True, eq=False)
class SharedFitResult:
    """Result of :func:`fit_shared`.

    Attributes
    ----------
    models : tuple of RationalDelayModel, length C
        One per channel, all with the same first N denominator sections (stable by
        construction), then the channel's own k channel sections (``N + k`` sections in
        all); channels fitted with ``zeros="free"`` have ``structure.zeros = "free"`` (and
        ``gain_sign = -1`` for a negative gain).
    datas : tuple of FrequencyData, length C
    poles : ndarray of complex, shape (2N,)
        The shared poles (the integrator's pole at 0 not included), by increasing |p|.
        rad/s.
    rel_errors : ndarray of float, shape (C, M)
        ``|Phi_c / G_c - 1|`` at every point.
    max_rel_errors, rms_rel_errors : ndarray of float, shape (C,)
    success : bool
        The last IPOPT stage converged: IPOPT met its tolerance or the stage ended at a
        relatively stationary point (the Gauss-Newton model promises a relative cost
        decrease of at most 1e-12, :mod:`freqid_casadi.solvers.shared_termination`); with
        ``balance_channels`` that stage solves the last reweighted problem, i.e. the one
        whose solution is returned.
    modes : freqid_casadi.core.modes.Modes
        The underdamped shared poles with every channel's residue, by frequency: a tuple
        of Mode that is also callable (``res.modes()`` is the same tuple, the spelling of
        ``FitResult.modes``).
    wall_time : float
        s.
    nit : int
        IPOPT iterations over all stages.
    stages : tuple of SharedStage
    zeros : tuple of str
        "minimum-phase" or "free" per channel.
    options : dict
    channel_poles : tuple of ndarray of complex, length C
        Each channel's own poles (2k each, rad/s, by increasing |p|) from its channel
        sections; empty arrays without channel sections. Not modes: they stand in for
        modes outside the band as that channel sees them.
    single_max_rel_errors : ndarray of float, shape (C,) or ()
        With ``balance_channels``: each channel's max relative error in its own
        single-channel fit (the targets); empty otherwise.
    message : str
        One sentence led by :attr:`status`: the worst channel's errors and what to do next
        (e.g. "not-converged: the final stage reached its iteration limit (400); ... —
        pass method=IpoptOptions(final_max_iter=4000) to let it run further"); with
        ``balance_channels``, whether every channel is within its own fit's max error;
        notes on under-resolved modes. The optimiser's words are in ``details``.
    status : FitStatus
        As ``FitResult.status``: "ok" when the last stage converged and every channel's
        residual is consistent with its noise
        (:func:`~freqid_casadi.fitting.verdict.residual_noise`), "poor-fit" when it
        converged but a channel's residual is well above its noise, "not-converged".
    details : dict
        ``final_stage``: the last stage's ``stage``, ``iterations``, ``max_iter`` (its
        limit), ``status`` (a :class:`~freqid_casadi.solvers.common.Status` name),
        ``solver_status`` (IPOPT's) and ``message`` (the termination test's text with its
        numbers); ``noise``: each channel's consistency check; ``start``: the start that
        won (with ``start="best"``) and ``start_max_rel_errors`` (largest channel max error
        of each start); with ``balance_channels``, ``balance`` (``exceed``: the channels
        above their own fit's max error, ``rounds``, ``targets``).
    """

    models: tuple
    datas: tuple
    poles: np.ndarray
    rel_errors: np.ndarray
    max_rel_errors: np.ndarray
    rms_rel_errors: np.ndarray
    success: bool
    modes: tuple
    wall_time: float
    nit: int
    stages: tuple = ()
    zeros: tuple = ()
    options: dict = field(default_factory=dict)
    channel_poles: tuple = ()
    single_max_rel_errors: np.ndarray = ()
    message: str = ""
    status: FitStatus = FitStatus.NOT_CONVERGED
    details: dict = field(default_factory=dict)

    @property
    def n_channels(self):
        return len(self.models)

    @property
    def n_shared(self):
        """Shared sections N (each model has ``N + channel_sections`` sections)."""
        return int(self.options.get("n_sections", self.models[0].n_sections))

    @property
    def channel_sections(self):
        """Sections of each channel's own k (0 without)."""
        return int(self.options.get("channel_sections", 0))

    @property
    def delays(self):
        """Per-channel delays (s), shape (C,)."""
        return np.array([m.delay for m in self.models])

    def summary(self):
        """One line: channels, sections, worst max/RMS relative error, time, convergence
        and :attr:`status`."""
        own = (f" + {self.channel_sections} per channel" if self.channel_sections else "")
        return (f"{self.n_channels} channels, {self.n_shared} shared sections{own}, "
                f"{len(self.modes)} modes, max rel. error {np.max(self.max_rel_errors):.4g} "
                f"(worst channel), RMS {np.max(self.rms_rel_errors):.4g}, "
                f"{self.wall_time:.2f} s, {self.nit} iterations, "
                f"{'converged' if self.success else 'NOT converged'}, status "
                f"{FitStatus(self.status).value}")

    def mode_shapes(self, coordinates=None, names=None, constants="lsfd"):
        """The modes' shapes: every channel's modal constant (residue) at every shared
        mode, phase-aligned and normalised (largest component magnitude 1), real where
        the data allow, with each mode's complexity (MPC, MPD).

        Parameters
        ----------
        coordinates : array_like of float, shape (C,) or (C, d), optional
            Where each channel was measured (e.g. the hammer positions of a roving-hammer
            test).
        names : sequence of str, optional
            Channel names (default the datas' names, else ``ch1``, ...).
        constants : {"lsfd", "model"}
            "lsfd" (default): each channel's residues at the shared poles re-estimated by
            linear least squares of ``d_c + sum_k r_ck / (s - p_k)`` on its data with the
            relative weights ``1/|Phi|`` (the LSFD step of modal analysis, the poles
            fixed): the residue of a lightly damped mode then rests on the points around
            its peak. "model": the residues of each channel's fitted model
            (:attr:`modes`), whose numerator also serves the relative error at the
            antiresonances (measured on a roving-hammer beam: the 974 Hz mode's MAC
            against the published shape 0.91 from the models, 0.99 by LSFD).

        Returns
        -------
        freqid_casadi.core.modes.ModeShapes
            ``numpy.asarray(result.mode_shapes())`` is the (modes, C) array of shapes;
            compare shape sets with :func:`freqid_casadi.mac`.
        """
        from ..core.modes import mode_shapes

        if constants not in ("lsfd", "model"):
            raise OptionError(f"constants must be 'lsfd' or 'model', got {constants!r}")
        if names is None:
            given = [d.name for d in self.datas]
            names = given if all(given) and len(set(given)) == len(given) else None
        mode_list = self.modes if constants == "model" else self._lsfd_modes()
        return mode_shapes(mode_list, coordinates, names)

    def _lsfd_modes(self):
        """:attr:`modes` with each channel's residue from :func:`lsfd_residues` at all
        shared poles (the channels' own poles too, as out-of-band terms)."""
        from ._start import lsfd_residues

        if not self.modes:
            return self.modes
        omega = self.datas[0].omega
        phi = np.array([d.response for d in self.datas])
        if self.options.get("integrator"):
            phi = phi * (1j * omega)
        phi = phi * np.exp(1j * omega[None, :] * self.delays[:, None])
        basis = list(self.poles)
        res = np.zeros((self.n_channels, len(self.modes)), complex)
        weights = None if self.datas[0].weights is None else \
            np.array([d.weights if d.weights is not None else np.ones(omega.size)
                      for d in self.datas])
        for c in range(self.n_channels):
            poles = np.array(basis + list(self.channel_poles[c]), complex)
            r, _ = lsfd_residues(omega, phi[c:c + 1], poles,
                                 None if weights is None else weights[c:c + 1])
            for k, m in enumerate(self.modes):
                res[c, k] = r[0, int(np.argmin(np.abs(poles - m.pole)))]
        pk = np.array([m.pole for m in self.modes])
        res = res * np.exp(-pk[None, :] * self.delays[:, None])     # the delay's factor
        if self.options.get("integrator"):
            res = res / pk[None, :]
        return Modes(dataclasses.replace(m, residues=tuple(res[:, k]))
                     for k, m in enumerate(self.modes))

    def to_control(self, pade_order=None, references=None):
        """python-control ``StateSpace``: every channel an output.

        Parameters
        ----------
        pade_order : int, optional
            Include each channel's delay as a Padé approximation of that order; otherwise
            the delays are left out and stated in the attribute ``output_delays`` (s, one
            per output).
        references : sequence of hashable, length C, optional
            The input (exciter) of each channel; channels with the same reference share an
            input. Default: one input for all channels.

        Returns
        -------
        control.StateSpace
            Block-diagonal realisation of the channels' section series (each channel keeps
            its own copy of the shared poles: not minimal, but exact), C outputs, one input
            per distinct reference (in order of first appearance, attribute
            ``input_references``); ``output_delays`` holds the delays still to apply.
        """
        import control as ct

        refs = [0] * self.n_channels if references is None else list(references)
        if len(refs) != self.n_channels:
            raise OptionError(f"references needs one entry per channel ({self.n_channels}), "
                              f"got {len(refs)}")
        inputs = list(dict.fromkeys(refs))
        parts = [m.to_control(pade_order) for m in self.models]
        n = sum(p.nstates for p in parts)
        A = np.zeros((n, n))
        B = np.zeros((n, len(inputs)))
        C = np.zeros((self.n_channels, n))
        D = np.zeros((self.n_channels, len(inputs)))
        k = 0
        for c, p in enumerate(parts):
            j = inputs.index(refs[c])
            ns = p.nstates
            A[k:k + ns, k:k + ns] = p.A
            B[k:k + ns, j] = np.ravel(p.B)
            C[c, k:k + ns] = np.ravel(p.C)
            D[c, j] = float(np.ravel(p.D)[0])
            k += ns
        sys = ct.ss(A, B, C, D)
        sys.output_delays = np.array([getattr(p, "delay", 0.0) for p in parts], float)
        sys.input_references = tuple(inputs)
        return sys


def _check_datas(datas, weights):
    if external_frequency_data(datas, "datas") is not None:        # one channel
        datas = [datas]
    datas = list(datas) if datas is not None else []
    datas = [external_frequency_data(d, f"datas[{c}]") or d for c, d in enumerate(datas)]
    if not datas or not all(isinstance(d, FrequencyData) for d in datas):
        raise DataError("datas must be a non-empty sequence of FrequencyData (one per "
                        "channel); read files with freqid_casadi.load")
    omega = datas[0].omega
    for c, d in enumerate(datas[1:], 1):
        if d.n_points != omega.size or not np.array_equal(d.omega, omega):
            raise DataError(
                f"channel {c} ({d.name or 'unnamed'}) is not on the omega grid of channel 0: "
                f"{d.n_points} points from {d.omega[0]:.6g} to {d.omega[-1]:.6g} rad/s vs "
                f"{omega.size} from {omega[0]:.6g} to {omega[-1]:.6g}; interpolate or "
                "measure all channels on one grid")
    wts = np.ones((len(datas), omega.size))
    for c, d in enumerate(datas):
        if d.weights is not None:
            wts[c] = d.weights
    if isinstance(weights, str):
        raise DataError(f"weights must be an array (channels, points) = {wts.shape} or "
                        f"broadcastable to it, got {weights!r} (weights='noise', estimated "
                        "from the data, is fc.fit's and freqid fit's)")
    if weights is not None:
        try:
            w = np.broadcast_to(np.asarray(weights, float), wts.shape)
        except (ValueError, TypeError):
            w = None
        if w is None or not np.all(np.isfinite(w)) or np.any(w < 0) or \
                np.any(np.sum(w, axis=1) <= 0):
            raise DataError(f"weights must be finite, >= 0 and broadcastable to (channels, "
                            f"points) = {wts.shape}, not all zero in a channel")
        wts = wts * w
    # the problem does not change with a common factor of the weights, the solvers'
    # absolute tolerances do: mean weight about 1 (uniform weights: all exactly 1)
    norm = normalised_weights(wts)
    wts = np.ones_like(wts) if norm is None else norm
    return datas, omega, np.array([d.response for d in datas]), wts


def _check_numbers(integrator, delay_max, balance):
    """The scalar options of :func:`fit_shared` (OptionError naming the bad one)."""
    if (isinstance(integrator, str) and integrator == "auto") or (
            isinstance(integrator, numbers.Integral)
            and not isinstance(integrator, (bool, np.bool_)) and integrator not in (0, 1)):
        raise OptionError(f"fit_shared takes integrator=True or False only, got "
                          f"{integrator!r}; for k poles (or zeros) at the origin fit each "
                          "channel with fc.fit(..., integrator=k), or divide the data by "
                          "(j omega)^k first")
    check_flag("integrator", integrator)
    check_flag("balance_channels", balance)
    if delay_max is not None and (isinstance(delay_max, (bool, np.bool_))
                                  or not isinstance(delay_max, numbers.Real)
                                  or not (0 < delay_max < np.inf)):
        raise OptionError(f"delay_max must be a finite delay > 0 in seconds or None, got "
                          f"{delay_max!r}; pass e.g. delay_max=0.01 (or None for the "
                          "data's default)")


def _check_count(name, value, low, fix):
    """OptionError unless ``value`` is an integer >= ``low`` (not a bool)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) \
            or value < low:
        raise OptionError(f"{name} must be an integer >= {low}, got {value!r}; {fix}")


def _solver_options(method, vector_fitting, max_iter, n_vf_iter):
    """``(IpoptOptions, VectorFittingOptions)`` of :func:`fit_shared` from ``method`` and
    ``vector_fitting``, or from the old keywords ``max_iter`` / ``n_vf_iter`` (each with a
    FutureWarning naming its new spelling; the same limits, so the same models)."""
    if max_iter is not None:
        if method is not None:
            raise OptionError("max_iter and method both give the iteration limits; drop "
                              "max_iter and pass method=IpoptOptions(max_iter=..., "
                              "final_max_iter=...) only")
        _check_count("max_iter", max_iter, 1, "pass method=IpoptOptions(max_iter=200, "
                     "final_max_iter=400) instead")
        warn_renamed("fit_shared", f"max_iter={max_iter!r}", "method=IpoptOptions("
                     f"max_iter={int(max_iter)}, final_max_iter={2 * int(max_iter)})", 3)
        method = IpoptOptions(max_iter=int(max_iter), final_max_iter=2 * int(max_iter))
    if n_vf_iter is not None:
        if vector_fitting is not None:
            raise OptionError("n_vf_iter and vector_fitting both give the vector-fitting "
                              "iterations; drop n_vf_iter and pass "
                              "vector_fitting=VectorFittingOptions(n_iter=...) only")
        _check_count("n_vf_iter", n_vf_iter, 0, "pass vector_fitting=VectorFittingOptions("
                     "n_iter=10) instead")
        warn_renamed("fit_shared", f"n_vf_iter={n_vf_iter!r}", "vector_fitting="
                     f"VectorFittingOptions(n_iter={int(n_vf_iter)})", 3)
        vector_fitting = VectorFittingOptions(n_iter=int(n_vf_iter))
    return _check_method(method), _check_vector_fitting(vector_fitting)


def _check_method(method):
    """The IpoptOptions of ``method`` (None or "ipopt": :data:`DEFAULT_METHOD`); the
    stages have their own exact Hessian, warm start and termination test, so only the
    iteration limits may differ from IpoptOptions' defaults."""
    return ipopt_limits("fit_shared", method, DEFAULT_METHOD, _USED_FIELDS)


def _check_vector_fitting(options):
    if options is None:
        return VectorFittingOptions()
    if not isinstance(options, VectorFittingOptions):
        raise OptionError(f"vector_fitting must be a VectorFittingOptions (or None), got "
                          f"{options!r:.80}; pass vector_fitting=VectorFittingOptions("
                          "n_iter=10)")
    return options


def check_largest_order(datas, n_sections, options):
    """DataError (or OptionError) before a series of fits when ``n_sections`` shared
    sections with the :func:`fit_shared` ``options`` have more parameters than the data
    have weighted points (see :func:`~freqid_casadi.modal.survey.stabilization`).

    Parameters
    ----------
    datas : sequence of FrequencyData, length C
        The channels, on one omega grid.
    n_sections : int
        The largest number of shared sections of the series.
    options : dict
        Keywords of :func:`fit_shared` (``weights``, ``channel_sections``, ``delay``).
    """
    wts = _check_datas(datas, options.get("weights"))[3]
    k = options.get("channel_sections", 0)
    if isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 0:
        _check_size(wts, int(n_sections), int(k), options.get("delay", "per-channel"))


def _check_size(wts, n, k, delay):
    """DataError when the channels' weighted points are fewer than the variables."""
    c = wts.shape[0]
    n_vars = 2 * n + (delay == "shared") + c * (1 + (delay == "per-channel") + 2 * n + 4 * k)
    counted = int(np.count_nonzero(wts > 0))
    if counted < n_vars:
        raise DataError(f"too few data points for {n} shared sections (and {k} per channel): "
                        f"{counted} weighted points over {c} channels for {n_vars} "
                        "parameters; use fewer sections or more data")


def _check_options(n_sections, delay, zeros, start, n_channels, channel_sections):
    _check_count("n_sections", n_sections, 1, "pass the number of shared sections, e.g. "
                 "n_sections=4 (one per mode in the band)")
    _check_count("channel_sections", channel_sections, 0, "pass the sections of each "
                 "channel's own beside the shared ones, e.g. channel_sections=1 (0: none)")
    if delay is not False and (not isinstance(delay, str) or delay not in DELAYS):
        # check_choice's message shape; False (the bool) is one of the choices
        raise OptionError(f"unknown delay {delay!r}; choose one of per-channel, shared, "
                          "False")
    try:
        zs = [zeros] * n_channels if isinstance(zeros, str) else list(zeros)
    except TypeError:
        zs = [zeros]
    for z in zs:
        check_choice("zeros", z, ZEROS)
    if len(zs) != n_channels:
        raise OptionError(f"zeros must be one of {', '.join(ZEROS)} or a list of them, one "
                          f"per channel: got {len(zs)} for {n_channels} channels; pass "
                          f"zeros='minimum-phase' (every channel) or a list of {n_channels}")
    check_choice("start", start, SHARED_STARTS)
    return int(n_sections), tuple(zs), int(channel_sections)


def fit_shared(datas, n_sections, *, integrator=False, delay="per-channel",
               zeros="minimum-phase", weights=None, start="best", progress=False,
               delay_max=None, method=None, vector_fitting=None, channel_sections=0,
               balance_channels=False, max_iter=None, n_vf_iter=None):
    """Fit several FRFs of one structure with one shared set of poles.

    Parameters
    ----------
    datas : sequence of FrequencyData, length C
        One FRF per channel, all on the same omega grid (rad/s), else DataError; a
        python-control ``FrequencyResponseData`` or a scikit-rf one-port ``Network`` is
        converted (:func:`~freqid_casadi.core.data.as_frequency_data`).
    n_sections : int
        Shared denominator sections N (2N poles); every channel also gets N numerator
        sections.
    integrator : bool
        A factor 1/s in every channel.
    delay : {"per-channel", "shared", False}
        One delay per channel, one for all, or none.
    zeros : {"minimum-phase", "free"} or sequence of them, one per channel
        "minimum-phase": gain and numerator coefficients >= 0 (zeros in the closed left
        half plane). "free": unbounded (a non-collocated sensor's right-half-plane zeros or
        negative gain); such a channel's model has ``structure.zeros = "free"`` (and
        ``gain_sign = -1`` for a negative gain). When a fit with minimum-phase channels
        is not "ok", it is run again with free zeros, and offered in the message (and
        ``details["free_zeros"]``) when it explains the data or halves the worst RMS
        error: a modal test's non-collocated sensors need right-half-plane zeros
        (:mod:`freqid_casadi.modal._zeros`).
    weights : array_like of float, shape (C, M), (M,) or scalar, optional
        Weights of the squared relative residuals, multiplying the datas' own weights.
    start : {"best", "rational", "sequential"}
        "best" (default) runs the rational start, then the sequential one, and keeps,
        among the results within 10 % of the lowest max relative error (largest over the
        channels), a converged one if any, then the lower RMS error (as
        :func:`freqid_casadi.fit`); ``details["start"]`` says which won. The sequential
        loop is not run when the rational start already explains every channel to its
        noise, or when the data hold more than :data:`BEST_SEQUENTIAL_LIMIT` points over
        all channels (its cost grows with the sections there: pass start="sequential");
        ``details["start_skipped"]`` then says why.
    progress : bool, "lines" or callable
        As for :func:`freqid_casadi.fit` (:mod:`freqid_casadi._progress`): True draws a bar
        on a terminal (one tick per stage) and elsewhere writes a line per 30 s of a long
        run; "lines" writes one line per stage to stderr; a callable receives every
        :class:`SharedStage` record.
    delay_max : float, optional
        Largest delay (s); default :func:`~freqid_casadi.fitting.fit.default_delay_max`.
    method : IpoptOptions, optional
        The IPOPT iteration limits: ``max_iter`` of each stage, ``final_max_iter`` of the
        final all-data stage (also of the rational start's polish and of each round of
        ``balance_channels``); default :data:`DEFAULT_METHOD`,
        ``IpoptOptions(max_iter=200, final_max_iter=400)`` ("ipopt" means the same). The
        other fields must keep their defaults (the stages have their own exact Hessian,
        warm start and termination test).
    vector_fitting : VectorFittingOptions, optional
        The vector-fitting start (``start="rational"`` and the rational half of "best");
        default ``VectorFittingOptions(n_iter=10)``.
    channel_sections : int
        k >= 0 sections of each channel's own (own poles and zeros, stable, minimum phase
        unless the channel's zeros are "free"), beside the N shared ones: they stand in
        for the modes outside the band as each channel sees them (the "upper and lower
        residuals" of modal analysis), so each channel's model has ``N + k`` sections.
        Their poles are not modes (:attr:`SharedFitResult.channel_poles`). Default 0.
    balance_channels : bool
        Make no channel's max relative error exceed that of its own single-channel fit
        (this function on that channel alone, same options: ``N + k`` sections, its zeros
        kind; C extra fits, :attr:`SharedFitResult.single_max_rel_errors`): after the fit,
        the points of the channels that lose are reweighted (Lawson's iteration towards
        their minimax fit, their weight raised) and the fit re-solved from its solution
        with the new weights, at most :data:`BALANCE_ROUNDS` times, each round ended by a
        looser test, then the last weighted problem once more to the stages' own test
        (each round's stage is appended to ``stages``; ``success`` is that last solve's);
        errors below 1e-8 count as exact (no loss). A channel is thus held to
        its own fit's max error at the price of its least-squares optimality (its RMS error
        grows); without channel sections the shared sections must also stand in for the
        out-of-band modes and the rounds may not reach every target (the result says).

    max_iter : int, optional
        Deprecated (FutureWarning): ``max_iter=k`` is
        ``method=IpoptOptions(max_iter=k, final_max_iter=2 * k)``, the same limits.
    n_vf_iter : int, optional
        Deprecated (FutureWarning): ``n_vf_iter=k`` is
        ``vector_fitting=VectorFittingOptions(n_iter=k)``.

    Returns
    -------
    SharedFitResult
        ``status`` ("ok", "poor-fit", "not-converged"), ``message`` (one sentence with
        the next step), the optimiser's numbers in ``details``.

    Raises
    ------
    DataError, OptionError
    """
    from .._threads import single_threaded_blas

    solver, vf = _solver_options(method, vector_fitting, max_iter, n_vf_iter)
    progress = check_progress(progress, "each SharedStage")
    with single_threaded_blas(), channel(progress, stage_line) as emit:
        def fit(zs, report=emit):
            return _fit_shared(datas, n_sections, integrator, delay, zs, weights, start,
                               report, delay_max, solver, vf, channel_sections,
                               balance_channels)
        return offer_free_zeros(fit(zeros), lambda zs: fit(zs, _ignore))


def _fit_shared(datas, n_sections, integrator, delay, zeros, weights, start, emit,
                delay_max, solver, vf, channel_sections, balance):
    t0 = time.perf_counter()
    datas, omega, phi, wts = _check_datas(datas, weights)
    n, zs, k = _check_options(n_sections, delay, zeros, start, len(datas), channel_sections)
    _check_numbers(integrator, delay_max, balance)
    _check_size(wts, n, k, delay)
    free = np.array([z == "free" for z in zs])
    dmax = float(delay_max) if delay_max is not None else default_delay_max(omega)
    g = np.abs(phi[:, 0]) * (omega[0] if integrator else 1.0)

    log = logger(emit)
    base = phi * (1j * omega) if integrator else phi          # VF fits the rational part

    def run(w, which):
        def make(wr, wl):
            with _interrupt.guard():    # CasADi expressions: see stages.StageSolver
                return SharedProblem(omega, phi, w, g, wr, integrator, delay, free, dmax, wl)
        if which == "rational":
            return rational_start(make, n, k, omega, base, w, free, log,
                                  solver.final_max_iter, vf.n_iter,
                                  _group_delays(omega, base, delay, dmax))
        return sequential_start(make, n, k, omega, w, log, solver.max_iter,
                                solver.final_max_iter)

    prob, z, lam, stages, won, start_errors, skipped = _run_starts(run, wts, start, datas,
                                                                   zs)
    options = {"n_sections": n, "channel_sections": k, "integrator": bool(integrator),
               "delay": delay, "zeros": list(zs), "start": start, "delay_max": dmax,
               "balance_channels": bool(balance), "max_iter": solver.max_iter,
               "final_max_iter": solver.final_max_iter, "n_vf_iter": vf.n_iter}
    singles = ()
    if balance:
        singles = np.array([_fit_shared([d], n, integrator, delay, [z], wts[c], start,
                                        _ignore, dmax, solver, vf, k, False)
                            .max_rel_errors[0] for c, (d, z) in enumerate(zip(datas, zs))])
        prob, z, more = lawson_rounds(prob, z, lam, singles, log, solver.final_max_iter,
                                      BALANCE_ROUNDS)
        stages += more
    res = _result(prob, z, datas, stages, zs, time.perf_counter() - t0, options)
    res = dataclasses.replace(res, details=dict(res.details, start=won,
                                                start_max_rel_errors=start_errors,
                                                **({"start_skipped": skipped} if skipped
                                                   else {})))
    if balance:
        res = _balance_note(res, singles, k, max(len(more) - 1, 0))
    return _resolution(res, omega, phi)


def _group_delays(omega, phi, delay, delay_max):
    """Per channel, the delay (s) the rational start removes before its vector fitting:
    the channel's group delay when its phase at the highest frequency exceeds half a turn
    (:func:`~freqid_casadi.fitting.start.significant_group_delay`), else 0; with
    ``delay="shared"`` their median for every channel; none without a delay."""
    if delay is False:
        return np.zeros(phi.shape[0])
    h = np.array([significant_group_delay(FrequencyData(omega, row)) for row in phi])
    h = np.clip(h, 0.0, delay_max)
    return np.full_like(h, np.median(h)) if delay == "shared" else h


def _ignore(record):
    return None


def _balance_note(res, singles, k, rounds):
    """``res`` with ``balance_channels``' outcome in its message and details."""
    miss = np.flatnonzero(res.max_rel_errors > np.maximum(singles, 1e-8))
    if miss.size:
        note = (f"; channels {', '.join(map(str, miss.tolist()))} still exceed their own "
                f"fit's max rel. error after {rounds} reweighted rounds — pass "
                f"channel_sections={k + 1} so that each channel has sections of its own for "
                "the modes outside the band")
    else:
        note = "; every channel is within its own fit's max rel. error"
    details = dict(res.details, balance={"exceed": miss.tolist(), "rounds": int(rounds),
                                         "targets": singles.tolist()})
    return dataclasses.replace(res, single_max_rel_errors=singles,
                               message=res.message + note, details=details)


def _resolution(res, omega, phi):
    """``res`` with a note in its message (and a DataWarning) when resonances of the data
    or modes of the fit are narrower than the frequency spacing."""
    import warnings

    from ..core.modes import resolution_notes
    from ..io.loaders import DataWarning

    notes = resolution_notes(omega, phi, res.modes)
    if not notes:
        return res
    text = "; ".join(notes)
    warnings.warn(f"fit_shared: {text}", DataWarning, stacklevel=4)
    return dataclasses.replace(res, message=f"{res.message}; under-resolved: {text}")


def _run_starts(run, wts, start, datas, zs):
    """Run the start(s) ``start`` asks for on weights ``wts`` and keep one (see
    :func:`fit_shared`); returns ``(prob, z, lam, stages, won, start_max_rel_errors,
    skipped)``, ``skipped`` the reason the sequential loop of "best" did not run, or None."""
    names = ("rational", "sequential") if start == "best" else (start,)
    runs, skipped = {}, None
    for name in names:
        if name == "sequential" and start == "best":
            skipped = _sequential_not_needed(runs["rational"], datas)
            if skipped:
                break
        prob, z, lam, stages = run(wts, name)
        ratio = prob.ratio(z) - 1.0
        rel = np.abs(ratio)
        runs[name] = ((prob, z, lam, stages), float(np.max(rel)),
                      float(np.sqrt(np.mean(rel ** 2))), bool(stages[-1].success), ratio)
    runs = {k: runs[k] for k in ("sequential", "rational") if k in runs}   # tie order
    lowest = min(r[1] for r in runs.values())
    near = [k for k, r in runs.items() if r[1] <= 1.1 * lowest] or list(runs)
    pick = sorted(near, key=lambda k: (not runs[k][3], runs[k][2]))[0]
    return (*runs[pick][0], pick, {k: r[1] for k, r in runs.items()}, skipped)


def _sequential_not_needed(rational_run, datas):
    """Why ``start="best"`` keeps the rational start without running the sequential loop,
    or None (``rational_run``: that start's entry in :func:`_run_starts`, its residual
    ratio last): the rational start converged and explains every channel to its noise (no
    model can do meaningfully better), or the data hold more than
    :data:`BEST_SEQUENTIAL_LIMIT` points over all channels (the loop re-solves the whole
    problem once per section and costs several times the rational start there)."""
    stages, ratio = rational_run[0][3], rational_run[4]
    size = sum(d.omega.size for d in datas)
    if size > BEST_SEQUENTIAL_LIMIT:
        return (f"{size} points over the channels (more than {BEST_SEQUENTIAL_LIMIT}): the "
                "sequential loop was not run; pass start='sequential' to run it")
    if not stages[-1].success:
        return None
    if all(residual_noise(ratio[c], d.omega, d.weights).consistent
           for c, d in enumerate(datas)):
        return ("the rational start explains every channel to its noise: the sequential "
                "loop was not run")
    return None


def _models(prob, z):
    """One RationalDelayModel per channel from the variables ``z``: the shared sections,
    then the channel's own."""
    q, v, h, p = prob.split(z)
    lp, lq = prob.split_local(z)
    models = []
    for c in range(prob.n_channels):
        vc = v[c] if abs(v[c]) > 1e-300 else 1e-300
        gain = prob.g[c] / vc
        secs = []
        pairs = [(p[c, k], q[k], wr) for k, wr in enumerate(prob.wr)]
        pairs += [(lp[c, k], lq[c, k], wl) for k, wl in enumerate(prob.wl[c])]
        for num, den, wr in pairs:
            a, zn, wn, sn = dc_to_thesis(num[0], num[1], wr)
            b, zd, wd, sd = dc_to_thesis(den[0], den[1], wr)
            gain *= sd / sn
            secs += [a, zn, wn, b, zd, wd]
        st = Structure(len(pairs), prob.integrator, prob.delay is not False,
                       "second-order", "free" if prob.free[c] else "minimum-phase",
                       1 if gain >= 0 else -1)
        models.append(RationalDelayModel(st, np.array([h[c], abs(gain)] + secs, float)))
    return tuple(models)


def _section_poles(model, sections):
    """Poles (rad/s) of the denominators of ``model``'s sections ``sections`` (a slice), by
    increasing |p|."""
    secs = model.sections()[sections]
    sub = RationalDelayModel(Structure(len(secs), False, False, "second-order", "free"),
                             np.concatenate([[0.0, 1.0], secs.ravel()]))
    poles = sub.poles()
    return poles[np.argsort(np.abs(poles), kind="stable")]


def _result(prob, z, datas, stages, zeros, wall, options):
    from ..core.modes import modes_of_models

    models = _models(prob, z)
    ratio = prob.ratio(z) - 1.0
    rel = np.abs(ratio)
    n = prob.n_sections
    checks = [residual_noise(ratio[c], d.omega, d.weights) for c, d in enumerate(datas)]
    rms = np.sqrt(np.mean(rel ** 2, axis=1))
    last = stages[-1]
    status = status_of(bool(last.success), bool(np.any(rms >= 1.0)),
                       NoiseCheck(consistent=all(c.consistent for c in checks)))
    limit = options["final_max_iter"]
    final = {"stage": int(last.stage), "iterations": int(last.nit), "max_iter": int(limit),
             "status": last.status.name, "solver_status": last.solver_status,
             "message": last.message}
    text = _message(status, last, limit, np.max(rel, axis=1), rms, checks, options,
                    datas[0].unit)
    return SharedFitResult(
        models=models, datas=tuple(datas), poles=_section_poles(models[0], slice(0, n)),
        rel_errors=rel,
        max_rel_errors=np.max(rel, axis=1), rms_rel_errors=rms,
        success=bool(last.success), modes=modes_of_models(models, n),
        message=text, status=status,
        details={"final_stage": final, "noise": [dict(c) for c in checks]},
        wall_time=wall, nit=int(sum(s.nit for s in stages
                                   if s.solver_status != "vector-fitting")),
        stages=tuple(stages), zeros=tuple(zeros), options=options,
        channel_poles=tuple(_section_poles(m, slice(n, None)) for m in models))


def _message(status, last, limit, max_errs, rms, checks, options, unit):
    """:attr:`SharedFitResult.message`: one sentence led by the status, with the errors
    and the next step (the optimiser's own words are in ``details["final_stage"]``)."""
    errors = (f"worst channel max rel. error {np.max(max_errs):.3g}, RMS "
              f"{np.max(rms):.3g}")
    n, k = options["n_sections"], options["channel_sections"]
    if status == FitStatus.OK:
        exact = all(c["rms"] <= ROUNDING_RMS for c in checks)
        return (f"ok: converged; {errors}, consistent with the noise in every channel"
                + (" (the fit is exact to rounding)" if exact else ""))
    if status == FitStatus.POOR_FIT:
        if np.any(rms >= 1.0):
            bad = np.flatnonzero(rms >= 1.0).tolist()
            return (f"poor-fit: channels {', '.join(map(str, bad))} have an RMS relative "
                    "error >= 1, no better than an infinite-gain model; check their gain "
                    "sign and pass zeros='free' for them, or use fewer sections")
        ratios = [c["ratio"] if not c.consistent else -math.inf for c in checks]
        c = int(np.argmax(ratios))
        bad = [i for i, chk in enumerate(checks) if not chk.consistent]
        w = checks[c]["worst_omega"]
        return (f"poor-fit: converged, but the residual of channel"
                f"{'s' if len(bad) > 1 else ''} {', '.join(map(str, bad))} is well above "
                f"the noise (channel {c}: {checks[c]['ratio']:.3g} times, largest near "
                f"omega = {w:.4g} {unit}); {errors} — pass n_sections={n + 1} or more for a "
                f"mode the shared poles miss, or channel_sections={k + 1} for modes outside "
                "the band")
    if last.status == Status.MAX_ITER:
        how = f"reached its iteration limit ({int(limit)})"
        step = (f"pass method=IpoptOptions(final_max_iter={10 * int(limit)}) to let it run "
                "further")
    else:
        how = ("stalled (the error stopped falling) at a point that is not stationary"
               if last.status == Status.STALLED
               else f"stopped ({TERMINATION_MESSAGES[last.status]})")
        step = ("try start='best' (both starts, the better kept)" if options["start"] != "best"
                else "try another number of shared sections")
    state = ("usable: every channel's residual is consistent with its noise"
             if all(c.consistent for c in checks)
             else "the models are feasible and these errors are measured")
    return f"not-converged: the final stage {how}; {errors} ({state}) — {step}"
