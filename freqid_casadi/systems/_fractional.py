"""The fractional example 1/sqrt(s) and its closed loop G_D (thesis §4.2), and Moheimani's
simply-supported beam (SPEC §4; Moheimani, ASME JDSMC 122 (2000), §3, eq. 11)."""

import math

import numpy as np

from ._common import _data, _omega, _positive, _real_scalar, thesis_grid
from ..errors import DataError, OptionError

__all__ = ["sqrt_inverse", "sqrt_inverse_at", "G_D", "G_D_at", "moheimani_beam",
           "moheimani_at", "moheimani_modes", "moheimani_kopt"]


# ----------------------------------------------------------------------------- fractional


def _fractional_grid():
    return thesis_grid(500, 1e-5, 1e5)


def sqrt_inverse_at(s):
    """``1/sqrt(s)`` (principal branch).

    Parameters
    ----------
    s : array_like of complex
        Laplace variable (rad/s).

    Returns
    -------
    ndarray of complex, shape of ``s``
    """
    return 1 / np.sqrt(np.asarray(s, dtype=complex))


def sqrt_inverse(omega=None):
    """Frequency response of the fractional integrator ``1/sqrt(s)`` (thesis §4.2).

    Parameters
    ----------
    omega : array_like of float, shape (M,), optional
        Frequencies in rad/s, > 0 and strictly increasing (default: 500 log-spaced points
        from 1e-5 to 1e5 rad/s).

    Returns
    -------
    FrequencyData
        ``response = (1j*omega)**(-1/2)`` (magnitude ``omega**-0.5``, phase -45 deg),
        named ``"1/sqrt(s)"``.

    Raises
    ------
    DataError
        If ``omega`` is not a valid frequency vector.
    """
    omega = _omega(omega, _fractional_grid)
    return _data(omega, sqrt_inverse_at(1j * omega), "1/sqrt(s)")


def G_D_at(s):
    """Closed loop ``G_D(s) = 1/(1 + sqrt(s))``: ``s`` (array_like of complex, rad/s) as in
    :func:`sqrt_inverse_at`, the same branch, and a complex array of the shape of ``s``."""
    return 1 / (1 + np.sqrt(np.asarray(s, dtype=complex)))


def G_D(omega=None):
    """Frequency response of ``G_D(s) = 1/(1 + sqrt(s))`` (thesis §4.2, SPEC §4).

    Parameters
    ----------
    omega : array_like of float, shape (M,), optional
        Frequencies as in :func:`sqrt_inverse` (rad/s; default 1e-5 to 1e5 rad/s).

    Returns
    -------
    FrequencyData
        ``response[i] = G_D(1j*omega[i])``, named ``"G_D"``.

    Raises
    ------
    DataError
        As :func:`sqrt_inverse`, for an invalid ``omega``.
    """
    omega = _omega(omega, _fractional_grid)
    return _data(omega, G_D_at(1j * omega), "G_D")


# ----------------------------------------------------------------------------- Moheimani

_BEAM = {"L": 1.3, "r1": 0.075, "r2": 0.075, "rho_A": 0.6265, "EI": 5.329}


def _n_modes(n, name="n_modes"):
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise OptionError(f"{name} must be an integer >= 1, got {n!r}")
    if n < 1:
        raise OptionError(f"{name} must be >= 1, got {n}")
    return int(n)


def moheimani_modes(n_modes=30, *, L=1.3, r1=0.075, r2=0.075, rho_A=0.6265, EI=5.329):
    """Natural frequencies and residues of Moheimani's simply-supported beam.

    Parameters
    ----------
    n_modes : int, optional
        Number of modes (default 30, the "truth" model), >= 1.
    L : float, optional
        Beam length in m (default 1.3).
    r1, r2 : float, optional
        Actuator and sensor positions in m (default 0.075 both: collocated).
    rho_A : float, optional
        Mass per unit length in kg/m (default 0.6265).
    EI : float, optional
        Flexural rigidity in N m^2 (default 5.329).

    Returns
    -------
    omega_i : ndarray of float, shape (n_modes,)
        Natural frequencies in rad/s, increasing.
    F_i : ndarray of float, shape (n_modes,)
        Residues ``phi_i(r1) phi_i(r2)`` in 1/kg.

    Notes
    -----
    SPEC §4 (seed 003 §3): ``omega_i = (i pi / L)^2 sqrt(EI / rho_A)``,
    ``phi_i(r) = sqrt(2/(rho_A L)) sin(i pi r / L)``.
    """
    n = _n_modes(n_modes)
    L = _positive(L, "L")
    r1 = _real_scalar(r1, "r1")
    r2 = _real_scalar(r2, "r2")
    rho_A = _positive(rho_A, "rho_A")
    EI = _positive(EI, "EI")
    i = np.arange(1, n + 1, dtype=float)
    omega_i = (i * np.pi / L) ** 2 * math.sqrt(EI / rho_A)
    F_i = 2 / (rho_A * L) * np.sin(i * np.pi * r1 / L) * np.sin(i * np.pi * r2 / L)
    return omega_i, F_i


