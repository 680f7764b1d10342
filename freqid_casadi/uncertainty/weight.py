"""A multiplicative uncertainty weight W(s) bounding a relative-error curve (layer L4).

Given the relative error of a fitted model, ``e_i = |Phi_i / G_N(j w_i) - 1|``
(``FitResult.rel_error``), the true plant lies in the multiplicative set
``G = G_N (1 + W Delta)``, ``|Delta| <= 1``, at the measured frequencies whenever
``|W(j w_i)| >= e_i``. :func:`fit_uncertainty_weight` finds a low-order, stable and
minimum-phase ``W`` with that property at *every* data point, as tight as possible, for use
as the uncertainty weight in ``control.mixsyn`` / ``control.hinfsyn``.

Weight structure
----------------
``W(s) = k * prod_j S_j(s)`` with ``order // 2`` second-order sections and, for an odd order,
one first-order section, each normalised to unit DC gain::

    S_j(s) = (1 + 2 zn s/wn + (s/wn)^2) / (1 + 2 zd s/wd + (s/wd)^2)     (second order)
    S_j(s) = (1 + s/wn) / (1 + s/wd)                                      (first order)

Every section is biproper, so ``W`` is proper with ``W(inf)`` finite. The corner frequencies
``wn, wd > 0`` and dampings ``zn, zd >= min_damping > 0`` put every pole and zero strictly in
the open left half plane (a monic quadratic with positive coefficients is Hurwitz), so these
simple bounds are the whole stability / minimum-phase constraint (as ``beta >= 0`` in
:mod:`freqid_casadi.core.model`).

The NLP (solved by IPOPT through CasADi)
----------------------------------------
Variables, scaled to about 1 (docs/style.md §8)::

    kappa = ln(k / k_ref),  k_ref = (1 + margin) max_i e_i
    d     = log10(w / w_c),  w_c = sqrt(w_1 w_M)       for every corner frequency
    zeta                                                for every damping

with the bounds (``lbx``/``ubx``) ``d in [log10(w_1/100/w_c), log10(100 w_M/w_c)]`` (corners
beyond two decades outside the data have no effect on it) and
``zeta in [min_damping, MAX_DAMPING]``. With ``L_i = ln|W(j w_i)|`` (built from (re, im)
pairs, docs/style.md §1.2) and ``b_i = ln((1 + margin) e_i)``::

    minimise    (1/M) sum_i (L_i - b_i)                 mean overbound in nepers
    subject to  g_i = 2 (L_i - b_i) >= 0,  i = 1..M     |W| >= (1 + margin) e_i

The objective is linear in ``ln|W|``: the mean log-ratio (an L1 fit from above), which
weights every point equally, i.e. equally per decade on a log-spaced grid, and is not
dominated by the few points where ``W`` must lie far above ``e`` (dips of ``e``, zeros).

Starts. The orders ``1..order`` are solved in turn, each from up to five starts whose gain
is raised to feasibility (``W = k_ref`` alone, order 0, is feasible and is the closed-form
order-0 answer):

* *fresh*: the data range is cut into ``n`` stretches of equal total variation of the
  smoothed ``ln e``; each section is centred on its stretch with the stretch's net rise of
  ``e`` as its high/low-frequency gain ratio (identity sections for a flat ``e``);
* *ladder*: each of the two best weights of the order below (distinct objectives) plus one
  real pole/zero pair (appended as a first-order section, or merged with the first-order
  section into a second-order one), at each of the two lowest local minima, off the
  cancelling diagonal ``z = p``, of the objective on a numpy grid (3 points per decade over
  the corner bounds); if IPOPT ends above a ladder start, the start is kept.

The best weight of the order below with a cancelling pair is a candidate too (not solved),
so the objective, and the mean overbound in dB, does not increase with the order (up to
rounding); the best candidate by the objective is returned. The NLP has many local minima;
several ladder starts and IPOPT's monotone barrier update make short solves from near a
minimum decide, not long ones whose end point moves with rounding (the BLAS kernel).

Verification. IPOPT's constraint tolerance can leave ``|W(j w_i)|`` a hair below
``(1 + margin) e_i``. After the solve the bound is checked in numpy at every point and, if
violated, ``k`` is multiplied by the largest ratio (``WeightResult.gain_correction``), so the
returned weight satisfies ``|W(j w_i)| >= (1 + margin) e_i`` exactly in floating point.

Zeros in ``e`` are floored at ``1e-16 max e`` before taking logs; floored points still count
in the objective but are excluded from :class:`Overbound` (their ratio is meaningless).

Implementation note: docs/style.md §2 reserves ``nlpsol`` for ``solvers/ipopt.py``; the small
constrained NLP here is built in :func:`_solve` and run by
:func:`~freqid_casadi.solvers.ipopt.run_nlpsol`, the wrapper every IPOPT solve goes through
(status, projection onto the bounds, evaluation errors).

Plotting (not in this module; see :mod:`freqid_casadi.plots`): on log-log axes, the
data ``e_i`` (markers) and ``(1 + margin) e_i``, ``|W(j w)|`` on a dense grid spanning the
data and a decade beyond (``WeightResult.frequency_response``), the pole and zero corner
frequencies as vertical lines, and in a second panel the overbound ``20 log10(|W|/e)`` dB at
the data points (never below ``20 log10(1 + margin)``).
"""

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import _cplx
from ..core.model import balanced_ss
from .._progress import channel, check_progress
from ..errors import DataError, OptionError
from ..options import IpoptOptions, ipopt_limits, warn_renamed
from ..solvers.common import SUCCESS_STATUSES, TERMINATION_MESSAGES, Status
from ..solvers.ipopt import run_nlpsol
from ._weight_sections import MAX_DAMPING, WeightSection, _factor, _real_pair_section, \
    _response, _section_log_abs2

