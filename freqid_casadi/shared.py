"""Many FRFs of one structure with one set of poles: :func:`fit_shared` (layer L4).

Channel ``c`` (one FRF, e.g. one sensor) is fitted by
``G_c(s) = exp(-h_c s) K_c [1/s] prod_k N_ck(s) / D_k(s)``: the denominator sections
``D_k`` (the structure's poles) are shared, the numerator sections, gains and delays are the
channel's own. The cost is the sum over channels of the relative least-squares error
``sum_i w_ci |Phi_ci / G_c(j w_i) - 1|^2``. Every stage is one IPOPT NLP with true bounds
(:mod:`freqid_casadi._shared_nlp`: exact block-arrowhead Hessian, cost per iteration linear
in the number of channels). Two starts:

``"rational"`` (default)
    vector fitting with one common pole set over all channels
    (:mod:`freqid_casadi._shared_start`), right-half-plane zeros of minimum-phase channels
    reflected (their group delay moved to the delay), then one IPOPT polish on all data;
``"sequential"``
    the package's main loop: a pole pair added at the frequency of the largest relative
    error over all channels, the window grown to cover it, all parameters re-fitted,
    warm-started; a last stage on all data.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from .data import FrequencyData
from .gauges import dc_to_thesis
from .errors import DataError, OptionError
from .resolution import default_delay_max
from .model import RationalDelayModel, Structure
from ._shared_nlp import SharedProblem, solve_stage
from .solvers.common import Status
from .solvers.ipopt import ipopt_status
from ._shared_start import channel_zeros, factor_variables, shared_vector_fitting

__all__ = ["fit_shared", "SharedFitResult", "SharedStage", "DELAYS", "ZEROS", "SHARED_STARTS"]

DELAYS = ("per-channel", "shared", False)
ZEROS = ("minimum-phase", "free")
SHARED_STARTS = ("rational", "sequential")


@dataclass(frozen=True)
class SharedStage:
    """One IPOPT stage of :func:`fit_shared`.

    Attributes
    ----------
    stage : int
        0 gain/delay stage (or the rational start's vector fitting), n the stage that added
        section n, ``n_sections + 1`` the final all-data stage (the polish of the rational
        start).
    n_sections, window : int
        Sections and number of frequencies (lowest first) fitted.
    omega_c : float
        rad/s where the section was placed (nan otherwise).
    max_rel_error : float
        Over all channels and points after the stage.
    nit : int
        IPOPT iterations (for the rational start's stage 0, status "vector-fitting": the
        vector-fitting iterations).
    t_solve, wall_time : float
        s: the IPOPT solve alone, and the stage with its NLP construction.
    cpu_solve : float
        s: CPU time of this process during the IPOPT solve(s) (single-threaded BLAS, so
        close to the solve's own cost even when other jobs load the machine).
    status : freqid_casadi.solvers.common.Status
        Why the stage stopped (COST_TOL: the start was exact to rounding, no solve).
    solver_status : str
        IPOPT's return_status ("vector-fitting" for the rational start's stage 0,
        "start-exact" when no solve was needed).
    success : bool
    """

    stage: int
    n_sections: int
    window: int
    omega_c: float
    max_rel_error: float
    nit: int
    t_solve: float
    wall_time: float
    status: Status
    solver_status: str
    success: bool
    cpu_solve: float = 0.0


@dataclass(frozen=True, eq=False)
class SharedFitResult:
    """Result of :func:`fit_shared`.

    Attributes
    ----------
    models : tuple of RationalDelayModel, length C
        One per channel, all with the same denominator sections (stable by construction);
        channels fitted with ``zeros="free"`` have ``structure.zeros = "free"`` (and ``gain_sign = -1`` for a negative gain).
    datas : tuple of FrequencyData, length C
    poles : ndarray of complex, shape (2N,)
        The shared poles (the integrator's pole at 0 not included), by increasing |p|.
    rel_errors : ndarray of float, shape (C, M)
        ``|Phi_c / G_c - 1|`` at every point.
    max_rel_errors, rms_rel_errors : ndarray of float, shape (C,)
    success : bool
        The last IPOPT stage converged.
    modes : tuple of freqid_casadi.modal.Mode
        The underdamped shared poles with every channel's residue, by frequency.
    wall_time : float
        s.
    nit : int
        IPOPT iterations over all stages.
    stages : tuple of SharedStage
    zeros : tuple of str
        "minimum-phase" or "free" per channel.
    options : dict
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

    @property
    def n_channels(self):
        return len(self.models)

    @property
    def delays(self):
        """Per-channel delays (s), shape (C,)."""
        return np.array([m.delay for m in self.models])

    def summary(self):
        """One line: channels, sections, worst max/RMS relative error, time, status."""
        return (f"{self.n_channels} channels, {self.models[0].n_sections} shared sections, "
                f"{len(self.modes)} modes, max rel. error {np.max(self.max_rel_errors):.4g} "
                f"(worst channel), RMS {np.max(self.rms_rel_errors):.4g}, "
                f"{self.wall_time:.2f} s, {self.nit} iterations, "
                f"{'converged' if self.success else 'NOT converged'}")

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
    if isinstance(datas, FrequencyData):
        datas = [datas]
    datas = list(datas) if datas is not None else []
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
    return datas, omega, np.array([d.response for d in datas]), wts


def _check_options(n_sections, delay, zeros, start, n_channels):
    if isinstance(n_sections, bool) or not isinstance(n_sections, (int, np.integer)) \
            or n_sections < 1:
        raise OptionError(f"n_sections must be an integer >= 1, got {n_sections!r}")
    if delay not in DELAYS or delay is True:
        raise OptionError(f"delay must be one of {DELAYS}, got {delay!r}")
    zs = [zeros] * n_channels if isinstance(zeros, str) else list(zeros)
    if len(zs) != n_channels or any(z not in ZEROS for z in zs):
        raise OptionError(f"zeros must be one of {ZEROS} or a list of them, one per channel "
                          f"({n_channels}), got {zeros!r}")
    if start not in SHARED_STARTS:
        raise OptionError(f"start must be one of {SHARED_STARTS}, got {start!r}")
    return int(n_sections), tuple(zs)


def fit_shared(datas, n_sections, *, integrator=False, delay="per-channel",
               zeros="minimum-phase", weights=None, start="rational", progress=False,
               delay_max=None, max_iter=200, n_vf_iter=10):
    """Fit several FRFs of one structure with one shared set of poles.

    Parameters
    ----------
    datas : sequence of FrequencyData, length C
        One FRF per channel, all on the same omega grid (rad/s), else DataError.
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
        negative gain); such a channel's model has ``structure.zeros = "free"`` (and ``gain_sign = -1`` for a negative gain).
    weights : array_like of float, shape (C, M), (M,) or scalar, optional
        Weights of the squared relative residuals, multiplying the datas' own weights.
    start : {"rational", "sequential"}
    progress : bool
        Print one line per stage to stderr.
    delay_max : float, optional
        Largest delay (s); default :func:`~freqid_casadi.fit.default_delay_max`.
    max_iter : int
        IPOPT iterations per stage (twice that in the final stage).
    n_vf_iter : int
        Vector-fitting iterations of the rational start.

    Returns
    -------
    SharedFitResult

    Raises
    ------
    DataError, OptionError
    """
    from .fit import _single_threaded_blas

    with _single_threaded_blas():
        return _fit_shared(datas, n_sections, integrator, delay, zeros, weights, start,
                           progress, delay_max, max_iter, n_vf_iter)


def _fit_shared(datas, n_sections, integrator, delay, zeros, weights, start, progress,
                delay_max, max_iter, n_vf_iter):
    t0 = time.perf_counter()
    datas, omega, phi, wts = _check_datas(datas, weights)
    n, zs = _check_options(n_sections, delay, zeros, start, len(datas))
    free = np.array([z == "free" for z in zs])
    dmax = float(delay_max) if delay_max is not None else default_delay_max(omega)
    g = np.abs(phi[:, 0]) * (omega[0] if integrator else 1.0)
    make = (lambda wr: SharedProblem(omega, phi, wts, g, wr, integrator, delay, free, dmax))
    log = _logger(progress)
    if start == "rational":
        base = phi * (1j * omega) if integrator else phi      # VF fits the rational part
        prob, z, stages = _rational(make, n, omega, base, wts, free, log, max_iter, n_vf_iter)
    else:
        prob, z, stages = _sequential(make, n, omega, wts, log, max_iter)
    return _result(prob, z, datas, stages, zs, time.perf_counter() - t0,
                   {"n_sections": n, "integrator": bool(integrator), "delay": delay,
                    "zeros": list(zs), "start": start, "delay_max": dmax})


def _logger(progress):
    import sys

    def log(rec):
        if progress:
            print(f"  stage {rec.stage:2d}: {rec.n_sections} sections, window {rec.window}, "
                  f"max rel. error {rec.max_rel_error:.3e}, {rec.nit} it, "
                  f"{rec.wall_time:.2f} s, {rec.solver_status}", file=sys.stderr)
        return rec
    return log


def _stage(prob, x0, window, stage, omega_c, log, lam=None, max_iter=200):
    """Solve one stage, keep the better of solution and start; return (z, lam, record)."""
    t0 = time.perf_counter()
    x0c = np.clip(x0, *prob.bounds())
    if np.max(np.abs(prob.ratio(x0c, window) - 1.0)) < 1e-10:
        # exact to rounding already: IPOPT cannot meet its tolerance on rounding noise
        res = {"x": x0c, "lam_x": np.zeros_like(x0c), "cost": prob.cost(x0c, window),
               "nit": 0, "t_solve": 0.0, "c_solve": 0.0, "status": "start-exact",
               "success": True}
    else:
        res = solve_stage(prob, x0, window, lam_x0=lam, max_iter=max_iter)
        res = _resolve(prob, res, prob.cost(x0c, window), window, max_iter)
    z, lam_x = res["x"], res["lam_x"]
    if not res["cost"] <= prob.cost(x0c, window):
        z, lam_x = x0c, np.zeros_like(x0c)
    err = float(np.max(np.abs(prob.ratio(z) - 1.0)))
    first = res["status"].split(";")[0]
    status = Status.COST_TOL if first == "start-exact" else ipopt_status(first)
    rec = SharedStage(stage, prob.n_sections, window or prob.omega.size, omega_c, err,
                      res["nit"], res["t_solve"], time.perf_counter() - t0, status,
                      res["status"], res["success"], res["c_solve"])
    return z, lam_x, log(rec)


def _resolve(prob, res, cost0, window, max_iter):
    """One more solve (at most ``max_iter // 4`` iterations) from a converged point whose
    cost fell below 1e-6 of the start's: IPOPT's objective is scaled by 1/cost(start), so
    its tolerance was relative to a cost far above the one reached. The stage's success and
    status stay the first solve's (it met its tolerance); the status notes the polish."""
    if not (res["success"] and res["cost"] < 1e-6 * cost0
            and np.max(np.abs(prob.ratio(res["x"], window) - 1.0)) > 1e-10):
        return res
    new = solve_stage(prob, res["x"], window, lam_x0=res["lam_x"],
                      max_iter=max(10, max_iter // 4))
    out = dict(res, nit=res["nit"] + new["nit"], t_solve=res["t_solve"] + new["t_solve"],
               c_solve=res["c_solve"] + new["c_solve"],
               status=f"{res['status']}; rescaled polish: {new['status']}")
    if new["cost"] < res["cost"]:
        out.update(x=new["x"], lam_x=new["lam_x"], cost=new["cost"])
    return out


def _sequential(make, n_total, omega, wts, log, max_iter):
    """The main loop over shared sections. Returns (problem, z, stages)."""
    m = omega.size
    prob = make([])
    c = prob.n_channels
    z = prob.join(np.zeros((0, 2)), np.ones(c), np.zeros(c), np.zeros((c, 0, 2)))
    window = min(5, m)
    z, lam, rec = _stage(prob, z, window, 0, np.nan, log, max_iter=max_iter)
    stages = [rec]
    for k in range(1, n_total + 1):
        err = np.max(np.sqrt(wts) * np.abs(prob.ratio(z) - 1.0), axis=0)
        idx = int(np.argmax(err))
        wc = float(omega[idx])
        window = min(m, max(window, idx + 1, 2 * k + 3))
        q, v, h, p = prob.split(z)
        rho = np.abs(prob.ratio(z, idx + 1)[:, idx])
        zeta0 = _peak_damping(err, idx, omega)
        zd = zeta0 if rho.max() >= 1 else min(zeta0 / max(rho.max(), 1e-12), 2.0)
        zn = np.clip(zd * rho, 1e-4, 2.0)
        prob = make(list(prob.wr) + [wc])
        q = np.vstack([q, [[1.0, 2 * zd]]])
        p = np.concatenate([p, np.stack([np.ones(c), 2 * zn], axis=1)[:, None, :]], axis=1)
        x0 = prob.join(q, v, h, p)
        lam0 = _extend_lam(prob, lam)
        z, lam, rec = _stage(prob, x0, window, k, wc, log, lam0, max_iter)
        stages.append(rec)
    z, lam, rec = _stage(prob, z, None, n_total + 1, np.nan, log, lam, 2 * max_iter)
    return prob, z, stages + [rec]


def _extend_lam(prob, lam):
    """Bound multipliers of the previous stage placed into the new layout (new entries 0)."""
    old_n = prob.n_sections - 1
    c, ns, no = prob.n_channels, prob.n_shared, prob.n_own
    out = np.zeros(prob.n_vars)
    ns_old, no_old = ns - 2, no - 2
    out[:2 * old_n] = lam[:2 * old_n]
    out[2 * old_n + 2:ns] = lam[2 * old_n:ns_old]
    own_old = lam[ns_old:].reshape(c, no_old)
    own = out[ns:].reshape(c, no)
    own[:, :no_old] = own_old
    return out


def _peak_damping(err, idx, omega):
    """Damping from the half-width of the error peak at ``idx`` (as fit's "peak" init)."""
    half = err[idx] / 2.0
    lo, hi = idx, idx
    while lo > 0 and err[lo - 1] > half:
        lo -= 1
    while hi < omega.size - 1 and err[hi + 1] > half:
        hi += 1
    width = (omega[min(hi + 1, omega.size - 1)] - omega[max(lo - 1, 0)]) / (2 * omega[idx])
    return float(np.clip(width / 2, 1e-3, 0.5))


def _rational(make, n, omega, phi, wts, free, log, max_iter, n_iter):
    """Shared-pole vector fitting, zeros per channel, then one IPOPT polish on all data."""
    t0 = time.perf_counter()
    poles, residues = shared_vector_fitting(omega, phi, 2 * n, wts, n_iter)
    floor = 1e-6 * omega[0]
    q, wr = factor_variables(poles, None, floor)
    prob = make(wr)
    c = prob.n_channels
    p = np.zeros((c, n, 2))
    h = np.zeros(c)
    for k in range(c):
        zk = channel_zeros(poles, residues[k])
        rhp = zk[zk.real > 0]
        if not free[k]:
            # an RHP zero z is the all-pass (s - z)/(s + z*) times its reflection; its
            # low-frequency group delay 2 Re z / |z|^2 goes to the delay
            h[k] = np.sum(2 * rhp.real / np.abs(rhp) ** 2) if rhp.size else 0.0
            zk = np.where(zk.real > 0, -np.conj(zk), zk)
        p[k] = factor_variables(zk, wr, floor)[0]
    h = np.clip(h, 0.0, prob.delay_max) if prob.delay else np.zeros(c)
    P = prob.ratio(prob.join(q, np.ones(c), h, p))
    v = np.sum(wts * P.real, axis=1) / np.sum(wts * np.abs(P) ** 2, axis=1)
    bad = ~free & (v <= 0)
    v[bad] = 1.0 / np.median(np.abs(P[bad]), axis=1) if bad.any() else v[bad]
    z0 = prob.join(q, v, h, p)
    err = float(np.max(np.abs(prob.ratio(z0) - 1.0)))
    stages = [log(SharedStage(0, n, omega.size, np.nan, err, n_iter, 0.0,
                              time.perf_counter() - t0, Status.CONVERGED, "vector-fitting",
                              True))]
    z, _, rec = _stage(prob, z0, None, n + 1, np.nan, log, None, 2 * max_iter)
    return prob, z, stages + [rec]


def _models(prob, z):
    """One RationalDelayModel per channel from the variables ``z``."""
    q, v, h, p = prob.split(z)
    models = []
    for c in range(prob.n_channels):
        vc = v[c] if abs(v[c]) > 1e-300 else 1e-300
        gain = prob.g[c] / vc
        secs = []
        for k, wr in enumerate(prob.wr):
            a, zn, wn, sn = dc_to_thesis(p[c, k, 0], p[c, k, 1], wr)
            b, zd, wd, sd = dc_to_thesis(q[k, 0], q[k, 1], wr)
            gain *= sd / sn
            secs += [a, zn, wn, b, zd, wd]
        st = Structure(prob.n_sections, prob.integrator, prob.delay is not False,
                       "second-order", "free" if prob.free[c] else "minimum-phase",
                       1 if gain >= 0 else -1)
        models.append(RationalDelayModel(st, np.array([h[c], abs(gain)] + secs, float)))
    return tuple(models)


def _result(prob, z, datas, stages, zeros, wall, options):
    from .modal import modes_of_models

    models = _models(prob, z)
    rel = np.abs(prob.ratio(z) - 1.0)
    poles = models[0].poles()
    if prob.integrator:
        poles = poles[1:]
    poles = poles[np.argsort(np.abs(poles), kind="stable")]
    return SharedFitResult(
        models=models, datas=tuple(datas), poles=poles, rel_errors=rel,
        max_rel_errors=np.max(rel, axis=1), rms_rel_errors=np.sqrt(np.mean(rel ** 2, axis=1)),
        success=bool(stages[-1].success), modes=modes_of_models(models),
        wall_time=wall, nit=int(sum(s.nit for s in stages
                                   if s.solver_status != "vector-fitting")),
        stages=tuple(stages), zeros=tuple(zeros), options=options)
