"""Examples A, B and C of the thesis (beams and rod, SPEC §4) and their perturbed plants.

The beam ratios are evaluated stably over the whole frequency range (see
:mod:`freqid_casadi.systems`): a power series in ``z = m**4`` near ``s = 0`` and rescaled
closed forms at high frequency.
"""

import math

import numpy as np

from ._common import _data, _omega, _positive, _real_scalar, thesis_grid
from ..errors import OptionError

__all__ = ["G_A", "G_A_at", "G_B", "G_B_at", "G_C", "G_C_at", "perturbed",
           "SERIES_THRESHOLD"]

#: ``|z|`` (z = m**4, dimensionless) below which the beam ratios use their power series.
#: At ``|z| = 4`` the series (16 terms, truncation < 1e-30) and the rescaled closed form
#: agree to ~1e-15 relative.
SERIES_THRESHOLD = 4.0

_N_SERIES = 16

# sinh x cos x - cosh x sin x = sum_j -4 (-4)^j x^(4j+3) / (4j+3)!
# cos x cosh x               = sum_k (-4)^k x^(4k) / (4k)!
# (from sin((1+i)x) and cos((1+i)x) expanded in powers of (1+i)^n = (2i)^(n/2) ...).
# Python int / int true division is correctly rounded.
_C_NUM = tuple((-4) * (-4) ** j / math.factorial(4 * j + 3) for j in range(_N_SERIES))
_C_COSCOSH = tuple((-4) ** k / math.factorial(4 * k) for k in range(_N_SERIES + 1))


def _fourth_root(z):
    """A fourth root m of z with Re m >= 0 and Im m >= 0 (one branch, used consistently)."""
    m = np.sqrt(np.sqrt(z))  # principal: arg m in (-pi/4, pi/4]
    return np.where(m.imag < 0, 1j * m, m)  # rotate (-pi/4, 0) to (pi/4, pi/2)


def _horner(coeffs, z):
    acc = np.zeros_like(z) + coeffs[-1]
    for c in coeffs[-2::-1]:
        acc = acc * z + c
    return acc


def _scaled_beam_terms(m):
    """Beam combinations divided by their growth ``C = exp((1 - 1j) m) / 4``.

    For ``m`` in the first quadrant (``_fourth_root``) returns ``(A1, A2, r)`` with

    - ``A1 = (sinh m cos m - cosh m sin m) / C``
    - ``A2 = (cos m cosh m) / C``
    - ``r = 1 / C = 4 exp(-(1 - 1j) m)``

    all bounded by 8 in magnitude, so no overflow at any frequency.
    """
    em1_p = np.expm1(-2 * m)        # p - 1,  p = exp(-2m),  |p| = exp(-2 Re m) <= 1
    em1_q = np.expm1(2j * m)        # q - 1,  q = exp(2jm),  |q| = exp(-2 Im m) <= 1
    one_minus_p, one_plus_p = -em1_p, 2 + em1_p
    one_plus_q, q_minus_one = 2 + em1_q, em1_q
    a1 = one_minus_p * one_plus_q + 1j * one_plus_p * q_minus_one
    a2 = one_plus_p * one_plus_q
    r = 4 * np.exp(-(1 - 1j) * m)
    return a1, a2, r


def _free_free_ratio(z):
    """``Q(z) = m (sinh m cos m - cosh m sin m) / (cos m cosh m - 1)``, ``z = m**4``.

    Analytic in z near 0 with ``Q(0) = 4``; poles at the free-free beam's modes
    (first at ``|z| ~ 500.6``).
    """
    z = np.asarray(z, dtype=complex)
    out = np.empty_like(z)
    small = np.abs(z) < SERIES_THRESHOLD
    if small.any():
        zs = z[small]
        # m * num = z * sum_j c_j z^j ;  cos cosh - 1 = z * sum_k c_{k+1} z^k
        out[small] = _horner(_C_NUM, zs) / _horner(_C_COSCOSH[1:], zs)
    big = ~small
    if big.any():
        m = _fourth_root(z[big])
        a1, a2, r = _scaled_beam_terms(m)
        out[big] = m * a1 / (a2 - r)
    return out


