"""One more candidate for a fit that did not converge: the rational start at nearby delays
(layer L4).

A fit of a delayed system can end in a valley where sections above the band stand in for
part of the delay (measured on example C, tests/test_relocate.py: both starts end at
about 0.0260 s against the system's 0.02625 s and creep there for thousands of
iterations). Vector fitting at a *fixed* trial delay tells the delays apart: its max
relative error on C is 3.5e-6 at 0.0260 s, 1.3e-4 at 0.0261 s and 1.1e-8 at 0.0262 s
(erratic in the delay, so a search must probe rather than follow a slope). For a candidate
whose last stage did not converge, :func:`delay_search_run` probes the vector fit at
delays around the candidate's own (and, for a run of the sequential loop alone, tries the
rational start of the whole fit, whose delay updates and group-delay search reach delays
turns of the phase away), polishes the best trial on all data (one stage, as
``start="rational"``) and offers the result as one more candidate to
:func:`~freqid_casadi.fitting.candidates.choose`, which keeps it only when it is better: a fit
that converged is never touched, and the search can never make a fit worse.
"""

import time

import numpy as np

from .stages import StageKind
from .start import MAX_TRIALS, PROBE_PHASE, search_delay

__all__ = ["search_delay", "delay_search_run", "PROBE_PHASE", "MAX_TRIALS"]

def delay_search_run(ctx, run, with_rational_start=False):
    """The candidate "the rational start at the best nearby delay" of an unconverged run.

    Tried when ``run``'s last stage did not converge, its structure has a delay and
    ``LoopOptions.delay_search`` and ``final_stage`` are on. The vector fit
    (:func:`~freqid_casadi.fitting.start.rational_start` at one fixed delay per trial) is probed
    around ``run``'s delay in steps of :data:`PROBE_PHASE` rad of phase at the highest
    frequency (:func:`search_delay`); the trial with the lowest max relative error is
    polished on all data by one stage (:func:`~freqid_casadi.fitting.stages.polish`).

    Parameters
    ----------
    ctx : mainloop.LoopContext
    run : tuple
        ``(param, z, lam, records)``.
    with_rational_start : bool
        Also try the rational start of the whole fit (:func:`~freqid_casadi.fitting.start.
        rational_start` from h = 0, as ``start="rational"`` makes it): for a run of the
        sequential loop alone (``start="sequential"``), whose delay may have settled turns
        of the phase away from the data's. The other starts have that start as a
        candidate of their own already.

    Returns
    -------
    tuple or None
        ``(param, z, lam, records)``: ``run``'s records followed by a
        ``StageKind.RATIONAL_START`` record (the probes) and a ``StageKind.DELAY_SEARCH``
        record (the polish); None when not tried or when no trial was usable.
    """
    from .mainloop import polish_record, start_record
    from .start import RationalStartError, rational_start

    param, z, _, records = run
    st, data, loop = param.structure, ctx.data, ctx.loop
    if (not st.delay or not loop.final_stage or not loop.delay_search
            or not records or records[-1].success):
        return None
    t0 = time.perf_counter()
    starts = {}

    def trial(h):
        try:
            rs = rational_start(data, st, delay_max=ctx.delay_max, delay0=h,
                                max_delay_updates=1)
        except RationalStartError:
            return np.inf
        starts[h] = rs
        return rs.max_rel_error

    h0 = float(param.to_model(z).delay)
    seen = search_delay(trial, h0, PROBE_PHASE / float(data.omega[-1]), ctx.delay_max)
    if with_rational_start:
        # the run's valley may lie turns of the phase from the data's delay, where no probe
        # near it reaches (example C with numpy's AVX2 functions: the sequential loop's
        # first section took 0.10 s for 0.026 s and the run ended at max rel. error 1.18);
        # the rational start as start="rational" makes it (its delay updates from h = 0,
        # and its search around the data's group delay) is one more trial
        try:
            rs = rational_start(data, st, delay_max=ctx.delay_max)
        except RationalStartError:
            rs = None
        if rs is not None and rs.delay not in starts:
            starts[rs.delay] = rs
            seen[rs.delay] = rs.max_rel_error
    if not starts:
        return None
    best = starts[min(starts, key=lambda h: starts[h].max_rel_error)]
    stage = st.n_sections + 1
    probes = start_record(ctx, best.model, stage, len(seen), "delay search", t0)
    ctx.callback(probes)
    pol, rec = polish_record(ctx, best.model, StageKind.DELAY_SEARCH)
    return pol.param, pol.x, pol.lam_x, list(records) + [probes, rec]