__all__ = ["WEIGHT_METHOD", "fit_uncertainty_weight", "weights_by_order", "iter_weights",
           "WeightResult", "WeightSection", "Overbound", "MAX_DAMPING", "CORNER_DECADES",
           "E_FLOOR",
           "MAX_DECADES", "frequency_scale", "rescaled"]


CORNER_DECADES = 2.0
"""Corner frequencies are bounded to the data range widened by this many decades each side."""

E_FLOOR = 1e-16
"""Relative floor of ``e`` before logs: ``e_i >= E_FLOOR * max(e)``."""

MAX_DECADES = 100
"""Widest omega band of a weight fit, decades (``|W|`` squares the frequency)."""

_LN10 = math.log(10.0)
_GRID_PER_DECADE = 3      # ladder grid search over corner frequencies
_LADDER_POOL = 2          # weights of the order below laddered from
_LADDER_PAIRS = 2         # grid minima (added pole/zero pairs) per ladder weight


# ---------------------------------------------------------------------------- results
class Overbound(NamedTuple):
    """How far ``|W|`` lies above ``e`` at the data points, ``20 log10(|W(j w_i)| / e_i)``.

    Points where ``e`` was floored (zeros) are left out.

    Attributes
    ----------
    mean_db, max_db, min_db : float
        Mean, largest and smallest overbound in dB; ``min_db >= 20 log10(1 + margin)``.
    """

    mean_db: float
    max_db: float
    min_db: float


@dataclass(frozen=True, eq=False)
class WeightResult:
    """Result of :func:`fit_uncertainty_weight`.

    Attributes
    ----------
    omega : ndarray of float, shape (M,)
        Data frequencies, rad/s.
    rel_error : ndarray of float, shape (M,)
        The bounded relative error ``e_i`` (as given, not floored).
    magnitude : ndarray of float, shape (M,)
        ``|W(j omega_i)|``; ``>= (1 + margin) * rel_error`` at every point.
    gain : float
        ``k = W(0)`` (every section has unit DC gain), > 0.
    sections : tuple of WeightSection
        Second-order sections first, then the first-order one (odd order).
    order : int
        McMillan degree of ``W``.
    overbound : Overbound
        Mean / max / min of ``20 log10(|W|/e)`` dB over the data.
    margin : float
        The requested relative margin.
    gain_correction : float
        Factor (>= 1) by which the gain was raised after IPOPT so the bound holds exactly;
        1.0 when IPOPT's point was already feasible.
    objective : float
        Mean of ``ln|W(j w_i)| - ln((1 + margin) e_i)`` (nepers) at the returned weight.
    status : Status
        Of the IPOPT solve that produced the weight (CONVERGED for order 0, closed form).
    message : str
        One sentence: whether the solve converged, how far ``|W|`` lies above the error,
        and the next step when it did not converge.
    success : bool
        ``status`` is a success status. The bound holds even when False.
    nit : int
        IPOPT iterations summed over all solves.
    details : dict
        The optimiser's own words: ``solver_status`` (IPOPT's return status, or "closed
        form" for order 0), ``start`` ("fresh", "ladder" or "closed form") and
        ``kept_start`` (True when IPOPT ended above its start and the start was kept, and
        for the order below's weight with a cancelling pair, which then carries that
        weight's ``solver_status``).

    Notes
    -----
    To plot: ``|W(j w)|`` from :meth:`frequency_response` on a dense grid against the
    markers ``rel_error`` (log-log), plus ``20 log10(magnitude / rel_error)`` in dB.
    """

    omega: np.ndarray
    rel_error: np.ndarray
    magnitude: np.ndarray
    gain: float
    sections: tuple
    order: int
    overbound: Overbound
    margin: float
    gain_correction: float
    objective: float
    status: Status
    message: str
    success: bool
    nit: int
    details: dict = None

    def frequency_response(self, omega):
        """``W(j omega)``.

        Parameters
        ----------
        omega : array_like of float, shape (K,)
            Frequencies in rad/s.

        Returns
        -------
        ndarray of complex, shape (K,)
        """
        return _response(self.gain, self.sections, omega)

    def poles(self):
        """Poles of ``W``, complex ndarray, shape (order,)."""
        p = [r for sec in self.sections for r in sec.poles()]
        return np.array(p, dtype=complex)

    def zeros(self):
        """Zeros of ``W``, complex ndarray, shape (order,)."""
        z = [r for sec in self.sections for r in sec.zeros()]
        return np.array(z, dtype=complex)

    def is_stable(self):
        """True if every pole has a negative real part (always, by the bounds)."""
        return bool(np.all(self.poles().real < 0))

    def is_minimum_phase(self):
        """True if every zero has a negative real part (always, by the bounds)."""
        return bool(np.all(self.zeros().real < 0))

    def to_control(self):
        """``W`` as a python-control ``StateSpace`` (sections realised and put in series).

        Returns
        -------
        control.StateSpace
            Proper, stable and minimum phase, with ``order`` states; pass it as a weight to
            ``control.mixsyn`` / ``control.augw`` (``control.tf(sys)`` gives the transfer
            function).
        """
        import control as ct

        sys = ct.ss([], [], [], [[self.gain]])
        for sec in self.sections:
            sys = ct.series(sys, ct.ss(ct.tf(list(sec.num), list(sec.den))))
        return balanced_ss(sys)


