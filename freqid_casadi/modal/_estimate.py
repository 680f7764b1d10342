"""The linear estimate of one order of a stabilization survey (layer L6).

A stabilization diagram in modal practice is drawn from a cheap linear estimator at every
order (LSCF/PolyMAX, or vector fitting), the costly polish kept for the modes selected.
Here the estimator is the first step of :func:`~freqid_casadi.modal.shared.fit_shared`'s
rational start: vector fitting with one pole set common to all channels
(:func:`freqid_casadi.baselines.vectfit`, started at the resonance peaks the channels share,
:func:`~freqid_casadi.modal._start.peak_poles`, poles flipped to the left half plane, rows
weighted by ``1/|Phi|``). Its poles at an order are exactly the poles that
``fit_shared(..., start="rational")`` starts its IPOPT polish from at that order.

:func:`estimate_order` is a plain numpy function of arrays, so that the orders of a survey
can run in worker processes (:func:`run_orders`).
"""

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..baselines import vectfit
from ..core.modes import Mode, Modes
from .._threads import single_threaded_blas
from .._workers import local_map
from ._start import peak_poles

__all__ = ["OrderEstimate", "estimate_order", "run_orders"]


@dataclass(frozen=True, eq=False)
class OrderEstimate:
    """The shared-pole vector fitting of one order of
    :func:`~freqid_casadi.modal.survey.stabilization` (``estimator="rational"``): what the
    diagram shows at that order. It has the fields of
    :class:`~freqid_casadi.modal.shared.SharedFitResult` that a survey reads (``poles``,
    ``modes``, the errors, ``success``, ``status``, ``message``, ``wall_time``, ``nit``,
    ``options``) but no models: the model of the selected modes is
    :attr:`StabilizationResult.polished <freqid_casadi.modal.survey.StabilizationResult>`.

    Attributes
    ----------
    order : int
        Number of shared poles (2 x sections).
    poles : ndarray of complex, shape (order,)
        The common poles, rad/s, closed left half plane, by increasing |p|.
    modes : Modes
        The underdamped poles (``Im p > 0``) with every channel's residue (least squares at
        the poles, the LSFD step; divided by ``p`` with ``integrator``), by frequency.
    constants : ndarray of float, shape (C,)
        Each channel's constant term (the upper residual; 0 with ``channel_sections``).
    max_rel_errors, rms_rel_errors : ndarray of float, shape (C,)
        ``|Phi_c / G_c - 1|`` of the pole-residue fit ``G_c`` (no delay), largest and RMS
        over the points.
    wall_time : float
        s.
    nit : int
        Vector-fitting iterations.
    success : bool
        Always True: a linear estimate has no convergence to fail (kept so that code
        reading a survey's ``fits`` works on both kinds).
    status : str
        "estimate".
    message : str
        One sentence: the estimator and its errors.
    options : dict
        ``n_sections``, ``n_iter``, ``constant``, ``integrator``.
    """

    order: int
    poles: np.ndarray
    modes: Modes
    constants: np.ndarray
    max_rel_errors: np.ndarray
    rms_rel_errors: np.ndarray
    wall_time: float
    nit: int
    success: bool = True
    status: str = "estimate"
    message: str = ""
    options: dict = field(default_factory=dict)

    def summary(self):
        """One line: order, modes, worst max/RMS relative error, time."""
        return (f"order {self.order}: shared-pole vector fitting, {len(self.modes)} modes, "
                f"max rel. error {np.max(self.max_rel_errors):.4g} (worst channel), RMS "
                f"{np.max(self.rms_rel_errors):.4g}, {self.wall_time:.2f} s")


