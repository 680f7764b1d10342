"""Rational approximations of 1/sqrt(s): the thesis's comparison methods for §4.2 (layer L4).

- Matsuda & Fujii (J. Guidance 16, 1993): a continued-fraction expansion fitted at
  geometrically spaced points of a band ("Method 2" of thesis fig. 4.20).
- Carlson & Halijak (IEEE Trans. Circuit Theory 11, 1964): the regular Newton process
  ``H_{k+1} = H_k (H_k^2 + 3x)/(3 H_k^2 + x)`` for ``x^{1/2}`` ("Method 3").

The thesis names both methods without formulas; what is implemented is written out in each
docstring. Both give poles and zeros interlaced on the negative real axis (stable and
minimum phase), realised as a cascade of first-order sections.
"""

import numpy as np
from numpy.polynomial import polynomial as P

from ..errors import OptionError
from ._ssmodel import check_order, real_cascade

__all__ = ["continued_fraction_sqrt", "thiele_coefficients", "newton_sqrt",
           "newton_sqrt_polynomials"]

_MAX_NEWTON_ITER = 5


def thiele_coefficients(x, f):
    """Coefficients of Thiele's interpolating continued fraction (inverse differences).

    Parameters
    ----------
    x : array_like of float, shape (K+1,)
        Distinct interpolation points.
    f : array_like of float, shape (K+1,)
        Values f(x_k).

    Returns
    -------
    ndarray of float, shape (K+1,)
        ``a_k = phi_k(x_k)`` with ``phi_0 = f`` and
        ``phi_k(x_i) = (x_i - x_{k-1}) / (phi_{k-1}(x_i) - phi_{k-1}(x_{k-1}))``, so that
        ``f(x) ~ a_0 + (x - x_0)/(a_1 + (x - x_1)/(a_2 + ... + (x - x_{K-1})/a_K))``
        interpolates f at every x_k.
    """
    x = np.asarray(x, float)
    phi = np.array(f, float, copy=True)
    a = np.empty(x.size)
    a[0] = phi[0]
    for k in range(1, x.size):
        phi[k:] = (x[k:] - x[k - 1]) / (phi[k:] - phi[k - 1])
        a[k] = phi[k]
    return a


def _thiele_polynomials(x, a):
    """Numerator and denominator (ascending coefficients) of the last convergent:
    ``P_k = a_k P_{k-1} + (x - x_{k-1}) P_{k-2}``, same for Q, ``P_{-1} = 1, Q_{-1} = 0,
    P_0 = a_0, Q_0 = 1``."""
    Pm, Pk = np.array([1.0]), np.array([a[0]])
    Qm, Qk = np.array([0.0]), np.array([1.0])
    for k in range(1, a.size):
        lin = np.array([-x[k - 1], 1.0])
        Pm, Pk = Pk, P.polyadd(a[k] * Pk, P.polymul(lin, Pm))
        Qm, Qk = Qk, P.polyadd(a[k] * Qk, P.polymul(lin, Qm))
    return P.polytrim(Pk), P.polytrim(Qk)


def continued_fraction_sqrt(order, *, omega_0=1.0, n_decades=10.0):
    """Matsuda-Fujii continued-fraction approximation of ``1/sqrt(s)`` of a given order.

    Parameters
    ----------
    order : int
        Number n >= 1 of poles (and of zeros): the model is biproper of order n.
    omega_0 : float, optional
        Geometric centre of the fitting band (rad/s). Default 1.
    n_decades : float, optional
        Width of the band in decades: the 2n + 1 interpolation points are
        ``omega_0 * 10**(n_decades * (k/(2n) - 1/2))``, k = 0..2n. Default 10, i.e.
        1e-5 .. 1e5 rad/s for omega_0 = 1, the band of thesis §4.2.

    Returns
    -------
    StateSpaceModel
        ``name = "continued-fraction"``, ``delay = 0``; ``G(omega_k) = omega_k^{-1/2}``
        at the 2n + 1 real points.

    Notes
    -----
    Matsuda's method as it is used for fractional operators (Matsuda & Fujii 1993; see
    also Vinagre et al., Fract. Calc. Appl. Anal. 3 (2000)): the gain ``x^{-1/2}``,
    ``x = omega``, is interpolated at geometrically spaced points by Thiele's continued
    fraction (:func:`thiele_coefficients`, inverse differences, points in increasing
    order), and the convergent with 2n + 1 points, a rational function of type (n, n),
    is evaluated at ``x = s``. The work is done in ``u = x/omega_0``. Because ``x^{-1/2}``
    is a Stieltjes function, its interpolants at positive points have interlacing real
    negative poles and zeros, so the model is stable and minimum phase; the real roots
    are computed from the convergent's polynomials and realised as a cascade of
    first-order sections whose gain is fixed by the value at ``s = omega_0``.
    """
    n = check_order(order)
    w0 = float(omega_0)
    if not np.isfinite(w0) or w0 <= 0:
        raise OptionError(f"omega_0 must be a positive frequency (rad/s), got {omega_0!r}")
    dec = float(n_decades)
    if not np.isfinite(dec) or dec <= 0:
        raise OptionError(f"n_decades must be > 0, got {n_decades!r}")
    u = 10.0 ** (dec * (np.arange(2 * n + 1) / (2 * n) - 0.5))
    a = thiele_coefficients(u, u ** -0.5)
    num, den = _thiele_polynomials(u, a)
    zeros = P.polyroots(num).real * w0
    poles = P.polyroots(den).real * w0
    return real_cascade(zeros, poles, 1.0, "continued-fraction", s_ref=w0,
                        value_ref=w0 ** -0.5)