# ---------------------------------------------------------------------------- scaling
def frequency_scale(omega):
    """Frequency (rad/s) to divide ``omega`` by before the fit: 1, or, far from 1 rad/s
    (where squares of omega over/underflow), the geometric mean of its ends (the problem
    is scale-free; :func:`rescaled` maps the sections back).

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s, > 0, increasing.

    Returns
    -------
    float

    Raises
    ------
    DataError
        If ``omega`` spans more than :data:`MAX_DECADES` decades.
    """
    decades = math.log10(omega[-1]) - math.log10(omega[0])
    if decades > MAX_DECADES:
        raise DataError(f"omega spans {decades:.0f} decades ({omega[0]:g} to {omega[-1]:g} "
                        f"rad/s), more than {MAX_DECADES}; fit the weight on a narrower band")
    if 1e-100 <= omega[0] and omega[-1] <= 1e100:
        return 1.0
    return math.exp(0.5 * (math.log(omega[0]) + math.log(omega[-1])))


def rescaled(sections, scale):
    """``sections`` (WeightSection) with corner frequencies multiplied by ``scale``.

    Parameters
    ----------
    sections : iterable of WeightSection
    scale : float

    Returns
    -------
    tuple of WeightSection
    """
    return tuple(dataclasses.replace(x, omega_num=x.omega_num * scale,
                                     omega_den=x.omega_den * scale) for x in sections)


# ---------------------------------------------------------------------------- validation
def _vector(x, name):
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"{name} must be an array of real numbers, got {type(x).__name__}"
                        ) from None
    if arr.ndim != 1:
        raise DataError(f"{name} must be one-dimensional, got shape {arr.shape}")
    return arr


#: The IPOPT options of the weight fit by default: at most 500 iterations per solve.
WEIGHT_METHOD = IpoptOptions(max_iter=500)


def _weight_options(function, method, max_iter, verbose):
    """The weight fit's IpoptOptions from ``method`` (its ``max_iter`` and ``ipopt`` are
    read) or the old keywords ``max_iter`` / ``verbose`` (FutureWarning each)."""
    if (max_iter is not None or verbose is not None) and method is not None:
        raise OptionError(f"{function}: max_iter/verbose and method both set the solver; "
                          "drop the old keyword and pass method=IpoptOptions(max_iter=..., "
                          "ipopt={'print_level': 5}) only")
    if max_iter is None and verbose is None:
        return ipopt_limits(function, method, WEIGHT_METHOD, ("max_iter", "ipopt"))
    if max_iter is not None and (isinstance(max_iter, bool) or not isinstance(
            max_iter, (int, np.integer)) or max_iter < 1):
        raise OptionError(f"max_iter must be an integer >= 1, got {max_iter!r}; pass "
                          "method=IpoptOptions(max_iter=500) instead")
    limit = WEIGHT_METHOD.max_iter if max_iter is None else int(max_iter)
    log = {"print_level": 5} if verbose else {}
    new = f"method=IpoptOptions(max_iter={limit}" + (f", ipopt={log})" if log else ")") + (
        "" if verbose is None else " (IPOPT's log; progress='lines' gives one line per order)")
    old = ", ".join(f"{k}={v!r}" for k, v in (("max_iter", max_iter), ("verbose", verbose))
                    if v is not None)
    warn_renamed(function, old, new, 3)
    return IpoptOptions(max_iter=limit, ipopt=log)


def _order_line(w):
    """One line of text for a :class:`WeightResult` (``progress="lines"``)."""
    return (f"order {w.order}: objective {w.objective:.4g}, overbound max {w.overbound.max_db:.3g}"
            f" dB, {w.nit} iterations, {'converged' if w.success else 'not converged'}")


