"""A global start for the fit: a linear-algebra rational fit turned into sections (layer L4).

The sequential loop of the thesis stops far from what its model structure can do. This
start fits all sections at once: for a trial delay, the data with the poles at the origin
and the delay removed, ``Phi(jw) * (jw)^k * exp(jwh)``, is fitted by relaxed vector
fitting with pole flipping (:func:`freqid_casadi.baselines.vector_fitting`, relative
weighting); right-half-plane zeros are reflected to the left half plane (same magnitude,
the phase difference is left to the delay), poles and zeros are paired into sections
(sorted by frequency), the gain is fitted in closed form. The delay is then updated from the
reflected zeros' group delay, a few times from h = 0; for a delay of more than half a turn
at the band edge the delay is also searched around the data's median group delay (the
updates from h = 0 see only the delay that right-half-plane zeros can represent, which
misses delays of many turns). The trial with the lowest max relative error wins. The
caller then polishes all parameters, delay included, by one IPOPT stage on all data
(:func:`freqid_casadi.fitting.fit.fit` with ``start="rational"``).

Above :data:`PROBE_POINTS` frequencies the trial delays (the updates, the search) are
tried on every k-th point (evenly spaced indices, the ends kept: the grid's spacing law is
kept), and only the best of them is made again on the data (where none is usable there,
they are all made on the data). A trial on the data fits, above :data:`START_POINTS`
frequencies, its vector fitting to every k-th point, and its gain and error to all
points; the start is only a start, and the polish that follows sees all data. At or below
:data:`PROBE_POINTS` nothing is subsampled.
"""

import contextlib
import contextvars
import hashlib
import math
import time
from dataclasses import dataclass

import numpy as np

from ..core.data import FrequencyData
from ..errors import OptionError, SolverError
from ..core.model import RationalDelayModel, times_jw_power

__all__ = ["RationalStart", "RationalStartError", "rational_start", "signed_start",
           "rational_start_memo", "best_signed_start", "memo_map", "MIN_FORKED_JOB",
           "sections_from_roots", "group_delay_estimate", "phase_steps",
           "significant_group_delay", "GROUP_DELAY_STEPS",
           "search_delay", "GROUP_DELAY_PHASE", "PROBE_PHASE", "MAX_TRIALS",
           "EXACT_TRIAL"]


class RationalStartError(SolverError):
    """Vector fitting gave no usable model at any trial delay (fit's ``start="best"``
    then keeps the sequential start; ``start="rational"`` raises it)."""


@dataclass(frozen=True)
class RationalStart:
    """The start found by :func:`rational_start`.

    Attributes
    ----------
    model : RationalDelayModel
        Stable, minimum-phase start (beta >= 0).
    delay : float
        The chosen trial delay (s).
    max_rel_error : float
        Of ``model`` on the data.
    delays, errors : ndarray of float, shape (n_delays,)
        The scanned delays (s) and the max relative error of each start.
    n_rhp_zeros_reflected : int
        Right-half-plane zeros of the chosen vector fit that were reflected.
    """

    model: RationalDelayModel
    delay: float
    max_rel_error: float
    delays: np.ndarray
    errors: np.ndarray
    n_rhp_zeros_reflected: int


def _quadratics(roots, n_factors, floor):
    """Split roots (closed LHP) into ``n_factors`` factors, each given as (c2, c1, c0) of
    ``c2 s^2 + c1 s + c0`` with c >= 0, at most two roots each, sorted by |root|."""
    roots = np.asarray(roots, complex)
    cplx = roots[roots.imag > 1e-12 * np.maximum(1.0, np.abs(roots))]
    real = np.sort(-np.abs(roots[np.abs(roots.imag) <= 1e-12 * np.maximum(1.0, np.abs(roots))]
                           .real))[::-1]
    factors = []
    for r in cplx:                                     # one of each conjugate pair
        w = max(abs(r), floor)
        factors.append((abs(r), (1.0, max(-2 * r.real, 0.0), w * w)))
    real = [min(r, -floor) for r in real]              # closed LHP, away from 0
    for k in range(0, len(real) - 1, 2):
        r1, r2 = real[k], real[k + 1]
        factors.append((np.sqrt(r1 * r2), (1.0, -(r1 + r2), r1 * r2)))
    if len(real) % 2:
        r = real[-1]
        factors.append((abs(r), (0.0, 1.0, -r)))        # s + |r|
    factors.sort(key=lambda f: f[0])
    while len(factors) < n_factors:
        factors.append((np.inf, (0.0, 0.0, 1.0)))       # constant 1: roots at infinity
    if len(factors) > n_factors:                         # too many roots: merge is wrong;
        raise OptionError(f"{len(factors)} factors for {n_factors} sections")  # pragma: no cover
    return [f[1] for f in factors]