def _clamped_free_ratio(w):
    """``B(w) = N(mu) / (mu**3 D(mu))``, ``w = mu**4``, with
    ``N = cosh mu sin mu - sinh mu cos mu`` and ``D = 1 + cosh mu cos mu``.

    Analytic in w near 0 with ``B(0) = 1/3``; poles at the clamped-free modes
    (first at ``|w| ~ 12.36``).
    """
    w = np.asarray(w, dtype=complex)
    out = np.empty_like(w)
    small = np.abs(w) < SERIES_THRESHOLD
    if small.any():
        ws = w[small]
        # N / mu^3 = -sum_j c_j w^j ;  D = 1 + sum_k (-4)^k w^k / (4k)!
        out[small] = -_horner(_C_NUM, ws) / (1 + _horner(_C_COSCOSH, ws))
    big = ~small
    if big.any():
        mu = _fourth_root(w[big])
        a1, a2, r = _scaled_beam_terms(mu)
        out[big] = -a1 / (mu ** 3 * (a2 + r))
    return out


# ----------------------------------------------------------------------------- example A


def G_A_at(s, *, h=0.01, eps1=0.001, eps2=0.0033):
    """Free-free beam G_A (force to velocity, integrator and delay) at complex ``s``.

    Parameters
    ----------
    s : array_like of complex, any shape
        Laplace variable in rad/s (``s = 1j*omega`` on the imaginary axis); ``s = 0`` is
        the integrator's pole.
    h : float, optional
        Delay in s (default 0.01), >= 0.
    eps1, eps2 : float, optional
        Damping parameters in s (defaults 0.001 and 0.0033), > 0.

    Returns
    -------
    ndarray of complex, shape of ``s``
        G_A(s) (dimensionless velocity per force units of the thesis).

    Notes
    -----
    SPEC §4, thesis eq. (4.1)::

        G_A(s) = -s e^{-hs} / ((eps1 s + 1)(eps2 s + 1))
                 * (sinh m cos m - cosh m sin m) / (m^3 (cos m cosh m - 1)),
        m^4 = -s^2 / (1 + eps1 s).

    With ``Q(z) = m (sinh m cos m - cosh m sin m)/(cos m cosh m - 1)`` and ``z = m^4`` this
    is exactly ``G_A(s) = e^{-hs} Q(z) / (s (eps2 s + 1))`` (the factor 1 + eps1 s
    cancels), and ``Q(0) = 4``: the low-frequency limit is ``4/s`` (K0 = 4). Q is
    evaluated by its power series for ``|z| < SERIES_THRESHOLD`` and otherwise in a form
    rescaled by ``exp(-(1 - 1j) m)``.
    """
    h = _positive(h, "h", allow_zero=True)
    eps1 = _positive(eps1, "eps1")
    eps2 = _positive(eps2, "eps2")
    s = np.asarray(s, dtype=complex)
    z = -s * s / (1 + eps1 * s)
    return np.exp(-h * s) * _free_free_ratio(z) / (s * (eps2 * s + 1))


def G_A(omega=None, *, h=0.01, eps1=0.001, eps2=0.0033):
    """Frequency response of the free-free beam G_A (SPEC §4, example A).

    Parameters
    ----------
    omega : array_like of float, shape (M,), optional
        Frequencies in rad/s, > 0 and strictly increasing (default: :func:`thesis_grid`).
    h, eps1, eps2 : float, optional
        Delay (s) and damping parameters (s); see :func:`G_A_at`.

    Returns
    -------
    FrequencyData
        ``response[i] = G_A(1j*omega[i])``, named ``"G_A"``.

    Raises
    ------
    DataError
        If ``omega`` is not a valid frequency vector.
    OptionError
        If a parameter is negative (or zero where it must be > 0) or not finite.
    """
    omega = _omega(omega, thesis_grid)
    return _data(omega, G_A_at(1j * omega, h=h, eps1=eps1, eps2=eps2), "G_A")


