"""The two starts and the IPOPT stages of the shared-pole fit (layer L4).

``"rational"``: vector fitting with one common pole set over all channels
(:mod:`freqid_casadi.modal._start`; started at the resonance peaks the channels share,
each channel with a constant, the upper residual, unless it has sections of its own), then, with
channel sections, one vector fitting per
channel with the shared poles fixed for its own poles; every channel's zeros from its
pole-residue form, right-half-plane zeros of minimum-phase channels reflected (their group
delay moved to the delay); one IPOPT polish on all data.

``"sequential"``: the package's main loop: a shared pole pair added at the frequency of the
largest relative error over all channels, the window grown to cover it, all parameters
re-fitted, warm-started; then each channel's own sections, one per stage, each at the
frequency of that channel's largest error (all data); a last stage on all data.
"""

import time
from dataclasses import dataclass

import numpy as np

from .. import _interrupt
from ._nlp import SharedProblem
from ..solvers.shared_stage import solve_stage
from ..solvers.shared_termination import SHARED_TERMINATION
from ._start import channel_zeros, factor_variables, peak_poles, shared_vector_fitting
from ..solvers.common import Status
from ..solvers.ipopt import ipopt_status
from ..solvers.termination import Termination

__all__ = ["SharedStage", "logger", "stage_line", "rational_start", "sequential_start",
           "lawson_weights", "lawson_rounds", "EXACT", "ROUND_TERMINATION"]

#: Max relative error below which a channel's fit counts as exact (not beaten by its own).
EXACT = 1e-8
#: The looser test ending the intermediate reweighted rounds of :func:`lawson_rounds` (their
#: weights change again at once); the last round ends by the stages' own test.
ROUND_TERMINATION = Termination(ftol=1e-8, polish_steps=0)