def _free_quadratics(roots, n_factors, floor):
    """As :func:`_quadratics` for roots anywhere (free zeros): real ``(c2, c1, c0)`` with
    ``c0 > 0`` (a factor with a negative constant term is negated; the gain absorbs the
    sign), real roots paired in order of magnitude whatever their signs."""
    roots = np.asarray(roots, complex)
    tol = 1e-12 * np.maximum(1.0, np.abs(roots))
    factors = [(abs(r), (1.0, -2 * r.real, max(abs(r), floor) ** 2))
               for r in roots[roots.imag > tol]]
    real = roots[np.abs(roots.imag) <= tol].real
    real = real[np.argsort(np.abs(real))]
    real = [np.copysign(max(abs(r), floor), r if r != 0 else -1.0) for r in real]
    for k in range(0, len(real) - 1, 2):
        r1, r2 = real[k], real[k + 1]
        c = (1.0, -(r1 + r2), r1 * r2)
        factors.append((np.sqrt(abs(r1 * r2)), c if c[2] > 0 else tuple(-x for x in c)))
    if len(real) % 2:
        r = real[-1]
        factors.append((abs(r), (0.0, 1.0, -r) if r < 0 else (0.0, -1.0, r)))
    factors.sort(key=lambda f: f[0])
    while len(factors) < n_factors:
        factors.append((np.inf, (0.0, 0.0, 1.0)))
    if len(factors) > n_factors:                          # pragma: no cover
        raise RationalStartError(f"{len(factors)} factors for {n_factors} sections")
    return [f[1] for f in factors]


def _theta(c2, c1, c0):
    """Thesis (a, zeta, omega) and scale s with ``c2 s^2 + c1 s + c0 = (a s^2 + 2 zeta omega
    s + omega^2) * s_scale``... returned as (a, zeta, omega, scale)."""
    omega = np.sqrt(c0)
    scale = 1.0                                        # c0 = omega^2 exactly
    return c2, c1 / (2 * omega), omega, scale


def sections_from_roots(poles, zeros, n_sections, *, basis="second-order", floor=1e-9,
                        free_zeros=False):
    """Section parameters (thesis order) whose roots are ``poles`` and ``zeros``.

    Roots must already be in the closed left half plane (``zeros`` anywhere with
    ``free_zeros``); they are paired by frequency.

    Parameters
    ----------
    poles, zeros : array_like of complex
        The roots (closed left half plane).
    n_sections : int
    basis : {"second-order", "first-order"}
    floor : float
        Smallest root magnitude used (rad/s): roots at 0 are moved to ``floor``.
    free_zeros : bool
        Zeros anywhere (second-order basis): numerators may have negative ``a`` or
        ``zeta_num`` (a model structure with ``zeros="free"``).

    Returns
    -------
    theta : ndarray, shape (n_sections, 6) or (n_sections, 4)
    scale : float
        ``prod num_k / prod den_k`` equals ``scale * prod (s - z)/(s - p)`` up to the
        leading coefficients; the caller fits the gain anyway.
    """
    if basis == "second-order":
        dens = _quadratics(poles, n_sections, floor)
        nums = (_free_quadratics if free_zeros else _quadratics)(zeros, n_sections, floor)
        rows = []
        for (n2, n1, n0), (d2, d1, d0) in zip(nums, dens):
            a, zn, wn, _ = _theta(n2, n1, n0)
            b, zd, wd, _ = _theta(d2, d1, d0)
            rows.append([a, zn, wn, b, zd, wd])
        return np.array(rows), 1.0
    p = np.sort(np.abs(np.asarray(poles, complex).real))
    z = np.sort(np.abs(np.asarray(zeros, complex).real))
    rows = []
    for k in range(n_sections):
        pk = max(p[k], floor) if k < p.size else None
        zk = max(z[k], floor) if k < z.size else None
        rows.append([1.0 if zk else 0.0, zk or 1.0, 1.0 if pk else 0.0, pk or 1.0])
    return np.array(rows), 1.0