def _validate(result_or_omega, rel_error, order, margin, min_damping):
    if hasattr(result_or_omega, "rel_error") and hasattr(result_or_omega, "data"):
        if rel_error is not None:
            raise DataError("pass either a FitResult or (omega, rel_error), not both")
        omega = _vector(result_or_omega.data.omega, "result.data.omega")
        e = _vector(result_or_omega.rel_error, "result.rel_error")
        e_name = "result.rel_error"
    else:
        if rel_error is None:
            raise DataError("rel_error is missing: call fit_uncertainty_weight(omega, "
                            "rel_error, ...) or fit_uncertainty_weight(fit_result, ...)")
        omega = _vector(result_or_omega, "omega")
        e = _vector(rel_error, "rel_error")
        e_name = "rel_error"
    if omega.size == 0:
        raise DataError("omega is empty: give at least one frequency point")
    if e.size != omega.size:
        raise DataError(f"omega and {e_name} must have equal lengths: len(omega)={omega.size}, "
                        f"len({e_name})={e.size}; pass one relative error per frequency")
    bad = ~np.isfinite(omega) | (omega <= 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"omega must be finite and > 0 (rad/s): omega[{i}]={omega[i]}; "
                        "drop that point")
    d = np.diff(omega)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0]) + 1
        raise DataError(f"omega must be strictly increasing: omega[{i}]={omega[i]!r} <= "
                        f"omega[{i - 1}]={omega[i - 1]!r}; sort and de-duplicate the points")
    bad = ~np.isfinite(e)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"{e_name} must be finite: {e_name}[{i}]={e[i]}; remove that point")
    bad = e < 0
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"{e_name} must be >= 0 (a modulus |Phi/G_N - 1|): "
                        f"{e_name}[{i}]={e[i]}; pass the absolute relative error")
    if not np.any(e > 0):
        raise DataError(f"{e_name} is zero at every point: there is no error to bound "
                        "(the weight would be W = 0)")
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise OptionError(f"order must be an integer >= 0, got {order!r}")
    if order < 0:
        raise OptionError(f"order must be >= 0 (0 = constant weight), got {order}")
    n_vars = 1 + 2 * int(order)
    if omega.size < n_vars:
        raise DataError(f"too few points for order {order}: {omega.size} points for "
                        f"{n_vars} parameters; use order <= {(omega.size - 1) // 2}")
    if (isinstance(margin, bool) or not isinstance(margin, (int, float, np.floating))
            or not math.isfinite(margin) or margin < 0):
        raise OptionError(f"margin must be a finite number >= 0 (relative, 0.1 = 10%), "
                          f"got {margin!r}")
    if (isinstance(min_damping, bool) or not isinstance(min_damping, (int, float, np.floating))
            or not (0 < min_damping < MAX_DAMPING)):
        raise OptionError(f"min_damping must be a number in (0, {MAX_DAMPING}), "
                          f"got {min_damping!r}")
    return omega, e


# ---------------------------------------------------------------------------- problem
class _Problem:
    """Data, scaling and bounds shared by every solve (one order per ``kinds``)."""

    def __init__(self, omega, e, margin, min_damping):
        self.omega = omega
        self.e = e
        self.e_floored = np.maximum(e, E_FLOOR * float(np.max(e)))
        self.floored = e < E_FLOOR * float(np.max(e))
        self.need = (1.0 + margin) * e                                # unfloored bound
        self.log_need = np.log1p(margin) + np.log(self.e_floored)    # b_i
        self.log_k_ref = float(np.max(self.log_need))
        self.omega_c = math.sqrt(omega[0] * omega[-1])
        self.x = omega / self.omega_c                                 # scaled frequency
        self.d_lo = math.log10(omega[0] / self.omega_c) - CORNER_DECADES
        self.d_hi = math.log10(omega[-1] / self.omega_c) + CORNER_DECADES
        self.min_damping = float(min_damping)

    # sections <-> scaled variables (without kappa)
    def pack(self, sections):
        z = []
        for s in sections:
            dn = math.log10(s.omega_num / self.omega_c)
            dd = math.log10(s.omega_den / self.omega_c)
            if s.order == 2:
                z += [dn, s.zeta_num, dd, s.zeta_den]
            else:
                z += [dn, dd]
        return np.array(z, dtype=float)

    def unpack(self, z, kinds):
        sections, i = [], 0
        for second in kinds:
            if second:
                dn, zn, dd, zd = (float(v) for v in z[i:i + 4])
                i += 4
            else:
                (dn, dd), zn, zd = (float(v) for v in z[i:i + 2]), None, None
                i += 2
            sections.append(WeightSection(self.omega_c * 10.0 ** dn,
                                          self.omega_c * 10.0 ** dd, zn, zd))
        return tuple(sections)

    def bounds(self, kinds):
        lb, ub = [-np.inf], [np.inf]                  # kappa is free
        for second in kinds:
            if second:
                lb += [self.d_lo, self.min_damping, self.d_lo, self.min_damping]
                ub += [self.d_hi, MAX_DAMPING, self.d_hi, MAX_DAMPING]
            else:
                lb += [self.d_lo, self.d_lo]
                ub += [self.d_hi, self.d_hi]
        return np.array(lb), np.array(ub)

    def sections_log_abs2(self, x, z, kinds, exp, log):
        """``sum_j ln|S_j(j w_i)|^2`` at scaled frequencies ``x = omega / omega_c`` from the
        scaled variables ``z`` (without kappa); numpy or CasADi."""
        total, i = 0, 0
        for second in kinds:
            if second:
                dn, zn, dd, zd = z[i], z[i + 1], z[i + 2], z[i + 3]
                i += 4
            else:
                dn, dd, zn, zd = z[i], z[i + 1], None, None
                i += 2
            y_num = x * exp(-_LN10 * dn)
            y_den = x * exp(-_LN10 * dd)
            total = total + _section_log_abs2(y_num, zn, y_den, zd, log)
        return total

    def feasible_kappa(self, zs, kinds):
        """Smallest kappa making the start feasible."""
        s = self.sections_log_abs2(self.x, zs, kinds, np.exp, np.log) if kinds else 0.0
        return float(np.max(self.log_need - self.log_k_ref - 0.5 * s))


