"""Complex arithmetic on (re, im) pairs for numpy arrays and CasADi SX/MX (layer L0).

CasADi's symbolic types have no complex dtype, so every formula of the model is written
once with these helpers and evaluated both on numpy floats and on CasADi symbols
(docs/style.md §1.2). A pair ``z = (re, im)`` holds the real and imaginary parts; each part may
be a Python float, a numpy array or a CasADi expression. Only ``+ - * /``, ``cos`` and
``sin`` are used, so broadcasting follows the operands' own rules.
"""

import numpy as np

__all__ = ["mul", "div", "inv", "expj", "scale", "abs2", "from_complex", "to_complex",
           "jw_power", "times_jw_power"]


def mul(z1, z2):
    """Product ``z1 * z2`` of two (re, im) pairs."""
    a, b = z1
    c, d = z2
    return (a * c - b * d, a * d + b * c)


def div(z1, z2):
    """Quotient ``z1 / z2`` of two (re, im) pairs (no division by |z2|^2 twice)."""
    a, b = z1
    c, d = z2
    den = c * c + d * d
    return ((a * c + b * d) / den, (b * c - a * d) / den)


def inv(z):
    """Reciprocal ``1 / z`` of a (re, im) pair."""
    c, d = z
    den = c * c + d * d
    return (c / den, -d / den)


def expj(phi, cos=np.cos, sin=np.sin):
    """``exp(j*phi)`` for real ``phi`` as a pair; pass ``ca.cos``/``ca.sin`` for symbols."""
    return (cos(phi), sin(phi))


def scale(k, z):
    """Real scalar times a pair."""
    return (k * z[0], k * z[1])


def abs2(z):
    """Squared modulus ``|z|^2`` of a pair."""
    return z[0] * z[0] + z[1] * z[1]


def from_complex(x):
    """Split a complex numpy array into an (re, im) pair of float arrays."""
    x = np.asarray(x)
    return (np.real(x).astype(float), np.imag(x).astype(float))


def to_complex(z):
    """Join a numeric (re, im) pair into one complex numpy array."""
    return np.asarray(z[0], dtype=float) + 1j * np.asarray(z[1], dtype=float)


def jw_power(omega, k):
    """``(j omega)^k`` for an integer ``k``: the unit ``j^k`` times the real ``omega^k``.

    Parameters
    ----------
    omega : array_like of float
        Frequencies (rad/s).
    k : int
        The power.

    Returns
    -------
    ndarray of complex, like ``omega``
    """
    omega = np.asarray(omega, dtype=float)
    return (1, 1j, -1, -1j)[int(k) % 4] * omega ** float(k)


def times_jw_power(x, omega, k):
    """``x * (j omega)^k``: the data with ``k`` poles at the origin removed.

    Parameters
    ----------
    x : array_like of complex
        A response at ``omega``.
    omega : array_like of float
        Frequencies (rad/s), broadcastable with ``x``.
    k : int
        Poles at the origin (negative: zeros).

    Returns
    -------
    ndarray of complex
        ``x`` itself for k = 0 and ``x * (1j * omega)`` for k = 1 (the integrator's
        arithmetic, bit for bit), else ``x * jw_power(omega, k)``.
    """
    if k == 0:
        return x
    if k == 1:
        return x * (1j * np.asarray(omega, dtype=float))
    return x * jw_power(omega, k)