def _fit_gain(model_unit, omega, target):
    """Gain K > 0 minimising sum |target/(K P) - 1|^2 (closed form in 1/K)."""
    u = target / model_unit.rational_response(omega)
    c = float(np.sum(u.real) / np.sum(np.abs(u) ** 2))
    return 1.0 / c if c > 0 else float(np.median(np.abs(u)))


#: Largest number of frequencies the start's vector fittings see (every k-th point above;
#: 200 000 points: 15 vector fittings of 0.25 s each otherwise, most of the start).
START_POINTS = 16384


#: Above this many frequencies the start's trial delays (:func:`rational_start`: the
#: delay updates and the group-delay search) are tried on every k-th point, vector fits
#: and errors alike, and only the best of them is made again on the data (each trial at
#: :data:`START_POINTS` cost 0.2-0.4 s: 200 000 points of example A at 2 sections took 14 s
#: instead of 9 s with the search's probes on all points, and the delay updates on all
#: points were a third of the fit).
PROBE_POINTS = 4096


def _subsample(n, most=START_POINTS):
    """Indices of at most ``most`` of ``n`` points, evenly spaced, ends kept
    (``slice(None)`` when ``n`` is not above it)."""
    if n <= most:
        return slice(None)
    return np.unique(np.linspace(0, n - 1, most).round().astype(int))


def _fitted_roots(vector_fitting, omega, x, scale, n_poles, n_iter):
    """Poles and finite zeros of the stable vector fitting of ``x`` (complex (M,)) at
    ``omega`` (rad/s, (M,)); ``scale``: the largest ``|x|`` before the delay's phase.

    Within :func:`rational_start_memo` (one fit) the roots are kept, and those of ``-x``
    are the same roots: vector fitting with relative weights is exactly odd in the data
    (its row weights ``1/|x|`` are even, its least-squares problems change sign in
    whole rows and columns, which IEEE rounding follows to the last bit: the fit of ``-x``
    is ``-C``, ``-D`` with the same ``A``, ``B``), and the zeros ``eig(A - B C / D)`` do
    not see the sign. The gain-sign check and ``integrator="auto"`` run the rational start
    on both signs of the data, mostly at the same trial delays: the negated start reuses
    the vector fittings of the positive one.
    """
    memo = _MEMO.get()
    if memo is not None:
        key = ("roots", vector_fitting, n_poles, n_iter, float(scale), _digest(omega))
        mine, negated = key + (_digest(x),), key + (_digest(-x),)
        hit = memo.get(mine) or memo.get(negated)
        if hit is not None:
            return hit
    vf = vector_fitting(FrequencyData(omega, x), n_poles, n_iter=n_iter,
                        enforce_stable_poles=True)
    poles = vf.poles()
    d = float(np.squeeze(vf.D))
    if abs(d) > 1e-10 * scale:
        # zeros of C (sI - A)^-1 B + D: eig(A - B C / D), exact for a biproper SISO fit and
        # much faster than the general pencil (SLICOT AB08ND)
        zeros = np.linalg.eigvals(np.asarray(vf.A) - np.outer(vf.B, vf.C) / d)
    else:
        zeros = vf.zeros()
    roots = poles, zeros[np.isfinite(zeros)]
    if memo is not None:
        memo[mine] = roots
    return roots


def _digest(a):
    """A short key of an array's bytes (the memo keeps no copy of the data)."""
    return hashlib.blake2b(np.ascontiguousarray(a).tobytes(), digest_size=16).digest()