def _kinds(order):
    return (True,) * (order // 2) + (False,) * (order % 2)


def _solve(prob, kinds, z_sections, solver):
    """One IPOPT solve from the sections' scaled variables ``z_sections``.

    Returns ``(x, status, return_status, nit)`` with ``x = [kappa, z...]`` inside the bounds.
    """
    import casadi as ca

    lb, ub = prob.bounds(kinds)
    zs0 = np.clip(z_sections, lb[1:], ub[1:])
    x0 = np.concatenate([[prob.feasible_kappa(zs0, kinds)], zs0])
    n = x0.size
    z = ca.SX.sym("z", n)
    x = ca.DM(prob.x)
    c = ca.DM(2.0 * (prob.log_need - prob.log_k_ref))
    s = prob.sections_log_abs2(x, [z[i] for i in range(1, n)], kinds, ca.exp, ca.log)
    g = 2.0 * z[0] + s - c                              # 2 (L_i - b_i)
    g_fun = ca.Function("weight_log_margin", [z], [g], ["z"], ["g"])
    f = 0.5 * ca.sum1(g) / prob.omega.size              # mean (L_i - b_i), nepers
    opts = {
        "print_time": False,
        "error_on_fail": False,
        "ipopt": {
            "print_level": 0,
            "sb": "yes",
            "max_iter": int(solver.max_iter),
            "tol": 1e-9,
            # stop once the objective has stalled at a feasible point: over-parametrised
            # weights (a cancelling pole/zero pair) otherwise crawl to max_iter
            "acceptable_tol": 1.0,
            "acceptable_iter": 10,
            "acceptable_obj_change_tol": 1e-6,
            "acceptable_constr_viol_tol": 1e-5,
            "constr_viol_tol": 1e-10,
            # monotone, not adaptive: adaptive's barrier updates made long solves whose end
            # point (one of many local minima) moved with the BLAS kernel's rounding
            "mu_strategy": "monotone",
            **dict(solver.ipopt),               # the user's IPOPT options over these
        },
    }
    res = run_nlpsol("uncertainty_weight", {"x": z, "f": f, "g": g_fun(z)}, opts, x0, lb, ub,
                     constrained=True)[0]
    return res.x, res.status, res.solver_status, res.nit


def _finish(prob, kappa, sections):
    """Gain from kappa, then the numpy feasibility check and correction.

    The check uses ``|W(j w_i)|`` exactly as :meth:`WeightResult.frequency_response`
    computes it and ``need_i = (1 + margin) * e_i``, so the returned bound holds bit for bit.
    """
    gain0 = math.exp(prob.log_k_ref + kappa)
    gain = gain0
    mag = np.abs(_response(gain, sections, prob.omega))
    ratio = float(np.max(prob.need / mag))
    while ratio > 1.0:           # a second pass only to absorb rounding of gain * ratio
        gain = gain * ratio * (1.0 + 4.0 * np.finfo(float).eps)
        mag = np.abs(_response(gain, sections, prob.omega))
        ratio = float(np.max(prob.need / mag))
    objective = float(np.mean(np.log(mag) - prob.log_need))
    return gain, mag, gain / gain0, objective


def _smoothed_log_e(prob):
    """ln e (floored at 1e-6 max e) smoothed by a moving average over M/10 points."""
    le = np.log(np.maximum(prob.e, 1e-6 * float(np.max(prob.e))))
    m = le.size
    width = max(1, m // 10)
    if width > 1:
        kernel = np.ones(width) / width
        le = np.convolve(np.pad(le, (width // 2, width - 1 - width // 2), mode="edge"),
                         kernel, mode="valid")
    return le


def _shaped_start(prob, kinds):
    """One section per stretch of equal total variation of the smoothed ln e.

    Section j covers the frequencies where the total variation of the smoothed ``ln e``
    goes from ``j/n`` to ``(j+1)/n`` of its total; it is centred (geometrically) there and
    its high/low-frequency gain ratio equals the net rise ``R`` of ``e`` over the stretch
    (first order: ``w_den / w_num = R``; second order: ``sqrt(R)``, ``zeta = 1``). A flat
    ``e`` gives identity sections spread evenly over the data range.
    """
    n = len(kinds)
    if n == 0:
        return ()
    le = _smoothed_log_e(prob)
    logw = np.log(prob.omega)
    tv = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(le)))])
    edges = np.arange(n + 1) / n
    if tv[-1] <= 1e-9:
        w_edges = logw[0] + edges * (logw[-1] - logw[0])
    else:
        w_edges = np.interp(edges * tv[-1], tv, logw)
    sections = []
    for j, second in enumerate(kinds):
        centre = 0.5 * (w_edges[j] + w_edges[j + 1])
        rise = float(np.interp(w_edges[j + 1], logw, le) - np.interp(w_edges[j], logw, le))
        half = 0.5 * rise / (2.0 if second else 1.0)          # ln of sqrt(w_den / w_num)
        half = float(np.clip(half, -_LN10 * CORNER_DECADES, _LN10 * CORNER_DECADES))
        wn, wd = math.exp(centre - half), math.exp(centre + half)
        sections.append(WeightSection(wn, wd, 1.0, 1.0) if second else WeightSection(wn, wd))
    return tuple(sections)


