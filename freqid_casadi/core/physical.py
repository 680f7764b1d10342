"""Physical parameters of a RationalDelayModel for the delta method (layer L1, private).

The thesis's ``beta`` has a redundant gauge (each numerator and denominator can be scaled
against K), so its Jacobian is rank deficient. The uncertainty of a fit is computed in a
set without redundancy, written in the quantities a user asks about::

    ln G_N(jw) = -jw h + ln g - n_int ln(jw)
                 + sum_num [m ln(jw) + ln f(jw)] - sum_den [m ln(jw) + ln f(jw)]

with every factor normalised to a unit lowest coefficient (``s^m`` stripped):

* quadratic ``f = 1 + 2 zeta s/omega + (s/omega)^2``: parameters ``omega`` (rad/s, the
  natural frequency) and ``zeta`` (damping ratio), ``zeta = 0`` being its bound;
* first order ``f = 1 + s/r``: the root ``r`` (rad/s), and the missing coefficient as a
  parameter at its bound 0 (``s2_*`` for a second-order section whose ``s^2`` coefficient
  is 0, ``s1_*`` for a constant factor, ``s0_*`` for a factor with roots at the origin);
* ``g`` the gain: the coefficient of the lowest power of s of ``K s^(-k) P_N`` (the DC gain
  when there are no roots at the origin; ``K0`` with an integrator), as ``log_gain``;
* ``h`` the delay (s), at its bound when ``h * max(omega) <= bound_tol``.

Derivatives of ``ln G_N`` are analytic (:func:`log_response`); a test checks them
against central differences of :meth:`RationalDelayModel.frequency_response`.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import StructureError
from .model import RationalDelayModel

__all__ = ["Parametrization", "parametrize", "log_response", "to_model", "polish", "align"]

QUADRATIC, FIRST, CONSTANT = "quadratic", "first-order", "constant"


@dataclass(frozen=True)
class _Factor:
    """One numerator or denominator factor: kind, index of its 2 (or 1) slots in theta,
    power of s stripped, sign (+1 numerator, -1 denominator), section (1-based)."""

    kind: str
    slots: tuple
    power: int
    sign: int
    section: int


@dataclass(frozen=True, eq=False)
class Parametrization:
    """A model written in physical parameters.

    Attributes
    ----------
    structure : freqid_casadi.core.model.Structure
    names : tuple of str, length P
        ``"delay"`` (only if the structure has one), ``"log_gain"``, then per section k
        ``omega_num[k], zeta_num[k], omega_den[k], zeta_den[k]`` for quadratic factors
        (``root_*``, ``s0_*``, ``s1_*``, ``s2_*`` for degenerate ones, see module notes;
        the first-order basis has one slot per factor).
    theta : ndarray of float, shape (P,)
        Values (s, ln of gain units, rad/s, dimensionless).
    at_bound : ndarray of bool, shape (P,)
        Parameters at their bound (zeta = 0 or at the fit's damping floor, delay 0 or at
        ``delay_max``, a missing coefficient).
    lower : ndarray of float, shape (P,)
        Lower bounds (0 for delay/zeta, -inf for log_gain, a tiny positive value for
        frequencies and roots).
    factors : tuple of _Factor
    """

    structure: object
    names: tuple
    theta: np.ndarray
    at_bound: np.ndarray
    lower: np.ndarray
    factors: tuple

    @property
    def n_params(self):
        """Number of parameters P."""
        return len(self.names)

    def index(self, name):
        """Position of ``name`` in :attr:`names`."""
        return self.names.index(name)


def _lowest(coeffs):
    """Power of s stripped (number of leading zero coefficients from s^0)."""
    nz = np.flatnonzero(np.asarray(coeffs) != 0)
    if nz.size == 0:
        raise StructureError("a section has an identically zero numerator or denominator; "
                             "its response is 0 or infinite: remove the section")
    return int(nz[0])


def _factor_coeffs(basis, theta_k):
    """(numerator, denominator) coefficients, lowest power first."""
    if basis == "second-order":
        a, zn, wn, b, zd, wd = theta_k
        return (wn * wn, 2 * zn * wn, a), (wd * wd, 2 * zd * wd, b)
    a1, a0, b1, b0 = theta_k
    return (a0, a1), (b0, b1)


def _slots_of(coeffs, part, k, zeta_floor, bound_tol):
    """Kind, slot names/values/at_bound/lower of one factor, its power and log lowest coeff."""
    m = _lowest(coeffs)
    c = coeffs[m:]
    deg = len(c) - 1
    while deg > 0 and c[deg] == 0:
        deg -= 1
    tiny = np.finfo(float).tiny
    if deg == 2:
        if c[0] * c[2] < 0:
            raise StructureError(
                f"section {k} has a {part}erator with real roots of opposite signs (a "
                "zeros='free' model): its uncertainty is not parametrized by (omega, zeta)")
        omega = float(np.sqrt(c[0] / c[2]))
        zeta = float(c[1] / (2 * np.sqrt(c[0] * c[2])))
        bound = zeta <= max(zeta_floor * (1 + bound_tol), bound_tol) and (
            part == "den" or zeta >= 0)      # a free zero's damping may be negative
        slots = [(f"omega_{part}[{k}]", omega, False, tiny),
                 (f"zeta_{part}[{k}]", zeta, bound, 0.0)]
        kind = QUADRATIC
    elif deg == 1:
        slots = [(f"root_{part}[{k}]", float(c[0] / c[1]), False, tiny)]
        kind = FIRST
    else:
        slots = []
        kind = CONSTANT
    n_slots = len(coeffs) - 1
    missing = [j for j in range(len(coeffs)) if j < m or j > m + deg]
    for j in missing[:n_slots - len(slots)]:
        slots.append((f"s{j}_{part}[{k}]", 0.0, True, 0.0))
    return kind, slots, m, float(np.log(c[0]))


def parametrize(model, omega_max=None, *, zeta_floor=0.0, delay_max=None, bound_tol=1e-8):
    """Physical parameters of a model (see the module notes).

    Parameters
    ----------
    model : RationalDelayModel
    omega_max : float, optional
        Highest data frequency (rad/s): the delay is at its bound when
        ``h * omega_max <= bound_tol``. Default: only ``h == 0`` is at the bound.
    zeta_floor : float
        The fit's damping floor (``FitResult.options["min_damping"]``); a damping within
        ``bound_tol`` (relative) of it is at the bound.
    delay_max : float, optional
        The fit's delay upper bound (s); a delay within ``bound_tol`` of it is at the bound.
    bound_tol : float
        Relative tolerance of the bound tests.

    Returns
    -------
    Parametrization

    Raises
    ------
    StructureError
        A section with an identically zero numerator or denominator.
    """
    if not isinstance(model, RationalDelayModel):
        raise StructureError(f"model must be a RationalDelayModel, got {type(model).__name__}")
    st = model.structure
    names, theta, bound, lower, factors = [], [], [], [], []
    if st.delay:
        h = model.delay
        at = h == 0 or (omega_max is not None and h * omega_max <= bound_tol) or (
            delay_max is not None and h >= delay_max * (1 - bound_tol))
        names.append("delay"), theta.append(h), bound.append(bool(at)), lower.append(0.0)
    names.append("log_gain"), bound.append(False), lower.append(-np.inf)
    # the gain's sign (Structure.gain_sign) is structural: the parameter is ln|K|
    log_gain = np.log(abs(model.gain)) if model.gain != 0 else -np.inf
    if not np.isfinite(log_gain):
        raise StructureError("the model's gain K is 0: its response is identically zero")
    theta.append(0.0)
    i_gain = len(theta) - 1
    for k, theta_k in enumerate(model.sections(), start=1):
        for part, sign, coeffs in zip(("num", "den"), (1, -1),
                                      _factor_coeffs(st.basis, theta_k)):
            kind, slots, m, log_c = _slots_of(coeffs, part, k, zeta_floor, bound_tol)
            log_gain += sign * log_c
            start = len(theta)
            for name, value, at, low in slots:
                names.append(name), theta.append(value), bound.append(at), lower.append(low)
            free_slots = tuple(range(start, start + (2 if kind == QUADRATIC else
                                                     1 if kind == FIRST else 0)))
            factors.append(_Factor(kind, free_slots, m, sign, k))
    theta[i_gain] = float(log_gain)
    theta = np.array(theta, dtype=float)
    at_bound = np.array(bound, dtype=bool)
    for arr in (theta, at_bound):
        arr.setflags(write=False)
    return Parametrization(st, tuple(names), theta, at_bound, np.array(lower), tuple(factors))


def log_response(par, theta, omega):
    """``ln G_N(j omega)`` and its derivatives with respect to the physical parameters.

    Parameters
    ----------
    par : Parametrization
    theta : array_like of float, shape (P,)
        Parameter values in the layout of ``par``.
    omega : array_like of float, shape (M,)
        Frequencies in rad/s (> 0).

    Returns
    -------
    log_g : ndarray of complex, shape (M,)
        ``ln G_N`` (imaginary part: phase, not unwrapped across factors).
    d_log_g : ndarray of complex, shape (M, P)
        Analytic ``d ln G_N / d theta``; zero columns for the slots of missing
        coefficients (parameters at their bound that the factor does not use).
    """
    theta = np.asarray(theta, dtype=float)
    s = 1j * np.asarray(omega, dtype=float)
    jac = np.zeros((s.size, theta.size), dtype=complex)
    i = 0
    log_g = np.zeros(s.size, dtype=complex)
    if par.structure.delay:
        log_g += -s * theta[0]
        jac[:, 0] = -s
        i = 1
    log_g += theta[i] + (1j * np.pi if par.structure.gain_sign < 0 else 0.0)
    jac[:, i] = 1.0
    power = -par.structure.origin_order
    for f in par.factors:
        power += f.sign * f.power
        if f.kind == QUADRATIC:
            w, z = theta[f.slots[0]], theta[f.slots[1]]
            x = s / w
            val = 1 + 2 * z * x + x * x
            jac[:, f.slots[0]] = f.sign * (-2 * z * x - 2 * x * x) / (w * val)
            jac[:, f.slots[1]] = f.sign * 2 * x / val
        elif f.kind == FIRST:
            r = theta[f.slots[0]]
            val = 1 + s / r
            jac[:, f.slots[0]] = f.sign * (-s / (r * r)) / val
        else:
            continue
        log_g += f.sign * np.log(val)
    if power:
        log_g += power * np.log(s)
    return log_g, jac


def to_model(par, theta):
    """The RationalDelayModel with the physical parameters ``theta`` (layout of ``par``).

    Every quadratic factor is written ``s^2 + 2 zeta omega s + omega^2`` (a = 1), a first
    order one ``r + s`` (second-order basis: ``a = 0, zeta = 1/(2 sqrt r), wn = sqrt r``)
    and K absorbs the scales, so ``to_model(par, par.theta)`` has the response of the
    parametrized model (not its beta).

    Parameters
    ----------
    par : Parametrization
    theta : array_like of float, shape (P,)

    Returns
    -------
    RationalDelayModel
    """
    theta = np.asarray(theta, dtype=float)
    st = par.structure
    beta = np.zeros(st.n_params)
    i = 1 if st.delay else 0
    if st.delay:
        beta[0] = theta[0]
    log_k = theta[i]
    size = st.section_size
    for f in par.factors:
        j = 2 + (f.section - 1) * size + (0 if f.sign > 0 else size // 2)
        if st.basis == "second-order":
            if f.kind == QUADRATIC:
                w, z = theta[f.slots[0]], theta[f.slots[1]]
                coeffs = (1.0, z, w)                     # a, zeta, omega
                log_c = 2 * np.log(w)
            elif f.kind == FIRST:
                r = theta[f.slots[0]]
                coeffs, log_c = (0.0, 0.5 / np.sqrt(r), np.sqrt(r)), np.log(r)
            else:
                coeffs, log_c = _constant_second(f.power)
        else:
            if f.kind == FIRST:
                r = theta[f.slots[0]]
                coeffs, log_c = (1.0, r), np.log(r)      # a1, a0
            else:
                coeffs, log_c = ((0.0, 1.0) if f.power == 0 else (1.0, 0.0)), 0.0
        beta[j:j + len(coeffs)] = coeffs
        log_k -= f.sign * log_c
    beta[1] = np.exp(log_k)
    return RationalDelayModel(st, np.maximum(beta, 0.0))


def _constant_second(power):
    """(a, zeta, omega) and log lowest coefficient of 1 (power 0) or s^2 (power 2)."""
    if power == 0:
        return (0.0, 0.0, 1.0), 0.0
    return (1.0, 0.0, 0.0), 0.0


def polish(par, omega, response, weights, theta0=None, max_nfev=200):
    """Weighted relative least squares in the physical parameters, from ``theta0``.

    The parameters at their bound stay fixed; the others keep their lower bounds.
    scipy ``least_squares`` (trust-region reflective) with the analytic Jacobian.

    Parameters
    ----------
    par : Parametrization
        The model in physical parameters (:func:`parametrize`); its slots at their bound
        (``par.at_bound``) stay fixed.
    omega : ndarray of float, shape (M,)
        Data frequencies, rad/s.
    response : ndarray of complex, shape (M,)
        Measured response at ``omega``.
    weights : ndarray of float, shape (M,)
        Weight of each point's squared relative error ``|response / G(j omega) - 1|^2``.
    theta0 : ndarray of float, shape (P,), optional
        Start (default ``par.theta``).
    max_nfev : int
        Most residual evaluations of scipy ``least_squares`` (default 200).

    Returns
    -------
    theta : ndarray of float, shape (P,)
    success : bool
    """
    from scipy.optimize import least_squares

    theta = np.array(par.theta if theta0 is None else theta0, dtype=float)
    free = ~par.at_bound
    sw = np.sqrt(np.concatenate([weights, weights]))

    def parts(x):
        t = theta.copy()
        t[free] = x
        log_g, d_log_g = log_response(par, t, omega)
        ratio = response * np.exp(-log_g)
        return ratio, d_log_g[:, free]

    def fun(x):
        ratio, _ = parts(x)
        r = ratio - 1
        return sw * np.concatenate([r.real, r.imag])

    def jac(x):
        ratio, d = parts(x)
        j = -ratio[:, None] * d
        return sw[:, None] * np.concatenate([j.real, j.imag])

    lower = par.lower[free]
    x0 = np.maximum(theta[free], lower)
    res = least_squares(fun, x0, jac=jac, bounds=(lower, np.inf), x_scale="jac",
                        max_nfev=max_nfev, method="trf")
    theta[free] = res.x
    return theta, bool(res.status > 0)


def _section_keys(par):
    """Per section: slot names without the index, and ln of its frequency slots."""
    keys = {}
    for f in par.factors:
        names, freqs = keys.setdefault(f.section, ([], []))
        for i in f.slots:
            names.append(par.names[i].split("[")[0])
            if not par.names[i].startswith("zeta"):
                freqs.append(np.log(par.theta[i]))
    return keys


def align(par, model, **kwargs):
    """Physical parameters of ``model`` in the section order of ``par``, or None.

    Sections are matched by the frequencies of their factors (least total
    ``|ln omega - ln omega_ref|``, Hungarian assignment); None when the structure or the
    kinds of the factors differ (e.g. a quadratic became first order).

    Parameters
    ----------
    par : Parametrization
        The reference.
    model : RationalDelayModel
        A refit with the same structure.
    **kwargs
        Passed to :func:`parametrize`.

    Returns
    -------
    ndarray of float, shape (P,) or None
    """
    from scipy.optimize import linear_sum_assignment

    if model.structure != par.structure:
        return None
    new = parametrize(model, **kwargs)
    ref_keys, new_keys = _section_keys(par), _section_keys(new)
    n = par.structure.n_sections
    cost = np.full((n, n), 1e12)
    for i in range(n):
        for j in range(n):
            (rn, rf), (nn, nf) = ref_keys[i + 1], new_keys[j + 1]
            if rn == nn:
                cost[i, j] = float(np.sum(np.abs(np.subtract(rf, nf))))
    rows, cols = linear_sum_assignment(cost)
    if np.any(cost[rows, cols] >= 1e12):
        return None
    head = 2 if par.structure.delay else 1
    theta = np.empty(par.n_params)
    theta[:head] = new.theta[:head]
    per = (par.n_params - head) // max(n, 1)
    for i, j in zip(rows, cols):
        theta[head + i * per:head + (i + 1) * per] = new.theta[head + j * per:head + (j + 1) * per]
    return theta