def _start_at(vector_fitting, data, structure, base, h, n_poles, n_iter, floor):
    """Vector fit at trial delay h -> (model, max rel. error, rhp zeros, group-delay step)."""
    omega, phi = data.omega, data.response
    s = 1j * omega
    sub = _subsample(omega.size)
    poles, zeros = _fitted_roots(vector_fitting, omega[sub], base[sub] * np.exp(s[sub] * h),
                                 float(np.max(np.abs(base))), n_poles, n_iter)
    free = structure.zeros == "free"
    # with free zeros only the right-half-plane zeros beyond the band stand for a delay
    # (their phase is nearly linear in omega there); those inside are kept as zeros
    rhp_mask = (zeros.real > 0) & ((np.abs(zeros) > omega[-1]) if free else True)
    rhp = zeros[rhp_mask]
    # each RHP zero z contributes the all-pass (s - z)/(s + conj z), whose group delay at
    # low frequency is 2 Re z / |z|^2: the delay the fit is missing
    step = float(np.sum(2 * rhp.real / np.abs(rhp) ** 2))
    poles = np.where(poles.real > 0, -poles.conj(), poles)
    zeros = np.where(rhp_mask, -zeros.conj(), zeros)
    zeros = zeros[np.argsort(np.abs(zeros))][:n_poles]
    theta, _ = sections_from_roots(poles, zeros, structure.n_sections,
                                   basis=structure.basis, floor=floor,
                                   free_zeros=free and structure.basis == "second-order")
    beta = np.concatenate([[h, 1.0], theta.ravel()])
    gain = _fit_gain(RationalDelayModel(structure, beta), omega, phi * np.exp(s * h))
    if not (np.isfinite(gain) and gain > 0):
        return None, np.inf, rhp.size, step
    beta[1] = gain
    model = RationalDelayModel(structure, beta)
    err = float(np.max(model.relative_error(data)))
    return model, (err if np.isfinite(err) else np.inf), int(rhp.size), step


def rational_start(data, structure, *, delay_max, delay0=0.0, max_delay_updates=12,
                   n_iter=10, group_delay_trial=False):
    """Stable, minimum-phase start for all sections at once (see the module docstring).

    Parameters
    ----------
    data : FrequencyData
    structure : Structure
        Number of sections, basis, integrator and delay of the model to start.
    delay_max : float
        Largest delay (s) tried.
    delay0 : float
        First trial delay (s), e.g. the sequential loop's estimate.
    max_delay_updates : int
        Delay updates ``h <- h + sum_{RHP zeros} 2 Re z/|z|^2``: a delay missing from the
        data's phase is fitted by right-half-plane zeros, whose low-frequency group delay
        estimates it. The updates are safeguarded by a bracket (a fit with RHP zeros means
        the delay is too small; bisection when a step leaves the bracket) and stop when a
        minimum-phase fit is reached with a tight bracket or a tiny error. With more than
        one update, when the data's group delay (:func:`group_delay_estimate`) has a
        phase above :data:`GROUP_DELAY_PHASE` at the highest frequency and no trial is
        exact yet and the best trial's delay is more than a quarter turn from it, the
        delay is also searched around it (:func:`search_delay`, steps of
        :data:`PROBE_PHASE` rad at the highest frequency) and the updates run again from
        the best probe.
    n_iter : int
        Vector-fitting iterations per trial delay.
    group_delay_trial : bool
        When the trials' best is poor (max relative error above :data:`POOR_TRIAL`), also
        try the data's group delay, however small its phase (the updates take a poor
        fit's right-half-plane zeros for too small a delay and can run off).

    Returns
    -------
    RationalStart
        The best (lowest max relative error) of the trial delays.
    """
    key = (data.omega.tobytes(), data.response.tobytes(),
           None if data.weights is None else data.weights.tobytes(), repr(structure),
           float(delay_max), float(delay0), int(max_delay_updates), int(n_iter),
           bool(group_delay_trial))
    memo = _MEMO.get()
    if memo is not None and key in memo:       # fit's gain-sign check ran this start
        return memo[key]
    result = _rational_start(data, structure, delay_max, delay0, max_delay_updates, n_iter,
                             group_delay_trial)
    if memo is not None:
        memo[key] = result
    return result


#: The starts computed inside one :func:`rational_start_memo` (one fit): the gain-sign
#: check of ``fit(gain_sign="auto")`` runs the same start as the fit's rational start.
_MEMO = contextvars.ContextVar("rational_start_memo", default=None)