# ----------------------------------------------------------------------------- example B


def G_B_at(s, *, E=5.0, I=1.0, c_d=0.01, L=5.5):  # noqa: E741 (SPEC symbol)
    """Clamped-free beam G_B at complex ``s``.

    Parameters
    ----------
    s : array_like of complex, any shape
        Laplace variable in rad/s.
    E, I : float, optional
        Material constants (defaults 5 and 1), > 0.
    c_d : float, optional
        Damping constant (default 0.01), >= 0.
    L : float, optional
        Beam length (default 5.5), > 0.

    Returns
    -------
    ndarray of complex, shape of ``s``
        G_B(s).

    Notes
    -----
    SPEC §4 (thesis §4.1.2)::

        G_B(s) = N(s) / (E I m^3 D(s)),   m = (-s^2 / (E I + s c_d I))^{1/4},
        N = cosh(Lm) sin(Lm) - sinh(Lm) cos(Lm),   D = 1 + cosh(Lm) cos(Lm).

    With ``mu = L m``: ``G_B = L^3/(E I) * N(mu)/(mu^3 D(mu))``, a function of
    ``w = mu^4`` equal to 1/3 at w = 0, so the DC gain is ``L^3/(3 E I)``. Power series in
    w for ``|w| < SERIES_THRESHOLD``, otherwise a form rescaled by ``exp(-(1 - 1j) mu)``.
    """
    E = _positive(E, "E")
    I = _positive(I, "I")  # noqa: E741
    c_d = _positive(c_d, "c_d", allow_zero=True)
    L = _positive(L, "L")
    s = np.asarray(s, dtype=complex)
    w = L ** 4 * (-s * s) / (E * I + s * (c_d * I))
    return L ** 3 / (E * I) * _clamped_free_ratio(w)


def G_B(omega=None, *, E=5.0, I=1.0, c_d=0.01, L=5.5):  # noqa: E741
    """Frequency response of the clamped-free beam G_B (SPEC §4, example B).

    Parameters
    ----------
    omega : array_like of float, shape (M,), optional
        Frequencies as in :func:`G_A` (rad/s; default :func:`thesis_grid`).
    E, I, c_d, L : float, optional
        Beam parameters; see :func:`G_B_at`.

    Returns
    -------
    FrequencyData
        ``response[i] = G_B(1j*omega[i])``, named ``"G_B"``.

    Raises
    ------
    DataError, OptionError
        As :func:`G_A`: an invalid ``omega``; a parameter of :func:`G_B_at` out of range.
    """
    omega = _omega(omega, thesis_grid)
    return _data(omega, G_B_at(1j * omega, E=E, I=I, c_d=c_d, L=L), "G_B")


# ----------------------------------------------------------------------------- example C


def G_C_at(s, *, lam=0.5, tau=0.0525, c=0.2, G=0.4, I_p=2.5, eps=0.001):
    """Damped free-free uniform rod G_C (integrator and delay tau*lam) at complex ``s``.

    Parameters
    ----------
    s : array_like of complex, any shape
        Laplace variable in rad/s; ``s = 0`` is the integrator's pole.
    lam : float, optional
        Normalised sensor position lambda = x/L in [0, 1] (default 0.5).
    tau : float, optional
        Travel time L/c in s (default 0.0525), > 0.
    c, G, I_p : float, optional
        Wave speed, shear modulus and polar moment (defaults 0.2, 0.4, 2.5), > 0.
    eps : float, optional
        Damping parameter in s (default 0.001), >= 0.

    Returns
    -------
    ndarray of complex, shape of ``s``
        G_C(s).

    Notes
    -----
    SPEC §4 (thesis §4.1.3)::

        G_C(s) = c/(G I_p) (e^{-2 tau (1-lam) s} + 1) / ((eps s + 1) - e^{-2 tau s})
                 * e^{-tau lam s}.

    The denominator is formed as ``eps s - expm1(-2 tau s)`` (no cancellation at small s);
    the low-frequency behaviour is ``c/(G I_p) * 2/((eps + 2 tau) s)``.
    """
    lam = _real_scalar(lam, "lam")
    if not 0 <= lam <= 1:
        raise OptionError(f"lam must be in [0, 1] (normalised position x/L), got {lam!r}")
    tau = _positive(tau, "tau")
    c = _positive(c, "c")
    G = _positive(G, "G")
    I_p = _positive(I_p, "I_p")
    eps = _positive(eps, "eps", allow_zero=True)
    s = np.asarray(s, dtype=complex)
    num = np.exp(-2 * tau * (1 - lam) * s) + 1
    den = eps * s - np.expm1(-2 * tau * s)
    return c / (G * I_p) * num / den * np.exp(-tau * lam * s)