def moheimani_at(s, n_modes=30, **beam):
    """Modal model ``G(s) = sum_{i<=n_modes} F_i / (s^2 + omega_i^2)`` at complex ``s``.

    Parameters
    ----------
    s : array_like of complex, any shape
        Laplace variable in rad/s; ``s = +-1j*omega_i`` are (undamped) poles.
    n_modes : int, optional
        Number of modes kept (default 30).
    **beam
        Beam parameters ``L, r1, r2, rho_A, EI`` of :func:`moheimani_modes`.

    Returns
    -------
    ndarray of complex, shape of ``s``
        G(s) in m/N (displacement per force).
    """
    omega_i, F_i = moheimani_modes(n_modes, **beam)
    s = np.asarray(s, dtype=complex)
    return np.sum(F_i / (s[..., None] ** 2 + omega_i ** 2), axis=-1)


def _moheimani_grid():
    return thesis_grid(500, 1.0, 1e4)


def moheimani_beam(omega=None, n_modes=30, **beam):
    """Frequency response of Moheimani's simply-supported beam (SPEC §4, seed 003 §3).

    Parameters
    ----------
    omega : array_like of float, shape (M,), optional
        Frequencies in rad/s, > 0, strictly increasing and not exactly at a mode
        (default: 500 log-spaced points from 1 to 1e4 rad/s, which miss every mode).
    n_modes : int, optional
        Number of modes (default 30).
    **beam
        Beam parameters ``L, r1, r2, rho_A, EI`` of :func:`moheimani_modes`.

    Returns
    -------
    FrequencyData
        ``response[i] = G(1j*omega[i])`` (real-valued: the model is undamped), named
        ``"moheimani_beam"``.

    Raises
    ------
    DataError
        If ``omega`` is invalid or hits a natural frequency (the response is infinite
        there).
    """
    omega = _omega(omega, _moheimani_grid)
    omega_i, _ = moheimani_modes(n_modes, **beam)
    close = np.isclose(omega[:, None], omega_i[None, :], rtol=1e-12, atol=0)
    if close.any():
        k, i = np.argwhere(close)[0]
        raise DataError(
            f"omega[{k}]={omega[k]!r} is the natural frequency omega_{i + 1}={omega_i[i]!r} of "
            "the undamped beam, where the response is infinite; move that point")
    return _data(omega, moheimani_at(1j * omega, n_modes, **beam), "moheimani_beam")


def moheimani_kopt(n_kept, omega_c, n_modes=30, **beam):
    """Moheimani's optimal feedthrough term for an ``n_kept``-mode truncation.

    Parameters
    ----------
    n_kept : int
        Number N of modes kept in the truncated model G_r, ``1 <= n_kept < n_modes``.
    omega_c : float
        Bandwidth in rad/s, ``0 < omega_c < omega_{N+1}``.
    n_modes : int, optional
        Number of modes of the "truth" model (default 30).
    **beam
        Beam parameters ``L, r1, r2, rho_A, EI`` of :func:`moheimani_modes`.

    Returns
    -------
    float
        K_opt in m/N; ``G_r(s) + K_opt`` is the corrected truncated model.

    Raises
    ------
    OptionError
        If ``n_kept`` or ``omega_c`` is out of range.

    Notes
    -----
    Seed 003 eq. (11), SPEC §4::

        K_opt = 1/(2 omega_c) sum_{i=N+1}^{n_modes} (F_i/omega_i) ln((omega_i + omega_c)
                                                                    / (omega_i - omega_c)),

    the closed form of ``(1/(2 omega_c)) int_{-omega_c}^{omega_c} Re(G - G_r)(j omega)
    d omega`` (SPEC §6).
    """
    n = _n_modes(n_modes)
    n_kept = _n_modes(n_kept, "n_kept")
    if n_kept >= n:
        raise OptionError(
            f"n_kept must be < n_modes={n} (no truncated modes otherwise), got {n_kept}")
    omega_c = _positive(omega_c, "omega_c")
    omega_i, F_i = moheimani_modes(n, **beam)
    if omega_c >= omega_i[n_kept]:
        raise OptionError(
            f"omega_c={omega_c!r} rad/s must be below the first truncated mode "
            f"omega_{n_kept + 1}={omega_i[n_kept]!r} rad/s; lower omega_c or keep more modes")
    wi, Fi = omega_i[n_kept:], F_i[n_kept:]
    # ln((w + wc)/(w - wc)) = 2 artanh(wc / w), accurate for wc << w
    return float(np.sum(Fi / wi * 2 * np.arctanh(omega_c / wi)) / (2 * omega_c))
