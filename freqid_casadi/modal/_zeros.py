"""A shared fit whose minimum-phase channels the data do not allow: the fit with free zeros
offered in its message (layer L5).

A modal test drives a structure at one point and measures several: the driving point's
FRF (collocated) is minimum phase, the others mostly are not (a mode whose modal constant
changes sign between two modes leaves no zero between them on the axis, and
right-half-plane zeros appear). A minimum-phase model of such a channel cannot follow its
phase: the fit ends poor (or does not converge), and the shared poles it keeps are pulled
away from the modes. Measured on 4 sensors of a 3-mode structure (0.5 % noise; the
gallery's ``plot_42_modal_mat_zeros``): minimum phase, the first mode at 10.009 Hz and
2.37 % damping for 10 Hz and 2.00 %, worst channel RMS 0.72; with free zeros 10.000 Hz,
2.000 %, RMS 0.0071 (the noise), in a tenth of the time. ``python
scripts/modal_zeros.py`` measures it on random modal tests
(results/modal-zeros).

:func:`offer_free_zeros` fits such a result again with free zeros in every channel and,
when that fit explains the data (status "ok") or halves the worst channel's RMS error,
says so in the result's message with the channels whose models then have
right-half-plane zeros, and the option that gives it.
"""

import dataclasses

import numpy as np

from ..fitting.verdict import FitStatus

__all__ = ["offer_free_zeros", "turns_phase", "FREE_GAIN", "RHP_TURN"]

#: The free-zeros fit is offered when its worst channel's RMS error is at most this
#: fraction of the fit's (or its status is "ok" where the fit's is not).
FREE_GAIN = 0.5


def _channels(res, chans):
    """``"channels 1 (H(:,2)), 3 (H(:,4))"``: 0-based indices, with the data's names when
    they tell the channels apart."""
    names = [d.name for d in res.datas]
    shown = [str(c) for c in chans]
    if all(names) and len(set(names)) == len(names):
        shown = [f"{c} ({names[c]})" for c in chans]
    return f"channel{'s' if len(chans) > 1 else ''} {', '.join(shown)}"


#: A model's right-half-plane zeros count when their all-pass factor, ``prod (1 - s/z) /
#: (1 + s/conj(z))``, leaves 1 by more than this somewhere in the band (0.5: a phase turn
#: of 29 degrees): one far beyond the band, the trace of a numerator's vanishing leading
#: coefficient, barely turns the phase there.
RHP_TURN = 0.5


def turns_phase(model, omega):
    """Whether ``model``'s right-half-plane zeros turn its phase in the band by more than
    :data:`RHP_TURN` (as ``|A(j omega) - 1|``, ``A`` their all-pass factor).

    Parameters
    ----------
    model : RationalDelayModel
    omega : ndarray of float, shape (M,)
        The band, rad/s.

    Returns
    -------
    bool
    """
    z = model.zeros()
    z = z[np.isfinite(z) & (z.real > 0)]
    if z.size == 0:
        return False
    s = 1j * np.asarray(omega, float)[:, None]
    allpass = np.prod((1.0 - s / z) / (1.0 + s / np.conj(z)), axis=1)
    return bool(np.max(np.abs(allpass - 1.0)) > RHP_TURN)


def offer_free_zeros(res, fit):
    """``res`` with the fit of free zeros offered in its message when it is better.

    Parameters
    ----------
    res : SharedFitResult
        A fit with some channels minimum phase.
    fit : callable
        ``zeros -> SharedFitResult``: the same fit with other zeros (every other option
        bound).

    Returns
    -------
    SharedFitResult
        ``res`` itself when its status is "ok", every channel is already free, or the
        free-zeros fit is not better (see :data:`FREE_GAIN`); else ``res`` with
        ``details["free_zeros"]`` (``status``, ``rms_rel_errors``, ``max_rel_errors`` of
        that fit, ``non_minimum_phase``: its channels whose models have right-half-plane
        zeros that turn the phase in the band, :func:`turns_phase`) and a message that
        ends with them and the option ``zeros='free'``; the order advice of a poor fit is
        dropped when the free-zeros fit is "ok" (the zeros, not the order, were the
        cause).
    """
    if res.status == FitStatus.OK or all(z == "free" for z in res.zeros):
        return res
    other = fit(["free"] * res.n_channels)
    worst, other_worst = np.max(res.rms_rel_errors), np.max(other.rms_rel_errors)
    ok = other.status == FitStatus.OK
    if not (ok or other_worst <= FREE_GAIN * worst):
        return res
    rhp = [c for c, (m, d) in enumerate(zip(other.models, other.datas))
           if turns_phase(m, d.omega)]
    head = res.message.split(" — pass n_sections=", 1)[0] if ok else res.message
    why = (f" ({_channels(other, rhp)} then with right-half-plane zeros, as a "
           "non-collocated sensor's)" if rhp else "")
    msg = (f"{head} — with free zeros the same fit reaches worst-channel RMS "
           f"{other_worst:.3g} against {worst:.3g}, status {other.status}{why}: pass "
           "zeros='free' (freqid modal --zeros free)")
    details = dict(res.details, free_zeros={
        "status": str(other.status), "rms_rel_errors": other.rms_rel_errors.tolist(),
        "max_rel_errors": other.max_rel_errors.tolist(), "non_minimum_phase": rhp})
    return dataclasses.replace(res, message=msg, details=details)