def _ladder_starts(prob, sections, order):
    """Starts of order ``order`` from ``sections`` of order - 1 (grid search), best first.

    Odd ``order``: a first-order section ``(1 + s/z)/(1 + s/p)`` is appended. Even: the
    first-order section ``(z0, p0)`` becomes a second-order one with zeros ``{z0, z}`` and
    poles ``{p0, p}``. The objective, after raising the gain to feasibility, is evaluated in
    numpy on a log grid of GRID_PER_DECADE points per decade over the corner bounds for
    ``z`` and ``p``; the starts are its LADDER_PAIRS lowest local minima (each no higher than
    its 8 neighbours) off the diagonal ``z = p``, where every pair cancels (a flat valley of
    ties whose pick, and the solve from it, rounding would decide). Empty if there is none.
    """
    seconds = tuple(s for s in sections if s.order == 2)
    first = [s for s in sections if s.order == 1]
    n_grid = int(round((prob.d_hi - prob.d_lo) * _GRID_PER_DECADE)) + 1
    grid = prob.omega_c * 10.0 ** np.linspace(prob.d_lo, prob.d_hi, n_grid)
    y = prob.omega[None, :] / grid[:, None]                          # (G, M)
    if order % 2 == 1:
        background = seconds + tuple(first)
        zeta_num = zeta_den = None
        y_num = y_den = y
    else:
        background = seconds
        z0, p0 = first[0].omega_num, first[0].omega_den
        wn, zeta_num = _real_pair_section(z0, grid)
        wd, zeta_den = _real_pair_section(p0, grid)
        y_num = prob.omega[None, :] / wn[:, None]
        y_den = prob.omega[None, :] / wd[:, None]
        zeta_num, zeta_den = zeta_num[:, None], zeta_den[:, None]
    log_num = 0.5 * np.log(_cplx.abs2(_factor(y_num, zeta_num)))    # (G, M)
    log_den = 0.5 * np.log(_cplx.abs2(_factor(y_den, zeta_den)))
    base = np.log(np.abs(_response(1.0, background, prob.omega))) - prob.log_need
    objective = np.empty((n_grid, n_grid))
    for i in range(n_grid):                    # rows: zeros; columns: poles
        r = base + log_num[i][None, :] - log_den                     # (G, M) = L - b - ln k
        objective[i] = np.max(-r, axis=1) + np.mean(r, axis=1)
    starts = []
    for i, j in _grid_minima(objective, _LADDER_PAIRS):
        if order % 2 == 1:
            starts.append(background + (WeightSection(float(grid[i]), float(grid[j])),))
        else:
            starts.append(background + (WeightSection(
                float(wn[i]), float(wd[j]), float(zeta_num[i, 0]), float(zeta_den[j, 0])),))
    return starts


def _grid_minima(objective, count):
    """``(i, j)`` of the ``count`` lowest local minima of a square ``objective`` off its
    diagonal (each entry no higher than its 8 neighbours; ties in grid order)."""
    n = objective.shape[0]
    obj = np.where(np.isfinite(objective) & ~np.eye(n, dtype=bool), objective, np.inf)
    pad = np.pad(obj, 1, constant_values=np.inf)
    low = np.isfinite(obj)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                low &= obj <= pad[1 + di:1 + di + n, 1 + dj:1 + dj + n]
    flat = np.flatnonzero(low)
    flat = flat[np.argsort(obj.flat[flat], kind="stable")][:count]
    return [tuple(int(k) for k in np.unravel_index(f, obj.shape)) for f in flat]


def _cancelled(prob, sections, order):
    """``sections`` (order - 1) as order ``order`` with a cancelling real pole/zero pair at
    ``omega_c`` (odd), or at ``sqrt(z0 p0)`` merged into the first-order section (even;
    exact unless a damping reaches MAX_DAMPING, ``z0/p0`` beyond 6.4 decades)."""
    if order % 2 == 1:
        return tuple(sections) + (WeightSection(prob.omega_c, prob.omega_c),)
    seconds = tuple(s for s in sections if s.order == 2)
    z0, p0 = next((s.omega_num, s.omega_den) for s in sections if s.order == 1)
    r = math.sqrt(z0 * p0)
    wn, zn = _real_pair_section(z0, r)
    wd, zd = _real_pair_section(p0, r)
    return seconds + (WeightSection(float(wn), float(wd), float(zn), float(zd)),)


class _Candidate(NamedTuple):
    objective: float
    gain: float
    sections: tuple
    magnitude: np.ndarray
    correction: float
    status: Status
    details: dict


def _candidate(prob, kappa, sections, status, details):
    gain, mag, correction, objective = _finish(prob, kappa, sections)
    return _Candidate(objective, gain, tuple(sections), mag, correction, status, details)