def estimate_order(omega, phi, wts, n_sections, n_iter=10, constant=True, integrator=False):
    """The shared-pole vector fitting of one order.

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s, strictly increasing.
    phi : ndarray of complex, shape (C, M)
        The rational part of the channels (times ``j omega`` with an integrator), as
        ``fit_shared``'s rational start fits it.
    wts : ndarray of float, shape (C, M)
        Squared-residual weights (``fit_shared``'s normalised weights).
    n_sections : int
        N: 2N poles.
    n_iter : int
        Pole-relocation iterations (``VectorFittingOptions.n_iter``).
    constant : bool
        A constant per channel (``fit_shared`` fits one unless the channels have sections
        of their own).
    integrator : bool
        The data were multiplied by ``j omega``: each residue is divided by its pole.

    Returns
    -------
    OrderEstimate
    """
    t0 = time.perf_counter()
    n = 2 * int(n_sections)
    with single_threaded_blas():
        fit = vectfit(omega, phi, n, weights=wts, n_iter=n_iter,
                      initial=peak_poles(omega, phi, n, wts), constant=constant,
                      stable=True)
        with np.errstate(all="ignore"):
            rel = np.abs(phi / fit.response(omega) - 1.0)
    rel = np.where(np.isfinite(rel), rel, np.inf)
    order = np.argsort(np.abs(fit.poles), kind="stable")
    poles, residues = fit.poles[order], fit.residues[:, order]
    modes = []
    for k in np.flatnonzero(poles.imag > 0):
        p = complex(poles[k])
        r = residues[:, k] / p if integrator else residues[:, k]
        modes.append(Mode(omega_n=float(abs(p)), frequency_hz=float(abs(p) / (2 * np.pi)),
                          zeta=float(-p.real / abs(p)), residues=tuple(complex(v) for v in r),
                          pole=p))
    max_err = np.max(rel, axis=1)
    rms = np.sqrt(np.mean(rel ** 2, axis=1))
    return OrderEstimate(
        order=n, poles=poles, modes=Modes(sorted(modes, key=lambda m: m.omega_n)),
        constants=np.asarray(fit.constants, float), max_rel_errors=max_err,
        rms_rel_errors=rms, wall_time=time.perf_counter() - t0, nit=int(n_iter),
        message=(f"estimate: shared-pole vector fitting ({n_iter} iterations); worst "
                 f"channel max rel. error {np.max(max_err):.3g}, RMS {np.max(rms):.3g}"),
        options={"n_sections": int(n_sections), "n_iter": int(n_iter),
                 "constant": bool(constant), "integrator": bool(integrator)})


def _held(task, args):
    """``(task(*args), [(category, message), ...])``: the warnings a worker process raised,
    for the caller to re-issue in its own process."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = task(*args)
    said = [(w.category, str(w.message)) for w in caught]
    return out, list(dict.fromkeys(said))


def run_orders(task, arguments, n_jobs):
    """``task(*args)`` for each ``args`` of ``arguments``, yielded in their order: in this
    process for ``n_jobs=1`` (each as it is done), else in ``n_jobs`` worker processes
    (forked where :func:`~freqid_casadi._workers.can_fork`, else joblib's loky backend; one
    BLAS thread each, as
    :func:`~freqid_casadi.fitting.batch.fit_many`; the last, costliest tasks handed out
    first, all yielded once all are done), the workers' warnings re-issued here. Each task
    runs with single-threaded BLAS in either case, so the results do not depend on
    ``n_jobs``.

    Parameters
    ----------
    task : callable
        A module-level function (picklable).
    arguments : list of tuple
    n_jobs : int
        >= 1.
    """
    if n_jobs == 1 or len(arguments) <= 1:
        for args in arguments:
            yield task(*args)
        return
    # the largest orders cost most: hand them out first, yield in the caller's order
    first = sorted(range(len(arguments)), key=lambda i: -i)
    results = dict(zip(first, list(local_map(_held, [(task, arguments[i]) for i in first],
                                             n_jobs))))
    for i in range(len(arguments)):
        out, said = results[i]
        for category, message in said:
            warnings.warn(message, category, stacklevel=3)
        yield out