def newton_sqrt_polynomials(n_iter, x0=1.0):
    """Numerator and denominator of the k-th regular-Newton iterate for ``x^{1/2}``.

    Parameters
    ----------
    n_iter : int
        Number of iterations k >= 0.
    x0 : float, optional
        The constant starting value ``H_0 = x0 > 0``.

    Returns
    -------
    num, den : ndarray of float
        Coefficients in ascending powers of x of ``H_k = num/den``, from the polynomial
        form of Carlson & Halijak's iteration with ``H = N/D``:
        ``N <- N (N^2 + 3 x D^2)``, ``D <- D (3 N^2 + x D^2)`` (no normalisation).
        From ``H_0 = 1``: ``H_1 = (1 + 3x)/(3 + x)``,
        ``H_2 = (1 + 36x + 126x^2 + 84x^3 + 9x^4)/(9 + 84x + 126x^2 + 36x^3 + x^4)``,
        in general ``num_j = C(3^k, 2j)``, ``den_j = C(3^k, 2j+1)``.
    """
    k = check_order(n_iter, "n_iter", 0)
    x0 = float(x0)
    if not np.isfinite(x0) or x0 <= 0:
        raise OptionError(f"x0 must be > 0, got {x0!r}")
    N, D = np.array([x0]), np.array([1.0])
    xpoly = np.array([0.0, 1.0])
    for _ in range(k):
        N2, xD2 = P.polymul(N, N), P.polymul(xpoly, P.polymul(D, D))
        N, D = P.polymul(N, P.polyadd(N2, 3 * xD2)), P.polymul(D, P.polyadd(3 * N2, xD2))
    return N, D


def newton_sqrt(n_iter, *, x0=1.0):
    """Carlson & Halijak's regular Newton process for ``1/sqrt(s)`` as a rational model.

    Parameters
    ----------
    n_iter : int
        Iterations k, 1 <= k <= 5; the model has order ``(3^k - 1)/2`` (1, 4, 13, 40, 121).
    x0 : float, optional
        Starting value ``H_0 = x0 > 0``. The approximation is exact at
        ``s = 1/x0^2`` rad/s and accurate in a band centred there (geometric symmetry).

    Returns
    -------
    StateSpaceModel
        ``name = "newton"``, ``delay = 0``, biproper.

    Notes
    -----
    The iteration ``H_{k+1} = H_k (H_k^2 + 3x)/(3 H_k^2 + x)`` (SPEC §6) converges to
    ``x^{1/2}``; with ``x = 1/s`` it approximates ``1/sqrt(s)``. Writing ``t = sqrt(x)``
    and ``r = (H - t)/(H + t)`` the iteration is ``r <- r^3``, hence with ``m = 3^k``
    ``H_k = t ((x0 + t)^m + (x0 - t)^m) / ((x0 + t)^m - (x0 - t)^m)``, whose roots in x
    are ``-x0^2 tan^2(pi (2j+1)/(2m))`` (numerator) and ``-x0^2 tan^2(pi j/m)``
    (denominator), j >= 0 resp. >= 1, up to ``(m - 1)/2`` each. In s = 1/x these give the
    zeros and poles used here (exact, rather than polynomial roots of coefficients as large
    as C(3^k, 3^k/2)); the gain is fixed by ``H_k(x0^2) = x0``. The coefficient form is
    :func:`newton_sqrt_polynomials`.
    """
    k = check_order(n_iter, "n_iter", 1)
    if k > _MAX_NEWTON_ITER:
        raise OptionError(f"n_iter must be <= {_MAX_NEWTON_ITER} (order (3^k-1)/2 = "
                          f"{(3 ** k - 1) // 2} is far beyond use), got {k}")
    x0 = float(x0)
    if not np.isfinite(x0) or x0 <= 0:
        raise OptionError(f"x0 must be > 0, got {x0!r}")
    m = 3 ** k
    d = (m - 1) // 2
    j = np.arange(d)
    x_zeros = -x0 ** 2 * np.tan(np.pi * (2 * j + 1) / (2 * m)) ** 2
    x_poles = -x0 ** 2 * np.tan(np.pi * (j + 1) / m) ** 2
    s_ref = 1.0 / x0 ** 2
    return real_cascade(1.0 / x_zeros, 1.0 / x_poles, 1.0, "newton", s_ref=s_ref,
                        value_ref=x0)
