"""One more candidate for a fit that did not converge: roots far above the band moved to
infinity, their phase into the delay (layer L4).

When the data's own delay is exact and a factor of the model has no root in the band (a
numerator that is a constant: a mode without zeros), the fit can end in a valley where a
root pair far above the band stands in for part of the delay: below its natural frequency
``wn`` a factor ``a s^2 + 2 zeta wn s + wn^2`` is ``wn^2 (1 + (2 zeta / wn) s + ...)``, a
phase lead of ``(2 zeta / wn) omega``, and a delay larger by ``2 zeta / wn`` cancels it. The
optimum is the root at infinity (the factor's ``a`` and ``zeta`` on their bound 0) with the
exact delay, and the solver creeps towards it along the valley. Measured (a user's exact
two-mode file, 300 points to 30 Hz, 2 ms; tests/test_far_roots.py): the sequential loop ends at
IPOPT's limit, max relative error 9.3e-10, a zero pair at 1.1e5 rad/s (580 times the top
frequency) and the delay 2.013 ms; moved to infinity with the delay 2.000 ms the error is
1.5e-9 and one polish converges at 3.8e-14.

:func:`far_root_run` does that for a candidate whose last stage did not converge: every
factor whose natural frequency exceeds :data:`FAR` times the highest data frequency is
replaced by its value at s = 0 (:func:`roots_to_infinity`), its first-order phase moved
into the delay, and the model is polished on all data; :func:`~.candidates.choose` keeps
it only when it is better.
"""

import math

import numpy as np

from ..core.model import RationalDelayModel
from .stages import StageKind

__all__ = ["roots_to_infinity", "far_root_run", "FAR"]

#: A factor's roots count as far above the band beyond this multiple of the highest data
#: frequency (their phase there is then within 1/FAR of a pure delay's).
FAR = 10.0


def _natural_frequency(a, zeta, omega):
    """Natural frequency (rad/s) of the roots of ``a s^2 + 2 zeta omega s + omega^2``
    (the real root ``omega / (2 zeta)`` when ``a = 0``; inf without a root)."""
    if a > 0:
        return omega / math.sqrt(a)
    return omega / (2.0 * zeta) if zeta > 0 else math.inf


def roots_to_infinity(model, omega_max, far=FAR):
    """``model`` with its factors' roots beyond ``far * omega_max`` moved to infinity.

    A second-order factor ``a s^2 + 2 zeta omega s + omega^2`` becomes ``omega^2`` (its
    value at s = 0, so the gain is kept); its phase lead ``2 zeta / omega`` (s) is taken
    off the delay for a numerator (a lead the delay had cancelled) and added for a
    denominator, the delay staying >= 0. Only second-order bases with a delay are changed.

    Parameters
    ----------
    model : RationalDelayModel
    omega_max : float
        Highest data frequency, rad/s.
    far : float
        Multiple of ``omega_max`` beyond which a root is moved.

    Returns
    -------
    (RationalDelayModel, int)
        The model and the number of factors moved (0: ``model`` itself).
    """
    st = model.structure
    if st.basis != "second-order" or not st.delay or not model.n_sections:
        return model, 0
    beta = np.array(model.beta, float)
    h, moved = float(beta[0]), 0
    for k in range(model.n_sections):
        for j, sign in ((0, -1.0), (3, 1.0)):          # numerator lead, denominator lag
            i = 2 + 6 * k + j
            a, zeta, omega = beta[i: i + 3]
            if omega > 0 and _natural_frequency(a, zeta, omega) > far * omega_max:
                h += sign * 2.0 * zeta / omega
                beta[i] = beta[i + 1] = 0.0
                moved += 1
    if not moved:
        return model, 0
    beta[0] = max(h, 0.0)
    return RationalDelayModel(st, beta), moved


def far_root_run(ctx, run):
    """The candidate "roots far above the band at infinity" of an unconverged run.

    Tried when ``run``'s last stage did not converge, ``LoopOptions.far_roots`` and
    ``final_stage`` are on and :func:`roots_to_infinity` moves at least one factor.

    Parameters
    ----------
    ctx : mainloop.LoopContext
    run : tuple
        ``(param, z, lam, records)``.

    Returns
    -------
    tuple or None
        ``(param, z, lam, records)``: ``run``'s records followed by a
        ``StageKind.FAR_ROOTS`` record (the polish); None when not tried.
    """
    param, z, _, records = run
    loop, data = ctx.loop, ctx.data
    if not loop.final_stage or not loop.far_roots or not records or records[-1].success:
        return None
    model, moved = roots_to_infinity(param.to_model(z), float(data.omega[-1]))
    if not moved:
        return None
    from .mainloop import polish_record

    pol, rec = polish_record(ctx, model, StageKind.FAR_ROOTS)
    return pol.param, pol.x, pol.lam_x, list(records) + [rec]
