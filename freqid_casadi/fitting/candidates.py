"""Which of several fitted models a fit keeps (layer L4).

``fit(start="best")`` runs the sequential loop and the rational start; every fit with a
delay also tries the same model at ``h = 0`` (the nested model class: a fit with a delay
must never be worse than the fit without one), unless the data's phase lag rules that
model out of the choice (:func:`zero_delay_floor`). :func:`choose` keeps, among the candidates
within 10 % of the lowest max relative error, a converged one if there is any, and then
the lowest RMS error. With weights, both are of the weighted relative error
``sqrt(w_i / mean(w)) |r_i|``, the objective's own measure (an unweighted ranking kept an
unconverged h = 0 candidate over the converged optimum of the weighted fit).
"""

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from ..core.metrics import error_stats, relative_error
from ..core.model import RationalDelayModel
from .stages import Kept, StageKind, polish, polish_start, stage_record
from .start import phase_steps

__all__ = ["Candidate", "choose", "zero_delay_run", "zero_delay_floor", "NEAR",
           "SCREEN_ITERATIONS", "SCREEN_FACTOR"]

#: Candidates whose max relative error is within this factor of the lowest are compared
#: by convergence, then RMS.
NEAR = 1.10
#: The h = 0 candidate is screened: its polish is abandoned after this many iterations
#: when its RMS relative error is then still above :data:`SCREEN_FACTOR` times the max
#: relative error of the best candidate so far (it would have to fall by that factor to
#: enter :func:`choose`'s pool). A polish that is not abandoned runs on unchanged, so a
#: candidate that can win is solved exactly as without the screen.
SCREEN_ITERATIONS = 20
SCREEN_FACTOR = 10.0


@dataclass(frozen=True, eq=False)
class Candidate:
    """One fitted model a fit may keep.

    Attributes
    ----------
    name : str
        "sequential", "rational" or "<start> at h=0".
    run : tuple
        ``(param, z, lam, records)`` as the loops return them.
    max_rel_error, rms_rel_error : float
    success : bool
        The candidate's last stage converged.
    rank_max, rank_rms : float
        Max and RMS of the weighted relative error ``sqrt(w_i / mean(w)) |r_i|``: what
        :func:`choose` compares (default: the unweighted ones).
    start : str
        The start the candidate comes from, "sequential" or "rational" (default ``name``).
    """

    name: str
    run: tuple
    max_rel_error: float
    rms_rel_error: float
    success: bool
    rank_max: float = None
    rank_rms: float = None
    start: str = None

    def __post_init__(self):
        for field_, value in (("rank_max", self.max_rel_error),
                              ("rank_rms", self.rms_rel_error), ("start", self.name)):
            if getattr(self, field_) is None:
                object.__setattr__(self, field_, value)

    @classmethod
    def of(cls, name, run, data, start=None):
        """The candidate ``name`` of a loop's ``run`` on ``data``, from ``start``."""
        param, z, _, records = run
        stats = relative_error(param.to_model(z), data)
        rank = stats
        if data.weights is not None:
            rank = error_stats(np.asarray(stats.values) * _rank_factors(data.weights))
        return cls(name, run, float(stats.max), float(stats.rms),
                   bool(records[-1].success) if records else False, float(rank.max),
                   float(rank.rms), start)


def choose(candidates):
    """The kept candidate: among those within :data:`NEAR` of the lowest max relative
    error, the converged ones if any, then the lowest RMS (ties: the first given); both
    weighted when the data have weights (:attr:`Candidate.rank_max`).

    Parameters
    ----------
    candidates : list of Candidate

    Returns
    -------
    Candidate
    """
    finite = [c for c in candidates if np.isfinite(c.rank_max)] or list(candidates)
    best = min(c.rank_max for c in finite)
    pool = [c for c in finite if c.rank_max <= NEAR * best] or finite
    pool = [c for c in pool if c.success] or pool
    return min(pool, key=lambda c: (c.rank_rms, candidates.index(c)))


def zero_delay_run(ctx, run, against=None):
    """The candidate "the same fit at h = 0": the model of ``run`` with its delay removed,
    polished on all data without a delay (one stage), in ``run``'s structure (h = 0).

    Tried for every structure with a delay unless ``LoopOptions.final_stage`` is False (the
    candidate is a stage on all data): a phase-wrapped delay (e.g. 0.14 s where
    the data have none, measured in tests/test_convergence.py) is a local minimum the
    h = 0 model escapes.

    Parameters
    ----------
    ctx : mainloop.LoopContext
    run : tuple
        ``(param, z, lam, records)``.
    against : float, optional
        The lowest max relative error (weighted, :attr:`Candidate.rank_max`) of the
        candidates so far: the polish is abandoned after :data:`SCREEN_ITERATIONS`
        iterations if its RMS is still above :data:`SCREEN_FACTOR` times it. It is not
        tried when :func:`zero_delay_floor` (times ``sqrt(min(w) / mean(w))`` with weights
        ``w``: a bound of :attr:`Candidate.rank_max`) is above :data:`NEAR` times it: the
        candidate could not enter :func:`choose`'s pool, and nothing changes but the time.

    Returns
    -------
    tuple or None
        The candidate's ``(param, z, lam, records)`` (records end with a
        ``StageKind.ZERO_DELAY`` record), or None when not tried or abandoned.
    """
    param, z, _, records = run
    st, data = param.structure, ctx.data
    beta = np.array(param.to_beta(z), float)
    if not st.delay or not ctx.loop.final_stage:
        return None
    t0 = time.perf_counter()
    beta[0] = 0.0
    st0 = dataclasses.replace(st, delay=False)
    screen = None
    if against is not None and np.isfinite(against):
        if _ranked_floor(data, st0) > FLOOR_MARGIN * NEAR * against:
            return None           # no model without the delay can enter choose()'s pool
        screen = (SCREEN_ITERATIONS, SCREEN_FACTOR * float(against))
    pol = polish(RationalDelayModel(st0, beta), data, method=ctx.solve.solver, loop=ctx.loop,
                 delay_max=ctx.delay_max, zeta_min=ctx.zeta_min, max_iter=ctx.final_max_iter,
                 abandon=screen)
    if (pol.result.extra or {}).get("abandoned"):
        return None
    model = RationalDelayModel(st, pol.model.beta)
    p1, z1 = polish_start(model, data, loop=ctx.loop, delay_max=ctx.delay_max,
                          zeta_min=ctx.zeta_min)
    rec = stage_record(st.n_sections + 1, p1, z1, data, data.n_points, math.nan, pol.result,
                       pol.result.nit, pol.result.nfev, time.perf_counter() - t0,
                       Kept(pol.kept), StageKind.ZERO_DELAY)
    return p1, z1, np.zeros_like(z1), list(records) + [rec]