def signed_start(data, structure, sign, *, delay_max, group_delay_trial=False):
    """The rational start of ``structure`` on ``sign`` times the data, with its relative
    errors, or None when vector fitting gives no usable start (floating-point warnings
    silenced).

    Parameters
    ----------
    data : FrequencyData
        The (scaled) data.
    structure : Structure
    sign : {1, -1}
        The gain sign tried: the start is made on ``sign * data.response``.
    delay_max : float
        As :func:`rational_start` (s, in the data's scale).
    group_delay_trial : bool
        As :func:`rational_start`.

    Returns
    -------
    (RationalStart, ndarray of float, shape (M,)) or None
        The start and ``|Phi_i / G_N(j w_i) - 1|`` on the signed data.
    """
    target = FrequencyData(data.omega, sign * data.response, None, data.weights)
    try:
        with np.errstate(all="ignore"):
            start = rational_start(target, structure, delay_max=delay_max,
                                   group_delay_trial=group_delay_trial)
            return start, np.abs(start.model.relative_error(target))
    except (RationalStartError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None


def best_signed_start(data, structure, signs, *, delay_max, exact,
                      group_delay_trial=False):
    """The better of :func:`signed_start`'s starts for ``signs`` in turn, the next sign
    skipped once a start's RMS relative error is below ``exact`` (the first on a tie).

    Parameters
    ----------
    data : FrequencyData
        The (scaled) data.
    structure : Structure
    signs : tuple of int
        The gain signs tried, in order (e.g. ``(1, -1)``).
    delay_max : float
        As :func:`rational_start`.
    exact : float
        RMS relative error below which no other sign can do better.
    group_delay_trial : bool
        As :func:`rational_start`.

    Returns
    -------
    (float, float, RationalStart) or None
        RMS and max relative error and the start; None when no start is usable (or none
        has a finite RMS).
    """
    best = None
    for sign in signs:
        found = signed_start(data, structure, sign, delay_max=delay_max,
                             group_delay_trial=group_delay_trial)
        if found is None:
            continue
        start, err = found
        rms = float(np.sqrt(np.mean(err ** 2)))
        if not math.isfinite(rms):
            continue
        if best is None or rms < best[0]:
            best = (rms, float(np.max(err)), start)
        if rms < exact:
            break                                   # the other sign cannot do better
    return best


#: Seconds the first of :func:`memo_map`'s jobs must take before the others go to worker
#: processes: starting two forked workers for a fit's process (about 150 MiB) took 20-40
#: ms of wall time (measured); the integrator's starts take 3-60 ms each on the robot arm
#: and the actuator (better run here) and 0.1-0.55 s on the S-parameter sets.
MIN_FORKED_JOB = 0.1


def memo_map(fn, jobs):
    """``[fn(*args) for args in jobs]``: the first here and, when it took at least
    :data:`MIN_FORKED_JOB` and the fit allows workers
    (:func:`~freqid_casadi._workers.allow_jobs`), the others in forked workers, the
    rational starts and vector fittings each worker computed then added to this fit's
    memo (:func:`rational_start_memo`) so that what follows reuses them as when the jobs
    run here. The results do not depend on where the jobs ran.

    Parameters
    ----------
    fn : callable
        A module-level function (it and its arguments are pickled).
    jobs : list of tuple

    Returns
    -------
    list
    """
    from .._workers import forked_map

    if not jobs:
        return []
    t0 = time.perf_counter()
    first = fn(*jobs[0])
    found = (forked_map(_memo_job, [(fn, *args) for args in jobs[1:]])
             if time.perf_counter() - t0 >= MIN_FORKED_JOB else None)
    if found is None:
        return [first] + [fn(*args) for args in jobs[1:]]
    memo = _MEMO.get()
    for _, new in found if memo is not None else ():
        for key, value in new.items():
            memo.setdefault(key, value)
    return [first] + [result for result, _ in found]


def _memo_job(fn, *args):
    """``(fn(*args), the memo's entries it added)``: :func:`memo_map`'s job in a worker."""
    memo = _MEMO.get()
    if memo is None:            # (no memo: nothing to share)
        return fn(*args), {}
    before = set(memo)
    result = fn(*args)
    return result, {key: value for key, value in memo.items() if key not in before}


@contextlib.contextmanager
def rational_start_memo():
    """Within this context (one :func:`~freqid_casadi.fitting.fit.fit`, in one thread), a
    :func:`rational_start` of the same data and arguments is computed once."""
    token = _MEMO.set({})
    try:
        yield
    finally:
        _MEMO.reset(token)


def phase_steps(response, lag=1):
    """The phase steps ``angle(H[k+lag] conj(H[k]))`` of a response, each in (-pi, pi]
    (no unwrapping), also where the product overflows (responses near 1e300).

    Parameters
    ----------
    response : ndarray of complex, shape (M,)
    lag : int, optional
        Steps between the two samples, 1 <= lag < M (default 1: neighbours).

    Returns
    -------
    ndarray of float, shape (M - lag,)
        rad.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        product = response[lag:] * np.conj(response[:-lag])
    step = np.angle(product)
    big = ~np.isfinite(product)
    if np.any(big):                   # products that overflow (responses near 1e300)
        angle = np.angle(response)
        d = (angle[lag:] - angle[:-lag])[big]
        step[big] = (d + np.pi) % (2 * np.pi) - np.pi
    return step


#: Most phase steps :func:`group_delay_estimate` takes across the band: denser data are
#: read at a lag of several samples (``ceil((M - 1) / GROUP_DELAY_STEPS)``). Between
#: neighbouring samples of dense, noisy data the delay's phase step is smaller than the
#: noise's, and the median of those steps drifts from the delay towards the mean phase
#: slope, resonances included, by a random amount (a corpus accelerance, 1.5 % noise,
#: 0.19 rad of delay at the band's top, 0.66 rad of median group delay without noise:
#: 1.6 rad at 1600 points, 3.7 at 4000, where its start then searched around a delay the
#: data do not have, 309 vector fittings instead of 25; 0.91 and 0.96 at this lag). Of 100
#: corpus cases sampled at 6400 points, the neighbours' estimate put 11 on the other side
#: of :data:`GROUP_DELAY_PHASE` than at their own points, the lagged one none; with 256
#: steps none either, but more measured sets would change (this many keeps every set of
#: up to 513 points as it was).
GROUP_DELAY_STEPS = 512


def group_delay_estimate(omega, response):
    """The data's delay as its typical group delay: the median over the band (weighted by
    the frequency step) of ``-angle(H[k+1] conj(H[k])) / (omega[k+1] - omega[k])``.

    A rational part's group delay is concentrated at its resonances and antiresonances;
    elsewhere the phase falls as ``-h omega``, so the median sees the delay ``h`` (on the
    corpus's delayed cases within a few % once the delay's phase at the band edge exceeds
    a few rad). No unwrapping: each step's phase difference is taken in (-pi, pi], which
    holds up to the resolvable delay ``pi / max(diff(omega))``.

    Above :data:`GROUP_DELAY_STEPS` steps the steps are taken between samples ``lag``
    apart (``lag = ceil((M - 1) / GROUP_DELAY_STEPS)``, all ``M - lag`` of them), unless
    the neighbours' estimate says the delay's phase over such a step would exceed a
    quarter turn (then the largest lag within it): on dense, noisy data the neighbours'
    phase steps are mostly noise, and their median drifts towards the mean phase slope.

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s, increasing, M >= 2.
    response : ndarray of complex, shape (M,)

    Returns
    -------
    float
        Seconds (negative when the phase rises over most of the band).
    """
    h = _median_step_delay(omega, response, 1)
    lag = -(-(omega.size - 1) // GROUP_DELAY_STEPS)          # ceil((M - 1) / steps)
    if lag > 1 and h != 0.0:
        # a lag whose phase step of the delay ``h`` stays within a quarter turn: the
        # lagged steps resolve it too (large delays, e.g. a line's, keep the neighbours)
        most = 0.25 * np.pi / (abs(h) * float(np.max(np.diff(omega))))
        lag = lag if most >= lag else int(most)
    return h if lag <= 1 else _median_step_delay(omega, response, lag)


def _median_step_delay(omega, response, lag):
    """The median (weighted by the steps' widths) of ``-phase_steps(response, lag) /
    (omega[k+lag] - omega[k])`` (s)."""
    dw = omega[lag:] - omega[:-lag]
    tau = -phase_steps(response, lag) / dw
    order = np.argsort(tau)
    cum = np.cumsum(dw[order])
    return float(tau[order][np.searchsorted(cum, 0.5 * cum[-1])])


#: The rational start also searches the delay around the data's group delay
#: (:func:`group_delay_estimate`) when that delay's phase at the highest frequency exceeds
#: this (rad): from h = 0 the updates see only the delay that right-half-plane zeros can
#: represent. On the corpus's 51 delayed in-class cases above it, the updates from h = 0
#: reached the noise in 25, the search in all 51 (9 fits had ended near RMS 1).
GROUP_DELAY_PHASE = np.pi

#: Max relative error of a trial start that explains the data exactly: the delay updates
#: stop there and the group-delay search does not run.
EXACT_TRIAL = 1e-9

#: Max relative error of the best trial above which a start asked for it
#: (``group_delay_trial``) also tries the data's group delay: the updates take
#: right-half-plane zeros for too small a delay, which a fit too poor to model the
#: rational part breaks (an integrator with one lightly damped pole-zero pair and 2 rad of
#: delay at the band's top: every trial of its k = 1 start above 1.0, the group delay's
#: 0.18).
POOR_TRIAL = 0.5

#: Probe step, in rad of phase at the highest frequency (``PROBE_PHASE / omega[-1]`` s).
PROBE_PHASE = 0.1
#: Most vector fits one search makes.
MAX_TRIALS = 17


def search_delay(trial, h0, step, delay_max, max_trials=MAX_TRIALS):
    """Local search of ``trial(h)`` (an error, inf when unusable) over the delay.

    Probes ``h0 +- k step`` for k = 1, 2, 4, 8, then a compass search around the best
    probe with steps ``step / 2, step / 4, ...`` (halved when neither side improves).

    Parameters
    ----------
    trial : callable
        ``h -> float``.
    h0 : float
        Start (s); probed first.
    step : float
        Probe step (s), > 0.
    delay_max : float
        Probes are clipped into ``[0, delay_max]`` (s).
    max_trials : int
        Most calls of ``trial``.

    Returns
    -------
    dict
        ``{h: trial(h)}`` of every probe.
    """
    seen = {}

    def probe(h):
        h = float(np.clip(h, 0.0, delay_max))
        if h not in seen and len(seen) < max_trials:
            seen[h] = float(trial(h))
        return seen.get(h, np.inf)

    probe(h0)
    for sign in (1.0, -1.0):
        for k in (1, 2, 4, 8):
            probe(h0 + sign * k * step)
    d = 0.5 * step
    while len(seen) < max_trials and d >= step / 64:
        best = min(seen, key=seen.get)
        if min(probe(best + d), probe(best - d)) >= seen[best]:
            d *= 0.5
    return seen



def _rational_start(data, structure, delay_max, delay0, max_delay_updates, n_iter,
                    group_delay_trial=False):
    from ..baselines import vector_fitting

    base = times_jw_power(data.response, data.omega, structure.origin_order)
    n_poles = structure.n_sections * (2 if structure.basis == "second-order" else 1)
    floor = 1e-6 * data.omega[0]

    def trial(on, on_base, h):
        """The start at delay ``h`` on the data ``on`` (``on_base``: its response times
        ``(j omega)^k``): ``(model, max rel. error, n_rhp, step)``, unusable as inf."""
        try:
            return _start_at(vector_fitting, on, structure, on_base, h, n_poles, n_iter,
                             floor)
        except (ValueError, np.linalg.LinAlgError, ArithmeticError):
            return None, np.inf, 1, 0.0

    trials = {}                               # h -> (model, max rel. error, n_rhp, step)

    def run(h):
        if h not in trials:
            trials[h] = trial(data, base, h)
        return trials[h]

    h0 = float(np.clip(delay0, 0.0, delay_max)) if structure.delay else 0.0
    n_updates = max_delay_updates if structure.delay else 1
    h_gd = _group_delay_start(data, structure, delay_max, max_delay_updates)

    def trial_delays(probe_run, seen):
        """The updates, then the search, by ``probe_run`` (its trials in ``seen``)."""
        _delay_updates(probe_run, h0, delay_max, n_updates)
        best = _best(seen)
        thinned = seen is not trials
        # the search, unless a trial is exact or the updates (on all points: on every
        # k-th point the search costs a few of their trials) already found a delay within
        # a quarter turn (at the highest frequency) of the group delay
        if (h_gd is not None and (best is None or seen[best][1] >= EXACT_TRIAL)
                and (thinned
                     or abs((best or 0.0) - h_gd) * float(data.omega[-1]) > 0.5 * np.pi)):
            _search(probe_run, data, h_gd, delay_max, max_delay_updates)

    probe_run, seen, finish = _probe_runs(data, base, trial, run, trials, n_updates > 1)
    trial_delays(probe_run, seen)
    finish()
    if _best(trials) is None and seen is not trials:   # none usable on every k-th point
        trial_delays(run, trials)
    best = _best(trials)
    if group_delay_trial and (best is None or trials[best][1] > POOR_TRIAL):
        h = _group_delay_start(data, structure, delay_max, max_delay_updates, any_phase=True)
        if h is not None and h not in trials:
            run(h)
            best = _best(trials)
    if best is None:
        raise RationalStartError("the rational start failed (vector fitting gave no usable model); "
                          "use start='sequential'")
    model, err, n_rhp, _ = trials[best]
    return RationalStart(model=model, delay=float(best), max_rel_error=err,
                         delays=np.asarray(list(trials), float),
                         errors=np.asarray([t[1] for t in trials.values()], float),
                         n_rhp_zeros_reflected=n_rhp)


def _best(trials):
    """The delay of the usable trial with the lowest error (the first of ties), or None."""
    usable = [h for h, t in trials.items() if t[0] is not None]
    return min(usable, key=lambda h: trials[h][1]) if usable else None


def _probe_runs(data, base, trial, run, trials, several):
    """``(probe_run, seen, finish)`` for the trial delays of one start (``run``: the trial
    on the data, kept in ``trials``): above :data:`PROBE_POINTS` frequencies, when the
    start tries ``several`` delays, ``probe_run(h)`` makes the trial on every k-th point
    (``trial(data, base, h)``), kept in ``seen``, and ``finish()`` makes the best of those
    on the data by ``run`` (the next best, up to the third, when a trial is unusable
    there); else (one trial delay: no delay, or no updates) ``run``, ``trials`` and
    nothing to finish."""
    sub = _subsample(data.omega.size, PROBE_POINTS)
    if not several or isinstance(sub, slice):
        return run, trials, lambda: None
    coarse = FrequencyData(data.omega[sub], data.response[sub])
    seen = {}

    def probe_run(h):
        if h not in seen:
            seen[h] = trial(coarse, base[sub], h)
        return seen[h]

    def finish():
        usable = [h for h, t in seen.items() if t[0] is not None]
        for h in sorted(usable, key=lambda h: seen[h][1])[:3]:  # stable: the first of ties
            if run(h)[0] is not None:
                return

    return probe_run, seen, finish


def _search(probe_run, data, h_gd, delay_max, max_delay_updates):
    """Probe the delay around ``h_gd`` (:func:`search_delay`), then the updates from the
    best probe, by ``probe_run`` (:func:`_probe_runs`)."""
    step = PROBE_PHASE / float(data.omega[-1])
    probes = search_delay(lambda h: probe_run(h)[1], h_gd, step, delay_max)
    _delay_updates(probe_run, min(probes, key=probes.get), delay_max, max_delay_updates)


def significant_group_delay(data):
    """The data's group delay (s, :func:`group_delay_estimate`) when its phase at the
    highest frequency exceeds :data:`GROUP_DELAY_PHASE` (more than half a turn), else 0.

    Parameters
    ----------
    data : FrequencyData

    Returns
    -------
    float
        Seconds (0 with fewer than 3 frequencies).
    """
    if data.omega.size < 3:
        return 0.0
    h = group_delay_estimate(data.omega, data.response)
    return h if h * float(data.omega[-1]) > GROUP_DELAY_PHASE else 0.0


def _group_delay_start(data, structure, delay_max, max_delay_updates, any_phase=False):
    """The data's group delay (s) when a delay search should start there, else None; with
    ``any_phase`` also when its phase at the highest frequency is below
    :data:`GROUP_DELAY_PHASE`."""
    if not structure.delay or max_delay_updates <= 1:
        return None
    if any_phase and data.omega.size >= 3:
        h = group_delay_estimate(data.omega, data.response)
    else:
        h = significant_group_delay(data)
    return h if 0.0 < h < delay_max else None


def _delay_updates(run, h, delay_max, max_updates):
    """Trial delays from ``h`` (``run(h) -> (model, error, n_rhp, step)``): each step adds
    the reflected zeros' group delay, safeguarded by a bracket (a fit with right-half-plane
    zeros means the delay is too small; bisection when a step leaves the bracket)."""
    lo, hi = 0.0, float(delay_max)           # bracket: below lo the fit needs RHP zeros
    for _ in range(max_updates):
        _, err, n_rhp, step = run(h)
        if n_rhp > 0:
            lo = max(lo, h)                  # the delay is too small: RHP zeros model it
            new_h = h + step
            if not lo < new_h < hi:          # the step leaves the bracket: bisect
                new_h = 0.5 * (lo + hi)
        else:
            hi = min(hi, h)                  # minimum phase already: not too small
            new_h = 0.5 * (lo + hi)
            if err < EXACT_TRIAL or hi - lo <= 1e-3 * max(hi, 1e-12):
                return
        if abs(new_h - h) <= 1e-12 * max(1.0, h):
            return
        h = float(new_h)
