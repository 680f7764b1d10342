"""One nominal model and one weight W(s) that cover a family of measured plants (layer L4).

MATLAB's ``ucover`` in Python: given a nominal model ``G_N`` and the FRFs ``Phi_i`` of C
members of a plant family (units off a production line, temperatures, payloads, repeated
tests), :func:`cover` finds a stable, minimum-phase ``W(s)`` with

    |W(j w)| >= max_i |Phi_i(j w) / G_N(j w) - 1|        at every point of every member,

so that every member lies in the multiplicative set ``G_N (1 + W Delta)``, ``|Delta| <= 1``,
the uncertainty a robust-stability test ``||W T||_inf < 1`` needs.

The envelope on different grids
-------------------------------
Member ``i``'s error ``e_i(w) = |Phi_i(j w) / G_N(j w) - 1|`` is known at its own
frequencies. The envelope lives on the *union* of all members' frequencies, with the
geometric midpoint of every two neighbours inserted (so that ``W`` is also held above the
envelope between the points, not only at them). At each of these frequencies it is the
maximum over the members whose measured band contains it of ``e_i`` interpolated linearly
in ``(ln w, ln e_i)`` between the member's two neighbouring points; at a member's own point
that is ``e_i`` itself, bit for bit. A member does not count outside its own band (no
extrapolation). So ``|W| >= envelope`` at the envelope's points implies the bound at every
point of every member, and between a member's points ``W`` stays above the log-log
interpolation of its error. The weight's NLP sees at most ``max_points`` of these points
(the largest envelope value in each bin of ``ln w``, :func:`thinned`); the gain is then
raised so the bound holds at all of them, and checked at every member's points.

Features of ``W`` are never narrower than the data resolve: every second-order section of
``W`` has a damping of at least ``min_damping`` (default 0.2: a resonance or notch of
``W`` at least about 40 % of its frequency wide, far wider than the relative spacing of
any FRF the package fits), see :func:`~freqid_casadi.uncertainty.weight.fit_uncertainty_weight`.

The order
---------
The orders ``0..max_order`` are fitted in turn (one ladder,
:func:`~freqid_casadi.uncertainty.weight.iter_weights`, stopped at the order kept);
``order=None`` keeps the
lowest order whose *median* ratio ``|W(j w)| / envelope(w)`` over the envelope's points is
at most ``tightness`` (default 2: half of the points have ``W`` within a factor of 2,
6 dB, of the envelope), or, if no order reaches it, the order with the lowest median ratio
(``CoverResult.message`` says so).

Delay-aware export
------------------
H-infinity synthesis (``control.mixsyn``, ``hinfsyn``) needs a rational nominal. With
``pade_order=k`` the nominal is ``G_R(s) = K [1/s] P_N(s) pade_k(s)`` (the model's delay
replaced by its Padé approximation, :meth:`RationalDelayModel.to_control` with
``delay="pade"``), and the members' errors are taken against it:
``|Phi_i / G_R - 1| = |(1 + d_i)(1 + p) - 1|`` with ``d_i = Phi_i / G_N - 1`` and
``p = exp(-j w h) / pade_k(j w) - 1``: the Padé error is folded into the weight exactly
(not added), so that the rational nominal plus ``W`` covers the measured plants with their
true delay. ``CoverResult.pade_error`` is ``|p|`` on the envelope's grid.
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..core.data import as_frequency_data
from ..core.model import RationalDelayModel, Structure
from ..errors import DataError, ExportWarning, OptionError
from ..options import IpoptOptions
from .weight import WeightResult, iter_weights

__all__ = ["cover", "CoverResult", "DEFAULT_TIGHTNESS", "DEFAULT_MAX_ORDER", "MAX_POINTS",
           "envelope", "envelope_grid", "thinned", "weight_as_model", "weight_as_tf"]

DEFAULT_TIGHTNESS = 2.0
"""Median ``|W| / envelope`` that ``order=None`` accepts."""

DEFAULT_MAX_ORDER = 8
"""Highest order ``order=None`` tries."""

MAX_POINTS = 200
"""Default number of envelope points the weight's NLP sees (see :func:`thinned`)."""