#: :func:`zero_delay_run` skips a candidate whose :func:`zero_delay_floor` exceeds
#: :data:`NEAR` times the best candidate's max relative error by this factor (the floor
#: is exact; the margin keeps rounding out of the decision).
FLOOR_MARGIN = 1.001


def _ranked_floor(data, structure):
    """:func:`zero_delay_floor` as a bound of :attr:`Candidate.rank_max`: the weighted error
    ``sqrt(w_i / mean(w)) |r_i|`` at the frequency that holds the error is at least the
    floor times the smallest of those factors."""
    floor = zero_delay_floor(data, structure)
    if data.weights is None or floor == 0.0:
        return floor
    with np.errstate(all="ignore"):
        least = float(np.min(_rank_factors(data.weights)))
    return floor * least if least > 0 else 0.0      # (nan when every weight is 0: no floor)


def _rank_factors(weights):
    """``sqrt(w_i / mean(w))``: the factors of the weighted relative error
    (:attr:`Candidate.rank_max`)."""
    w = np.asarray(weights, float)
    return np.sqrt(w / np.mean(w))


def zero_delay_floor(data, structure):
    """A lower bound of the max relative error of every model of ``structure`` without a
    delay on ``data``, from the phase alone: the sections cannot follow a phase lag much
    longer than their own (the rational part of a delayed system's data at h = 0).

    Each second-order section's poles change its phase monotonically by less than pi over
    the band, its zeros by less than pi (either way with ``zeros="free"``); a first-order
    section's by less than pi / 2; the gain's sign and the poles at the origin add a
    constant. A model whose phase is within ``psi`` of the data's at every frequency
    (``|G / Phi - 1| < sin psi`` everywhere needs that) must follow the data's lag ``L``
    (the sum of the steps ``-angle(Phi[i+1] conj Phi[i])``,
    :func:`~freqid_casadi.fitting.start.phase_steps`) up to ``2 psi``, less what a
    turn of the phase between two frequencies can skip: a step of the data's lag ``d``
    skipped costs at least ``2 pi - 2 psi - d`` of the zeros' rise and gains at most
    ``2 psi + d`` (the largest steps first, as long as the rise lasts). So when ``L - 2
    psi`` exceeds the poles' fall plus those gains, some frequency has an error of at
    least ``sin psi``; the floor is the largest such ``sin psi`` (bisection in ``psi``;
    a lead is the mirror image). No assumption on the frequency spacing or the noise:
    sparse or noisy data only give a lower floor.

    Parameters
    ----------
    data : FrequencyData
        M >= 2 frequencies.
    structure : Structure
        Its sections, basis and zeros (delay and poles at the origin are not used).

    Returns
    -------
    float
        In [0, 1]: 0 when the phase says nothing.
    """
    resp = np.asarray(data.response)
    if resp.size < 2:
        return 0.0
    step = phase_steps(resp)
    if not np.all(np.isfinite(step)):
        return 0.0
    unit = np.pi if structure.basis == "second-order" else 0.5 * np.pi
    lag = -float(np.sum(step))
    fall = unit * structure.n_sections * (2 if structure.zeros == "free" else 1)
    rise = unit * structure.n_sections
    if lag < 0:                                    # a lead: zeros and poles swap roles
        lag, step = -lag, -step
        fall, rise = rise, fall
    d = np.sort(-step)[::-1]                       # the data's lag steps, largest first
    # a step skipped costs the least at psi = pi / 2: the steps the rise can pay for
    # there are all any psi can use (at 200 000 points, the bisection on all steps cost
    # 90 ms a call)
    d = d[:int(np.searchsorted(np.cumsum(np.maximum(0.0, np.pi - d)), rise, "right")) + 1]

    def beyond(psi):
        """Whether no model follows the lag within psi at every frequency."""
        cost = np.cumsum(np.maximum(0.0, 2 * np.pi - 2 * psi - d))
        gain = np.concatenate([[0.0], np.cumsum(2 * psi + d)[cost <= rise]])
        return lag - 2 * psi > fall + float(np.max(gain))

    lo, hi = 0.0, 0.5 * np.pi
    if not beyond(lo):
        return 0.0
    if beyond(hi):
        return 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if beyond(mid) else (lo, mid)
    return float(np.sin(lo))
