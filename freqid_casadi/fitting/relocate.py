"""Relocation of all sections by one vector fit at the current delay (layer L4).

The sequential loop's ``init="relocate"`` (:func:`~freqid_casadi.fitting.mainloop.sequential`):
after the new section is placed as with "peak", a second candidate start is the vector fit
(:func:`freqid_casadi.baselines.vector_fitting`, relative weighting, stable poles) of the
stage's window with the integrator and the *current* delay removed, with as many poles as
the stage has (two per second-order section), its right-half-plane zeros reflected and its
roots paired into sections (:func:`freqid_casadi.fitting.start.sections_from_roots`, as the
rational start does at each trial delay). The stage starts from whichever of the two has
the lower stage cost.

Why: from about the ninth section on (example A) the stage NLPs creep along a curved valley
whose cause is the configuration of all sections, not the new one: a one-section fit of
the residual ``Phi/G_prev`` with the old sections fixed explains only ~10 % of it and,
measured, leaves the iterations unchanged. The linear relocation moves every pole at once.
"""

import numpy as np

from ..core.model import times_jw_power
from ..errors import StructureError

__all__ = ["relocated_start", "STALL_RULE", "VF_ITERATIONS"]

#: Pole-relocation iterations of the vector fit.
VF_ITERATIONS = 10
#: ``(window, ftol)`` of the stall rule of the section stages with init="relocate": a
#: stage ends when its cost fell by less than 5 % over 5 IPOPT iterations. Without the
#: relocation this rule trades accuracy for iterations (example C: max rel. error 4.9e-3);
#: with it the next stage's vector fit restarts every section, and the last (all-data)
#: stage runs without it.
STALL_RULE = (5, 0.05)


def _references(model, omega_min):
    """Each section's reference frequency (rad/s): its denominator's natural frequency
    (second order: ``wd / sqrt(b)``; first order: ``b0 / b1``), else ``omega_min``."""
    refs = []
    for row in model.sections():
        if model.structure.basis == "second-order":
            w = row[5] / np.sqrt(row[3]) if row[3] > 0 else row[5]
        else:
            w = row[3] / row[2] if row[2] > 0 else np.nan
        refs.append(float(w) if np.isfinite(w) and w > 0 else float(omega_min))
    return tuple(refs)


def relocated_start(param, wdata, z_start, zeta_min=None):
    """The vector-fit candidate start of a stage, or None if it is not better.

    Parameters
    ----------
    param : Parametrization
        The stage's parametrization (new section included).
    wdata : FrequencyData
        The stage's window.
    z_start : ndarray of float, shape (param.n_vars,)
        The stage's start with the new section placed ("peak").
    zeta_min : float, optional
        Damping floor: the vector fit is projected onto it before the costs are compared.

    Returns
    -------
    (Parametrization, ndarray of float) or None
        The relocated start: a parametrization like ``param`` whose sections' reference
        frequencies are the relocated sections' (so the variables stay about 1) and the
        variables there (within the bounds, on the damping floor), when its stage cost is
        lower than that of ``z_start``; None otherwise or when the vector fit fails.
    """
    from ..baselines import vector_fitting
    from ..core.objective import Parametrization
    from .stages import stage_cost
    from .start import _start_at

    st = param.structure
    n_poles = st.n_sections * (2 if st.basis == "second-order" else 1)
    if n_poles == 0 or wdata.n_points < 2 * n_poles + 2:
        return None
    h = float(param.to_beta(z_start)[0])
    base = times_jw_power(wdata.response, wdata.omega, st.origin_order)
    try:
        model = _start_at(vector_fitting, wdata, st, base, h, n_poles, VF_ITERATIONS,
                          1e-6 * wdata.omega[0])[0]
        if model is None:
            return None
        refs = _references(model, wdata.omega[0]) if param.scaled else param.omega_ref
        new = Parametrization(st, param.gauge, refs, param.gain_ref, param.delay_max,
                              param.scaled)
        z = new.from_beta(np.asarray(model.beta, float))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, StructureError):
        return None                      # StructureError: a root at s = 0 (dc gauge)
    lb, ub = new.bounds()
    z = np.clip(z, lb, ub)
    if not np.all(np.isfinite(z)):
        return None
    if zeta_min is not None:
        z = new.project_damping(z, zeta_min)
    cost = stage_cost(new, wdata, z)
    better = np.isfinite(cost) and cost < stage_cost(param, wdata, z_start)
    return (new, z) if better else None