@dataclass(frozen=True, eq=False)
class CoverResult:
    """Result of :func:`cover`.

    Attributes
    ----------
    weight : WeightResult
        The fitted weight (:mod:`freqid_casadi.uncertainty.weight`) on the envelope's grid.
    weight_model : RationalDelayModel
        ``W`` as a model with no delay (second-order basis; a first-order section of ``W``
        is a section with ``a = b = 0``): ``weight_model.frequency_response`` is ``W(j w)``.
    weight_tf : control.TransferFunction
        ``W(s)`` for python-control (``mixsyn(G, w1, w2, w3=weight_tf)``).
    order : int
        McMillan degree of ``W``.
    omega : ndarray of float, shape (K,)
        The envelope's grid, rad/s: the union of the members' frequencies and the midpoints.
    envelope : ndarray of float, shape (K,)
        ``max_i e_i`` at ``omega`` (see the module notes).
    member_omegas : tuple of ndarray of float
        Each member's frequencies, rad/s.
    member_errors : tuple of ndarray of float
        Each member's relative error ``|Phi_i / G - 1|`` at its own frequencies, against
        the nominal ``G`` (``G_N``, or its rational Padé form with ``pade_order``).
    member_names : tuple of str
    nominal : RationalDelayModel
        ``G_N``.
    pade_order : int or None
    pade_error : ndarray of float, shape (K,) or None
        ``|exp(-j w h) / pade_k(j w) - 1|`` at ``omega``.
    median_ratios : dict of int to float
        ``median(|W| / envelope)`` of every order tried.
    median_ratio, max_ratio : float
        Median and largest ``|W| / envelope`` of the returned weight (``>= 1 + margin`` at
        every point).
    margin, tightness : float
    success : bool
        The returned order meets ``tightness`` (the bound holds regardless).
    message : str
    """

    weight: WeightResult
    weight_model: RationalDelayModel
    weight_tf: object
    order: int
    omega: np.ndarray
    envelope: np.ndarray
    member_omegas: tuple
    member_errors: tuple
    member_names: tuple
    nominal: RationalDelayModel
    pade_order: object
    pade_error: object
    median_ratios: dict
    median_ratio: float
    max_ratio: float
    margin: float
    tightness: float
    success: bool
    message: str

    def frequency_response(self, omega):
        """``W(j omega)``, complex ndarray shaped like ``omega`` (rad/s)."""
        return self.weight.frequency_response(omega)

    def nominal_control(self):
        """The nominal for python-control: rational (Padé) with ``pade_order``, else the
        rational part with the delay as the attribute ``delay``.

        Returns
        -------
        control.StateSpace
        """
        if self.pade_order is None:
            return self.nominal.to_control()
        return _pade_nominal(self.nominal, self.pade_order)

    def covers(self):
        """True if ``|W| >= (1 + margin) e_i`` at every point of every member."""
        return all(bool(np.all(np.abs(self.frequency_response(w)) >= (1 + self.margin) * e))
                   for w, e in zip(self.member_omegas, self.member_errors))


# ---------------------------------------------------------------------------- checks
def _nominal(model):
    if hasattr(model, "model") and hasattr(model, "rel_error"):        # a FitResult
        model = model.model
    if not isinstance(model, RationalDelayModel):
        raise DataError(f"model must be a RationalDelayModel or FitResult (the nominal), got "
                        f"{type(model).__name__}; fit one with freqid_casadi.fit")
    return model


def _members(datas):
    if isinstance(datas, (str, bytes)) or not hasattr(datas, "__iter__") \
            or hasattr(datas, "omega") or hasattr(datas, "s"):
        datas = [datas]                                    # one member
    members = [as_frequency_data(d, f"datas[{i}]") for i, d in enumerate(datas)]
    if not members:
        raise DataError("datas is empty: give the FRFs of the family's members")
    units = {d.unit for d in members}
    if len(units) > 1:
        raise DataError(f"datas mix frequency units {sorted(units)}; give every member in "
                        "rad/s (or every one in rad/sample)")
    return members


def _number(value, name, lo, hint):
    if (isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value) or value < lo):
        raise OptionError(f"{name} must be a finite number >= {lo}, got {value!r}; {hint}")
    return float(value)


def _orders(order, max_order):
    for name, v in (("order", order), ("max_order", max_order)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer))
                              or v < 0):
            raise OptionError(f"{name} must be an integer >= 0 or None, got {v!r}")
    if order is not None:
        return int(order), int(order)
    return None, DEFAULT_MAX_ORDER if max_order is None else int(max_order)