def _message(best, order, overbound, max_iter):
    """:attr:`WeightResult.message`: one sentence, the solve's outcome, the over-bound and
    the next step (IPOPT's own words are in ``details``)."""
    closest = ("touching it at the closest point" if overbound.min_db < 0.01 else
               f"{overbound.min_db:.2g} dB above it at the closest point")
    above = f"|W| is {overbound.mean_db:.2g} dB above the error on average, {closest}"
    if order == 0:
        return f"ok: the constant weight (closed form); {above}"
    fixed = (f"; the gain was raised {100 * (best.correction - 1):.2g} % so that the bound "
             "holds" if best.correction > 1.0 + 1e-4 else "")
    if best.status in SUCCESS_STATUSES:
        return f"ok: converged; {above}{fixed}"
    why = TERMINATION_MESSAGES[best.status]
    step = (f"pass method=IpoptOptions(max_iter={10 * int(max_iter)}) to let it run further"
            if best.status == Status.MAX_ITER else "try another order")
    return (f"not converged ({why}); the bound holds all the same: {above}{fixed} — "
            f"{step}")


def _overbound(prob, mag):
    keep = ~prob.floored
    db = 20.0 * np.log10(mag[keep] / prob.e[keep])
    return Overbound(float(np.mean(db)), float(np.max(db)), float(np.min(db)))


# ---------------------------------------------------------------------------- public
def fit_uncertainty_weight(result_or_omega, rel_error=None, *, order=2, margin=0.0,
                           min_damping=0.2, method=None, progress=False, max_iter=None,
                           verbose=None):
    """Fit a stable, minimum-phase weight ``W(s)`` with ``|W(j w_i)| >= (1 + margin) e_i``.

    Parameters
    ----------
    result_or_omega : FitResult or array_like of float, shape (M,)
        A fit result (its ``data.omega`` and ``rel_error`` are used), or the frequencies in
        rad/s, finite, > 0 and strictly increasing (then ``rel_error`` is required).
    rel_error : array_like of float, shape (M,), optional
        The relative error ``e_i = |Phi_i / G_N(j w_i) - 1| >= 0`` (finite, not all zero).
    order : int
        McMillan degree of ``W`` (>= 0): ``order // 2`` second-order sections and one
        first-order section if odd; 0 gives the constant ``W = (1 + margin) max e``.
    margin : float
        Relative safety margin >= 0: the bound is ``(1 + margin) e_i`` (0.1 = 10 %).
    min_damping : float
        Lower bound of the dampings of second-order sections (keeps ``W`` free of sharp
        resonances and notches between the data points), in (0, MAX_DAMPING).
    method : IpoptOptions, optional
        ``max_iter``: IPOPT's iteration limit per solve; ``ipopt``: IPOPT options over the
        weight fit's own (e.g. ``{"print_level": 5}`` for IPOPT's log); default
        :data:`WEIGHT_METHOD`, ``IpoptOptions(max_iter=500)``. The other fields must keep
        their defaults.
    progress : bool, "lines" or callable
        One record per order solved (:mod:`freqid_casadi._progress`): True draws a bar on a
        terminal (elsewhere a line per 30 s of a long run), "lines" writes a line per order
        to stderr, a callable receives each order's :class:`WeightResult`.
    max_iter : int, optional
        Deprecated (FutureWarning): ``method=IpoptOptions(max_iter=k)``.
    verbose : bool, optional
        Deprecated (FutureWarning): ``verbose=True`` is
        ``method=IpoptOptions(ipopt={"print_level": 5})``.

    Returns
    -------
    WeightResult
        The bound holds at every data point even if IPOPT did not converge
        (``success=False``); see the module notes for the formulation.

    Raises
    ------
    DataError
        Bad ``omega``/``rel_error`` (length mismatch, NaN, negative, all zero, unsorted).
    OptionError
        Bad ``order``, ``margin``, ``min_damping``, ``method`` or ``progress``.

    Notes
    -----
    Minimises the mean log-ratio ``mean_i ln(|W(j w_i)| / ((1 + margin) e_i))`` subject to
    ``ln|W(j w_i)|^2 >= 2 ln((1 + margin) e_i)`` at every point, over the gain, corner
    frequencies and dampings (bounds as ``lbx``/``ubx``). The orders ``1..order`` are solved
    in turn (each from a fresh start and from the two best weights of the order below), so
    ``objective`` does not increase with ``order`` (up to rounding).
    """
    solver = _weight_options("fit_uncertainty_weight", method, max_iter, verbose)
    return weights_by_order(result_or_omega, rel_error, max_order=order, margin=margin,
                            min_damping=min_damping, method=solver, progress=progress)[-1]


def weights_by_order(result_or_omega, rel_error=None, *, max_order=2, margin=0.0,
                     min_damping=0.2, method=None, progress=False, max_iter=None,
                     verbose=None):
    """The weights of every order ``0..max_order`` that :func:`fit_uncertainty_weight`
    passes through (it solves the orders in turn, each from a fresh start and from the
    weights of the order below): ``weights_by_order(..., max_order=n)[n]`` is
    ``fit_uncertainty_weight(..., order=n)``.

    Parameters
    ----------
    result_or_omega, rel_error, margin, min_damping, method, progress, max_iter, verbose
        As :func:`fit_uncertainty_weight`.
    max_order : int
        Highest McMillan degree (>= 0).

    Returns
    -------
    tuple of WeightResult, length max_order + 1
        Entry ``n`` has order ``n``; ``nit`` counts the iterations up to that order.

    Raises
    ------
    DataError, OptionError
        As :func:`fit_uncertainty_weight` (``max_order`` in place of ``order``).
    """
    solver = _weight_options("weights_by_order", method, max_iter, verbose)
    return tuple(iter_weights(result_or_omega, rel_error, max_order=max_order, margin=margin,
                              min_damping=min_damping, method=solver, progress=progress))