@dataclass(frozen=True)
class SharedStage:
    """One IPOPT stage of :func:`~freqid_casadi.modal.shared.fit_shared`.

    Attributes
    ----------
    stage : int
        0 gain/delay stage (or the rational start's vector fitting), n the stage that added
        shared section n, ``N + j`` (sequential start) the stage that added every channel's
        own section j, ``N + k + 1`` the final all-data stage (the polish of the rational
        start); ``balance_channels`` adds ``N + k + 1 + j`` for its reweighted round j and
        one more for the last solve of the last weighted problem.
    n_sections, window : int
        Shared sections and number of frequencies (lowest first) fitted.
    omega_c : float
        rad/s where the shared section was placed (nan otherwise).
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
        IPOPT converged or the stage ended at a relatively stationary point
        (:mod:`freqid_casadi.solvers.shared_termination`).
    message : str
        Why the stage stopped, with the termination test's numbers.
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
    message: str = ""


def logger(emit):
    """A function handing each :class:`SharedStage` to ``emit`` (the progress channel's,
    :mod:`freqid_casadi._progress`) and returning the record."""
    def log(rec):
        emit(rec)
        return rec
    return log


def stage_line(rec):
    """One line of text for a :class:`SharedStage` (``progress="lines"`` and the bar)."""
    why = rec.status.name.lower().replace("_", " ")
    return (f"stage {rec.stage:2d}: {rec.n_sections} sections, window {rec.window}, "
            f"max rel. error {rec.max_rel_error:.3e}, {rec.nit} it, {rec.wall_time:.2f} s, "
            f"{'converged' if rec.success else f'not converged ({why})'}")


def _stage(prob, x0, window, stage, omega_c, log, lam=None, max_iter=200,
           term=SHARED_TERMINATION):
    """Solve one stage (``term``: its termination test), keep the better of solution and
    start; return (z, lam, record)."""
    with _interrupt.guard():        # CasADi expressions: see stages.StageSolver.__call__
        return _stage_guarded(prob, x0, window, stage, omega_c, log, lam, max_iter, term)


def _stage_guarded(prob, x0, window, stage, omega_c, log, lam, max_iter, term):
    t0 = time.perf_counter()
    x0c = np.clip(x0, *prob.bounds())
    if np.max(np.abs(prob.ratio(x0c, window) - 1.0)) < 1e-10:
        # exact to rounding already: IPOPT cannot meet its tolerance on rounding noise
        res = {"x": x0c, "lam_x": np.zeros_like(x0c), "cost": prob.cost(x0c, window),
               "nit": 0, "t_solve": 0.0, "c_solve": 0.0, "status": "start-exact",
               "success": True, "stationary": True,
               "message": "converged: the start is exact to rounding (max rel. error < 1e-10)"}
    else:
        res = solve_stage(prob, x0, window, lam_x0=lam, max_iter=max_iter, termination=term)
        res = _resolve(prob, res, prob.cost(x0c, window), window, max_iter)
    z, lam_x = res["x"], res["lam_x"]
    if not res["cost"] <= prob.cost(x0c, window):
        z, lam_x = x0c, np.zeros_like(x0c)
    err = float(np.max(np.abs(prob.ratio(z) - 1.0)))
    first = res["status"].split(";")[0].split(" (after")[0]
    status = Status.COST_TOL if first == "start-exact" else \
        Status.CONVERGED if res["stationary"] else ipopt_status(first)
    rec = SharedStage(stage, prob.n_sections, window or prob.omega.size, omega_c, err,
                      res["nit"], res["t_solve"], time.perf_counter() - t0, status,
                      res["status"], res["success"], res["c_solve"], res["message"])
    return z, lam_x, log(rec)


def _resolve(prob, res, cost0, window, max_iter):
    """One more solve (at most ``max_iter // 4`` iterations) from a converged point whose
    cost fell below 1e-6 of the start's: IPOPT's objective is scaled by 1/cost(start), so
    its tolerance was relative to a cost far above the one reached. The stage's success and
    status stay the first solve's (it met its tolerance); the status notes the polish."""
    if not (res["success"] and not res["stationary"] and res["cost"] < 1e-6 * cost0
            and np.max(np.abs(prob.ratio(res["x"], window) - 1.0)) > 1e-10):
        return res
    new = solve_stage(prob, res["x"], window, lam_x0=res["lam_x"],
                      max_iter=max(10, max_iter // 4))
    out = dict(res, nit=res["nit"] + new["nit"], t_solve=res["t_solve"] + new["t_solve"],
               c_solve=res["c_solve"] + new["c_solve"],
               status=f"{res['status']}; rescaled polish: {new['status']}")
    if new["cost"] < res["cost"]:
        out.update(x=new["x"], lam_x=new["lam_x"], cost=new["cost"],
                   stationary=new["stationary"], message=new["message"])
    return out


def sequential_start(make, n_total, n_local, omega, wts, log, max_iter, final_max_iter):
    """The main loop over shared sections, then over each channel's own sections.

    Parameters
    ----------
    make : callable
        ``make(wr, wl)`` -> :class:`~freqid_casadi.modal._nlp.SharedProblem` with shared
        reference frequencies ``wr`` (N,) and local ones ``wl`` (C, k) (rad/s), the data's
        weights.
    n_total, n_local : int
        Shared sections N and sections of each channel's own k.
    omega : ndarray of float, shape (M,)
    wts : ndarray of float, shape (C, M)
    log : callable
    max_iter, final_max_iter : int
        IPOPT iterations of each stage and of the final all-data stage
        (``IpoptOptions.max_iter``, ``final_max_iter``).

    Returns
    -------
    (SharedProblem, ndarray z, ndarray lam, list of SharedStage)
        The last stage's problem, solution, bound multipliers and every stage's record.
    """
    m = omega.size
    prob = make([], None)
    c = prob.n_channels
    z = prob.join(np.zeros((0, 2)), np.ones(c), np.zeros(c), np.zeros((c, 0, 2)))
    window = min(5, m)
    z, lam, rec = _stage(prob, z, window, 0, np.nan, log, max_iter=max_iter)
    stages = [rec]
    for k in range(1, n_total + 1):
        err = np.sqrt(wts) * np.abs(prob.ratio(z) - 1.0)
        idx = int(np.argmax(np.max(err, axis=0)))
        window = min(m, max(window, idx + 1, 2 * k + 3))
        rho = np.abs(prob.ratio(z, idx + 1)[:, idx])
        new, d_new = _section_guess(np.max(err, axis=0), idx, omega, rho)
        old = prob
        prob = make(list(old.wr) + [float(omega[idx])], None)
        q, v, h, p = old.split(z)
        x0 = prob.join(np.vstack([q, d_new]), v, h, np.concatenate([p, new[:, None]], axis=1))
        z, lam, rec = _stage(prob, x0, window, k, float(omega[idx]), log,
                             _move_lam(old, prob, lam), max_iter)
        stages.append(rec)
    for j in range(1, n_local + 1):
        err = np.sqrt(wts) * np.abs(prob.ratio(z) - 1.0)
        idx = np.argmax(err, axis=1)                                   # each channel's own
        rho = np.abs(prob.ratio(z))[np.arange(c), idx]
        guesses = [_section_guess(err[i], idx[i], omega, rho[i:i + 1]) for i in range(c)]
        old = prob
        prob = make(old.wr, np.hstack([old.wl, omega[idx][:, None]]))
        lp, lq = old.split_local(z)
        x0 = prob.join(*old.split(z), np.concatenate([lp, [[g[0][0]] for g in guesses]], 1),
                       np.concatenate([lq, [[g[1]] for g in guesses]], 1))
        z, lam, rec = _stage(prob, x0, None, n_total + j, np.nan, log,
                             _move_lam(old, prob, lam), max_iter)
        stages.append(rec)
    z, lam, rec = _stage(prob, z, None, n_total + n_local + 1, np.nan, log, lam,
                         final_max_iter)
    return prob, z, lam, stages + [rec]


def _section_guess(err, idx, omega, rho):
    """Numerator variables (len(rho), 2) and denominator variables (2,) of a section placed
    at ``omega[idx]`` (its reference frequency): damping from the error peak's half-width,
    the numerator's damping scaled by the ratio magnitudes ``rho`` there (fit's "peak"
    start)."""
    zeta0 = _peak_damping(err, idx, omega)
    zd = zeta0 if rho.max() >= 1 else min(zeta0 / max(rho.max(), 1e-12), 2.0)
    zn = np.clip(zd * rho, 1e-4, 2.0)
    return np.stack([np.ones(rho.size), 2 * zn], axis=1), np.array([1.0, 2 * zd])


def _move_lam(old, new, lam):
    """Bound multipliers of ``old``'s layout placed into ``new``'s (one more shared or
    local section per channel; new entries 0)."""
    out = np.zeros(new.n_vars)
    a, b = old.layout(), new.layout()
    for key in a:
        src, dst = a[key], b[key]
        if src.size:
            dst = dst[tuple(slice(0, s) for s in src.shape)]
            out[dst.ravel()] = lam[src.ravel()]
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


def rational_start(make, n, n_local, omega, phi, wts, free, log, final_max_iter, n_iter,
                   delay0=None):
    """Shared-pole vector fitting (and per channel its own poles), zeros per channel, then
    one IPOPT polish on all data.

    A channel delay of more than half a turn at the highest frequency is removed before
    the vector fitting (``delay0``, from the channels' group delays): the common poles would
    otherwise be spent on it (measured: 3 channels x 300 points with a delay of 40 rad at
    the band's top, start="rational" ended at RMS 0.88-0.94; with it removed, at the noise).

    Parameters
    ----------
    make : callable
        As for :func:`sequential_start`.
    n, n_local : int
        Shared sections N and sections of each channel's own k.
    omega : ndarray of float, shape (M,)
    phi : ndarray of complex, shape (C, M)
        The rational part of the data (times ``j omega`` with an integrator).
    wts : ndarray of float, shape (C, M)
    free : ndarray of bool, shape (C,)
    log : callable
    final_max_iter, n_iter : int
        IPOPT iterations of the polish (``IpoptOptions.final_max_iter``) and
        vector-fitting iterations (``VectorFittingOptions.n_iter``).
    delay0 : ndarray of float, shape (C,), optional
        Delay (s) taken out of each channel before the vector fitting and added to its
        start's delay (default none).

    Returns
    -------
    (SharedProblem, ndarray z, ndarray lam, list of SharedStage)
        As :func:`sequential_start`.
    """
    t0 = time.perf_counter()
    delay0 = np.zeros(phi.shape[0]) if delay0 is None else np.asarray(delay0, float)
    if np.any(delay0):
        phi = phi * np.exp(1j * omega[None, :] * delay0[:, None])
    # a constant per channel (the upper residual; an accelerance's high-frequency limit)
    # unless the channels have sections of their own, which take that role (measured on
    # the beam: 6 shared sections max rel. error 0.0248 -> 0.0109, 119 -> 16 iterations;
    # 5 + 1 own sections with the constant as well: a worse optimum, RMS 5.5e-4 -> 6.1e-4)
    fitted = shared_vector_fitting(omega, phi, 2 * n, wts, n_iter,
                                   initial=peak_poles(omega, phi, 2 * n, wts),
                                   constant=not n_local)
    poles, residues = fitted[:2]
    consts = fitted[2] if not n_local else np.zeros(phi.shape[0])
    floor = 1e-6 * omega[0]
    q, wr = factor_variables(poles, None, floor)
    c = phi.shape[0]
    chans = [(poles, residues[k], np.zeros(0, complex), consts[k]) for k in range(c)]
    if n_local:
        chans = []
        for k in range(c):
            pk, rk = shared_vector_fitting(omega, phi[k:k + 1], 2 * n_local, wts[k:k + 1],
                                           n_iter, fixed=poles)
            chans.append((pk, rk[0], pk[:2 * n_local], 0.0))
    lq, wl = zip(*[factor_variables(own, None, floor) for _, _, own, _ in chans]) \
        if n_local else (np.zeros((c, 0, 2)), np.zeros((c, 0)))
    prob = make(wr, np.array(wl))
    p, lp, h = np.zeros((c, n, 2)), np.zeros((c, n_local, 2)), np.zeros(c)
    for k, (pk, rk, _, dk) in enumerate(chans):
        h[k], p[k], lp[k] = _channel_numerators(pk, rk, dk, free[k], wr, prob.wl[k], floor)
    h = np.clip(h + delay0, 0.0, prob.delay_max) if prob.delay else np.zeros(c)
    P = prob.ratio(prob.join(q, np.ones(c), h, p, lp, np.array(lq)))
    v = np.sum(wts * P.real, axis=1) / np.sum(wts * np.abs(P) ** 2, axis=1)
    bad = ~free & (v <= 0)
    v[bad] = 1.0 / np.median(np.abs(P[bad]), axis=1) if bad.any() else v[bad]
    z0 = prob.join(q, v, h, p, lp, np.array(lq))
    err = float(np.max(np.abs(prob.ratio(z0) - 1.0)))
    stages = [log(SharedStage(0, n, omega.size, np.nan, err, n_iter, 0.0,
                              time.perf_counter() - t0, Status.CONVERGED, "vector-fitting",
                              True))]
    z, lam, rec = _stage(prob, z0, None, n + n_local + 1, np.nan, log, None, final_max_iter)
    return prob, z, lam, stages + [rec]


def _channel_numerators(poles, residues, constant, free, wr, wl, floor):
    """(delay s, shared-section numerators (N, 2), local ones (k, 2)) of one channel from
    its pole-residue form ``constant + sum r / (s - p)``: the zeros (RHP ones reflected for
    a minimum-phase channel, their low-frequency group delay returned) spread over all its
    sections by magnitude."""
    zk = channel_zeros(poles, residues, constant)
    h = 0.0
    if not free:
        # an RHP zero z is the all-pass (s - z)/(s + z*) times its reflection; its
        # low-frequency group delay 2 Re z / |z|^2 goes to the delay
        rhp = zk[zk.real > 0]
        h = float(np.sum(2 * rhp.real / np.abs(rhp) ** 2)) if rhp.size else 0.0
        zk = np.where(zk.real > 0, -np.conj(zk), zk)
    refs = np.concatenate([wr, wl])
    order = np.argsort(refs, kind="stable")
    num = np.zeros((refs.size, 2))
    num[order] = factor_variables(zk, refs[order], floor)[0]
    return h, num[:wr.size], num[wr.size:]


def lawson_weights(prob, z, targets):
    """New weights for the channels that lose against their targets, or None if none does.

    Lawson's iteration (the weighted least-squares route to minimax): each channel whose max
    relative error exceeds its target has its point weights multiplied by
    ``|r_ci| / rms_i |r_ci|`` (then scaled back to the channel's previous mean weight), and
    its mean weight multiplied by ``(max_i |r_ci| / target_c)^2``; the other channels keep
    theirs. Without the second factor a losing channel's share of the cost never grows and
    the shared poles stay where the other channels hold them (measured on the beam's 5 + 1
    fit: the fourth sensor stalled at 1.29x its target over 10 rounds; with it, every
    channel within its target after 2 rounds). Errors up to :data:`EXACT` count as exact
    (no loss).

    Parameters
    ----------
    prob : SharedProblem
        The solved problem (its weights are the current ones).
    z : ndarray of float, shape (n_vars,)
        Its solution.
    targets : ndarray of float, shape (C,)
        Largest acceptable max relative error per channel.

    Returns
    -------
    ndarray of float, shape (C, M), or None
    """
    err = np.abs(prob.ratio(z) - 1.0)
    lose = np.max(err, axis=1) > np.maximum(targets, EXACT)
    if not lose.any():
        return None
    wts = np.array(prob.weights, float)
    e = err[lose]
    upd = wts[lose] * e / np.sqrt(np.mean(e * e, axis=1, keepdims=True))
    ratio = np.max(e, axis=1, keepdims=True) / np.maximum(targets[lose], EXACT)[:, None]
    wts[lose] = upd / np.mean(upd, axis=1, keepdims=True) * \
        np.mean(wts[lose], axis=1, keepdims=True) * ratio ** 2
    return wts


def lawson_rounds(prob, z, lam, targets, log, final_max_iter, rounds):
    """Lawson rounds (:func:`lawson_weights`) as warm-started solves of the reweighted
    problem, the intermediate ones ended by :data:`ROUND_TERMINATION`, then one solve of
    the last weighted problem to the stages' own test (so the result's success is that of
    the returned model's problem).

    Parameters
    ----------
    prob : SharedProblem
        The solved problem of the unweighted fit.
    z, lam : ndarray of float, shape (n_vars,)
        Its solution and bound multipliers.
    targets : ndarray of float, shape (C,)
        Largest acceptable max relative error per channel.
    log : callable
    final_max_iter : int
        IPOPT iterations of each round and of the last solve (``IpoptOptions.final_max_iter``).
    rounds : int
        Most reweighted rounds.

    Returns
    -------
    (SharedProblem, ndarray z, list of SharedStage)
        The last weighted problem, its solution and the rounds' records (stage numbers
        continue from the fit's final stage, one per round).
    """
    stages, no = [], prob.n_sections + prob.n_local + 1
    for k in range(1, rounds + 1):
        w = lawson_weights(prob, z, targets)
        if w is None:
            break
        with _interrupt.guard():
            prob = SharedProblem(prob.omega, prob.phi, w, prob.g, prob.wr, prob.integrator,
                                 prob.delay, prob.free, prob.delay_max, prob.wl)
        z, lam, rec = _stage(prob, z, None, no + k, np.nan, log, lam, final_max_iter,
                             ROUND_TERMINATION)
        stages.append(rec)
    if stages:
        z, lam, rec = _stage(prob, z, None, no + len(stages) + 1, np.nan, log, lam,
                             final_max_iter)
        stages.append(rec)
    return prob, z, stages