# ---------------------------------------------------------------------------- envelope
def _pade_nominal(nominal, pade_order):
    """``nominal.to_control`` with its delay as the Pade approximation of ``pade_order``,
    without the export's warning that the approximation misses the delay: the weight
    covers that error (the members' errors are taken against this nominal)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="the Pade approximation",
                                category=ExportWarning)
        return nominal.to_control(delay="pade", pade_order=pade_order)


def _pade_response(delay, pade_order, omega):
    """``pade_k(j omega)`` of ``exp(-delay s)`` (python-control's coefficients)."""
    import control as ct

    sys = RationalDelayModel(Structure(0, False, True), np.array([delay, 1.0])).to_control(
        delay="pade", pade_order=pade_order)
    return np.asarray(ct.frequency_response(sys, omega).complex).reshape(-1)


def _member_error(nominal, data, pade_order):
    """``|Phi / G - 1|`` at the member's points (G the Padé nominal with ``pade_order``)."""
    g = nominal.frequency_response(data.omega)
    if pade_order is not None and nominal.delay > 0:
        g = nominal.rational_response(data.omega) * _pade_response(nominal.delay, pade_order,
                                                                   data.omega)
    with np.errstate(all="ignore"):
        e = np.abs(data.response / g - 1.0)
    if not np.all(np.isfinite(e)):
        i = int(np.flatnonzero(~np.isfinite(e))[0])
        raise DataError(f"the nominal is zero or infinite at omega={data.omega[i]:g} of "
                        f"member {data.name or ''!s}: the relative error is not finite there; "
                        "drop that point or use a nominal without a zero on the axis")
    return e


def envelope_grid(omegas):
    """The union of ``omegas`` with the geometric midpoint of every two neighbours.

    Parameters
    ----------
    omegas : sequence of ndarray of float
        rad/s, each > 0 and increasing.

    Returns
    -------
    ndarray of float, shape (2 U - 1,)
        U the number of distinct frequencies; the members' own values are kept exactly.
    """
    union = np.unique(np.concatenate([np.asarray(w, float) for w in omegas]))
    if union.size < 2:
        return union
    mid = np.sqrt(union[:-1] * union[1:])
    out = np.empty(2 * union.size - 1)
    out[0::2], out[1::2] = union, mid
    return out


def envelope(omega, member_omegas, member_errors):
    """``max_i e_i(omega)``, each member interpolated in (ln w, ln e) inside its own band.

    Parameters
    ----------
    omega : ndarray of float, shape (K,)
        rad/s.
    member_omegas, member_errors : sequences of ndarray of float
        Each member's frequencies (rad/s, increasing) and relative errors (>= 0).

    Returns
    -------
    ndarray of float, shape (K,)
        0 where no member's band reaches.
    """
    env = np.zeros(omega.size)
    lw = np.log(omega)
    for w, e in zip(member_omegas, member_errors):
        inside = (omega >= w[0]) & (omega <= w[-1])
        tiny = 1e-300
        vals = np.exp(np.interp(lw[inside], np.log(w), np.log(np.maximum(e, tiny))))
        exact = np.isin(omega[inside], w)                 # a member's own point: exact
        idx = np.searchsorted(w, omega[inside][exact])
        vals[exact] = e[idx]
        env[inside] = np.maximum(env[inside], vals)
    return env


# ---------------------------------------------------------------------------- weight
def weight_as_model(weight):
    """``W`` of a :class:`WeightResult` as a :class:`RationalDelayModel` without delay.

    A unit-DC section ``(1 + 2 zn s/wn + (s/wn)^2) / (...)`` is the thesis section
    ``(s^2 + 2 zn wn s + wn^2) / (s^2 + 2 zd wd s + wd^2)`` times ``wd^2 / wn^2``; a
    first-order one ``(1 + s/wn)/(1 + s/wd)`` is the section with ``a = b = 0``,
    ``zeta = 1/2``.

    Parameters
    ----------
    weight : WeightResult

    Returns
    -------
    RationalDelayModel
    """
    gain, secs = float(weight.gain), []
    for sec in weight.sections:
        second = sec.order == 2
        a = 1.0 if second else 0.0
        zn = sec.zeta_num if second else 0.5
        zd = sec.zeta_den if second else 0.5
        secs += [a, zn, sec.omega_num, a, zd, sec.omega_den]
        gain *= (sec.omega_den / sec.omega_num) ** 2
    st = Structure(len(weight.sections), False, False, "second-order")
    return RationalDelayModel(st, np.array([0.0, gain] + secs, float))


def weight_as_tf(weight):
    """``W(s)`` of a :class:`WeightResult` as a python-control ``TransferFunction``.

    Parameters
    ----------
    weight : WeightResult

    Returns
    -------
    control.TransferFunction
        The product of the unit-DC sections' polynomials times the gain.
    """
    import control as ct

    num, den = np.array([float(weight.gain)]), np.array([1.0])
    for sec in weight.sections:
        num, den = np.polymul(num, sec.num), np.polymul(den, sec.den)
    return ct.tf(num, den)


def _raised(weight, factor):
    """``weight`` with its gain multiplied by ``factor`` (>= 1)."""
    import dataclasses

    mag = weight.magnitude * factor
    mag.setflags(write=False)
    return dataclasses.replace(weight, gain=weight.gain * factor, magnitude=mag,
                               gain_correction=weight.gain_correction * factor)


def _exact(weight, members, margin):
    """Raise the gain until ``weight_as_model`` (and the WeightResult) bound every member's
    error at every point in floating point (rounding of the conversion, at most ulps)."""
    for _ in range(4):
        model = weight_as_model(weight)
        worst = 1.0
        for w, e in members:
            need = (1.0 + margin) * e
            for mag in (np.abs(model.frequency_response(w)),
                        np.abs(weight.frequency_response(w))):
                worst = max(worst, float(np.max(need / mag)))
        if worst <= 1.0:
            return weight, model
        weight = _raised(weight, worst * (1.0 + 4.0 * np.finfo(float).eps))
    return weight, weight_as_model(weight)


def thinned(omega, env, n_max):
    """At most about ``n_max`` points of the envelope for the weight's NLP: in each of
    ``n_max`` equal bins of ``ln omega`` the point where the envelope is largest.

    Parameters
    ----------
    omega, env : ndarray of float, shape (K,)
    n_max : int

    Returns
    -------
    ndarray of int
        Indices into ``omega``, increasing (all of them when ``K <= n_max``).
    """
    if omega.size <= n_max:
        return np.arange(omega.size)
    lw = np.log(omega)
    edges = np.linspace(lw[0], lw[-1], n_max + 1)
    b = np.clip(np.searchsorted(edges, lw, side="right") - 1, 0, n_max - 1)
    # per bin, the index of the largest envelope (ties: the first)
    order = np.lexsort((-env, b))
    first = np.ones(order.size, bool)
    first[1:] = b[order][1:] != b[order][:-1]
    return np.sort(order[first])


def _on_full_grid(weight, grid, env, margin):
    """``weight`` (fitted on a thinned grid) with its gain raised so that
    ``|W| >= (1 + margin) env`` at every point of ``grid``, rebased onto ``grid``."""
    import dataclasses

    mag = np.abs(weight.frequency_response(grid))
    need = (1.0 + margin) * env
    factor = max(1.0, float(np.max(need / mag)) * (1.0 + 4.0 * np.finfo(float).eps))
    om, ee, mag = grid.copy(), env.copy(), mag * factor
    for a in (om, ee, mag):
        a.setflags(write=False)
    return dataclasses.replace(weight, omega=om, rel_error=ee, magnitude=mag,
                               gain=weight.gain * factor,
                               gain_correction=weight.gain_correction * factor)


def _median_ratio(weight, env):
    """``median(|W| / env)`` over the points where ``env`` is not negligible."""
    keep = env > 1e-12 * float(np.max(env))
    return float(np.median(weight.magnitude[keep] / env[keep]))


def _choose(weights, grid, env, tightness, fixed_order):
    """(weight, median ratios by order, success, message)."""
    ratios = {wr.order: _median_ratio(wr, env) for wr in weights}
    if fixed_order is not None:
        wr = weights[-1]
        ok = ratios[fixed_order] <= tightness
        return wr, ratios, ok, (f"order {fixed_order} as asked: median |W|/envelope "
                                f"{ratios[fixed_order]:.3g}")
    for wr in weights:
        if ratios[wr.order] <= tightness:
            return wr, ratios, True, (
                f"order {wr.order}: the lowest with median |W|/envelope "
                f"{ratios[wr.order]:.3g} <= {tightness:g}")
    best = min(weights, key=lambda wr: ratios[wr.order])
    shown = ", ".join(f"{k}: {r:.3g}" for k, r in sorted(ratios.items()))
    return best, ratios, False, (
        f"no order up to {len(weights) - 1} reaches median |W|/envelope <= {tightness:g} "
        f"(median ratio by order {shown}); order {best.order} is the tightest. An envelope "
        "that jumps from point to point (the noise of one or two members' errors) is one no "
        "weight follows closely: the bound holds at every order, so a lower one may serve "
        f"as well (order=0: a constant weight, ratio {ratios[min(ratios)]:.3g}); else pass "
        "a larger max_order, more members, or a nominal closer to the family's centre")


# ---------------------------------------------------------------------------- public
def cover(model, datas, *, order=None, margin=0.0, pade_order=None, max_order=None,
          tightness=DEFAULT_TIGHTNESS, min_damping=0.2, max_iter=500,
          max_points=MAX_POINTS):
    """A stable, minimum-phase ``W(s)`` covering every member's error against a nominal.

    Parameters
    ----------
    model : RationalDelayModel or FitResult
        The nominal ``G_N`` (e.g. ``fc.fit`` of one member, or of their mean).
    datas : sequence of FrequencyData, control.FrequencyResponseData or skrf.Network
        The members' FRFs (any grids, one frequency unit); converted by
        :func:`~freqid_casadi.core.data.as_frequency_data`.
    order : int, optional
        McMillan degree of ``W``; None: the lowest order up to ``max_order`` whose median
        ``|W| / envelope`` is at most ``tightness``.
    margin : float
        Relative safety margin >= 0: ``|W| >= (1 + margin) e_i`` (0.1 = 10 %).
    pade_order : int, optional
        Cover against the rational nominal with the delay replaced by its Padé
        approximation of this order (the Padé error folded into ``W``, see the module
        notes); the nominal for synthesis is then :meth:`CoverResult.nominal_control`.
    max_order : int, optional
        Highest order tried with ``order=None`` (default :data:`DEFAULT_MAX_ORDER`).
    tightness : float
        Median ``|W| / envelope`` accepted by ``order=None`` (>= 1; default 2).
    min_damping : float
        Lower bound of the dampings of ``W``'s second-order sections, in (0, 20).
    max_iter : int
        IPOPT iterations per solve.
    max_points : int
        Points of the envelope the weight's NLP sees (:func:`thinned`: the largest value
        in each of ``max_points`` bins of ``ln w``); the gain is then raised so the bound
        holds at every point of the envelope's full grid.

    Returns
    -------
    CoverResult
        ``|W| >= (1 + margin) e_i`` holds at every point of every member in floating point
        (checked, for ``weight_model`` and ``weight`` alike).

    Raises
    ------
    DataError
        A nominal that is not a model, a member that cannot be converted, mixed units,
        an error that is not finite (the nominal zero on the axis), all errors zero.
    OptionError
        Bad ``order``, ``max_order``, ``margin``, ``tightness``, ``pade_order``, ...
    """
    nominal = _nominal(model)
    members = _members(datas)
    fixed_order, top = _orders(order, max_order)
    margin = _number(margin, "margin", 0.0, "a relative margin, 0.1 = 10 %")
    tightness = _number(tightness, "tightness", 1.0, "a median ratio |W|/envelope, e.g. 2")
    if pade_order is not None:
        _pade_nominal(nominal, pade_order)                          # OptionError if bad
    member_omegas = tuple(d.omega for d in members)
    member_errors = tuple(_member_error(nominal, d, pade_order) for d in members)
    grid = envelope_grid(member_omegas)
    env = envelope(grid, member_omegas, member_errors)
    if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) \
            or max_points < 2 * top + 2:
        raise OptionError(f"max_points must be an integer >= 2 max_order + 2 = {2 * top + 2}, "
                          f"got {max_points!r}")
    idx = thinned(grid, env, int(max_points))
    weights = []
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) \
            or max_iter < 1:
        raise OptionError(f"max_iter must be an integer >= 1, got {max_iter!r}; pass e.g. "
                          "max_iter=500")
    for wr in iter_weights(grid[idx], env[idx], max_order=top, margin=margin,
                           min_damping=min_damping, method=IpoptOptions(max_iter=max_iter)):
        weights.append(_on_full_grid(wr, grid, env, margin))
        if fixed_order is None and _median_ratio(weights[-1], env) <= tightness:
            break                                  # the lowest order that is tight enough
    weight, ratios, ok, message = _choose(weights, grid, env, tightness, fixed_order)
    weight, w_model = _exact(weight, list(zip(member_omegas, member_errors)), margin)
    keep = env > 1e-12 * float(np.max(env))
    r = np.abs(weight.frequency_response(grid[keep])) / env[keep]
    pade_err = None
    if pade_order is not None:
        pade_err = np.abs(np.exp(-1j * grid * nominal.delay)
                          / _pade_response(nominal.delay, pade_order, grid) - 1.0)
    for arr in (grid, env) + member_errors + ((pade_err,) if pade_err is not None else ()):
        arr.setflags(write=False)
    return CoverResult(
        weight=weight, weight_model=w_model, weight_tf=weight_as_tf(weight),
        order=weight.order, omega=grid, envelope=env, member_omegas=member_omegas,
        member_errors=member_errors,
        member_names=tuple(d.name or f"member {i}" for i, d in enumerate(members)),
        nominal=nominal, pade_order=pade_order, pade_error=pade_err, median_ratios=ratios,
        median_ratio=float(np.median(r)), max_ratio=float(np.max(r)), margin=margin,
        tightness=tightness, success=bool(ok), message=message)