def iter_weights(result_or_omega, rel_error=None, *, max_order=2, margin=0.0,
                 min_damping=0.2, method=None, progress=False, max_iter=None, verbose=None):
    """:func:`weights_by_order` one order at a time (a generator: a caller that has what
    it needs stops the ladder early, e.g. :func:`~freqid_casadi.uncertainty.cover.cover`).

    The arguments are checked before the first weight is yielded.

    Parameters
    ----------
    result_or_omega, rel_error, margin, min_damping, method, progress, max_iter, verbose
        As :func:`fit_uncertainty_weight`.
    max_order : int
        Highest McMillan degree (>= 0).

    Yields
    ------
    WeightResult
        Orders 0, 1, ..., ``max_order``.
    """
    solver = _weight_options("iter_weights", method, max_iter, verbose)
    progress = check_progress(progress, "each WeightResult")
    omega, e = _validate(result_or_omega, rel_error, max_order, margin, min_damping)
    return _ladder(omega, e, int(max_order), float(margin), min_damping, solver, progress)


def _ladder(omega, e, max_order, margin, min_damping, solver, progress):
    scale = frequency_scale(omega)              # solve at omega / scale, rescale after
    prob = _Problem(omega / scale, e, margin, min_damping)

    with channel(progress, _order_line, total=max_order + 1, unit="order") as emit:
        # order 0 is closed form: W = max (1 + margin) e (verified like any other weight)
        best = _candidate(prob, 0.0, (), Status.CONVERGED,
                          {"solver_status": "closed form", "start": "closed form",
                           "kept_start": False})
        nit = 0
        out = _weight_result(prob, omega, e, scale, best, 0, margin, nit)
        emit(out)
        yield out
        pool = [best]                  # the best distinct weights of the order below
        for n in range(1, max_order + 1):
            ranked, it = _best_of_order(prob, pool, n, solver)
            nit += it
            pool = []
            for cand in ranked:
                if len(pool) < _LADDER_POOL and all(
                        abs(cand.objective - p.objective) > 1e-6 * abs(p.objective)
                        for p in pool):
                    pool.append(cand)
            out = _weight_result(prob, omega, e, scale, ranked[0], n, margin, nit,
                                 solver.max_iter)
            emit(out)
            yield out


def _best_of_order(prob, pool, n, solver):
    """The weights of order ``n`` from a fresh start, from ladder starts on every weight of
    ``pool`` (order n - 1, best first) and from ``pool[0]`` with a cancelling pair (not
    solved); returns ``(candidates best first, iterations)``."""
    kinds = _kinds(n)
    starts = [("fresh", _shaped_start(prob, kinds))]
    starts += [("ladder", start) for below in pool
               for start in _ladder_starts(prob, below.sections, n)]
    below = pool[0]
    start = _cancelled(prob, below.sections, n)
    # the order below itself: never worse than it, even if every solve ends above it
    cands = [_candidate(prob, prob.feasible_kappa(prob.pack(start), kinds), start,
                        below.status, {"solver_status": below.details["solver_status"],
                                       "start": "ladder", "kept_start": True})]
    nit = 0
    for label, start in starts:
        xs, st, ipopt_msg, it = _solve(prob, kinds, prob.pack(start), solver)
        nit += it
        how = {"solver_status": ipopt_msg, "start": label, "kept_start": False}
        cand = _candidate(prob, float(xs[0]), prob.unpack(xs[1:], kinds), st, how)
        if label == "ladder":
            # keep a ladder start if IPOPT ended above it (as fit.py keeps a stage's start)
            kappa0 = prob.feasible_kappa(prob.pack(start), kinds)
            kept = _candidate(prob, kappa0, start, st, dict(how, kept_start=True))
            if kept.objective < cand.objective:
                cand = kept
        cands.append(cand)
    # solved candidates first, so that on a tie a solve wins over the cancelled pair
    return sorted(cands[1:] + cands[:1], key=lambda c: c.objective), nit


def _weight_result(prob, omega, e, scale, best, order, margin, nit,
                   max_iter=WEIGHT_METHOD.max_iter):
    mag = best.magnitude.copy()
    mag.setflags(write=False)
    om = omega.copy()
    om.setflags(write=False)
    ee = e.copy()
    ee.setflags(write=False)
    over = _overbound(prob, mag)
    return WeightResult(
        omega=om, rel_error=ee, magnitude=mag, gain=float(best.gain),
        sections=rescaled(best.sections, scale), order=order, overbound=over,
        margin=float(margin), gain_correction=float(best.correction),
        objective=float(best.objective), status=best.status,
        message=_message(best, order, over, max_iter),
        success=best.status in SUCCESS_STATUSES, nit=int(nit), details=dict(best.details))