def G_C(omega=None, *, lam=0.5, tau=0.0525, c=0.2, G=0.4, I_p=2.5, eps=0.001):
    """Frequency response of the damped free-free rod G_C (SPEC §4, example C).

    Parameters
    ----------
    omega : array_like of float, shape (M,), optional
        Frequencies as in :func:`G_A` (rad/s; default :func:`thesis_grid`).
    lam, tau, c, G, I_p, eps : float, optional
        Rod parameters; see :func:`G_C_at`.

    Returns
    -------
    FrequencyData
        ``response[i] = G_C(1j*omega[i])``, named ``"G_C"``.

    Raises
    ------
    DataError, OptionError
        As :func:`G_A`: an invalid ``omega``; a parameter of :func:`G_C_at` out of range.
    """
    omega = _omega(omega, thesis_grid)
    resp = G_C_at(1j * omega, lam=lam, tau=tau, c=c, G=G, I_p=I_p, eps=eps)
    return _data(omega, resp, "G_C")


# ----------------------------------------------------------------------------- perturbed

_PERTURBED = {
    "A": (G_A, {"eps1": 0.001, "eps2": 0.0033}),
    "B": (G_B, {"E": 5.0, "I": 1.0}),
    "C": (G_C, {"tau": 0.0525, "lam": 0.5}),
}


def perturbed(example, percent, omega=None):
    """Perturbed plant of the thesis's figs 4.8, 4.13 and 4.19.

    Parameters
    ----------
    example : {"A", "B", "C"}
        Which benchmark ("G_A", "G_B", "G_C" are accepted too).
    percent : float
        Relative change in percent (e.g. 5 or 10 for the thesis's +5 % and +10 %), > -100.
    omega : array_like of float, shape (M,), optional
        Frequencies in rad/s (default: :func:`thesis_grid`).

    Returns
    -------
    FrequencyData
        The perturbed plant's response, named e.g. ``"G_A+5%"``.

    Raises
    ------
    OptionError
        Unknown ``example`` or ``percent`` not a finite number > -100.
    DataError
        If ``omega`` is not a valid frequency vector.

    Notes
    -----
    SPEC §4: all other parameters keep their nominal values; the perturbed ones are
    multiplied by ``1 + percent/100``:

    - A: ``eps1`` and ``eps2`` (the delay h stays 0.01);
    - B: ``E`` and ``I`` (so E I grows by ``(1 + percent/100)**2``, resonances by about
      ``1 + percent/100``);
    - C: ``tau`` and ``lam`` (so the delay tau*lam also grows, by ``(1 + percent/100)**2``).
    """
    key = str(example).upper()
    key = key[2:] if key.startswith("G_") else key
    if key not in _PERTURBED:
        raise OptionError(f"example must be 'A', 'B' or 'C', got {example!r}")
    pct = _real_scalar(percent, "percent")
    if pct <= -100:
        raise OptionError(f"percent must be > -100 (parameters stay positive), got {percent!r}")
    fun, nominal = _PERTURBED[key]
    factor = 1 + pct / 100
    data = fun(omega, **{k: v * factor for k, v in nominal.items()})
    return _data(data.omega, data.response, f"G_{key}{pct:+g}%")
