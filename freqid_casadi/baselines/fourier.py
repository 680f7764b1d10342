"""Fourier-transform based approximation (Gu, Khargonekar & Lee 1989), layer L4.

The thesis's "Method III" (SPEC §6): map the right half plane to the exterior of the unit
disc by the bilinear transform, sample the plant on the unit circle, take an inverse FFT to
get the impulse response of the discrete-time equivalent, truncate it to an FIR filter, and
reduce the FIR by balanced truncation (SLICOT) before mapping back to continuous time.
"""

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._ssmodel import StateSpaceModel, ab09ad, bilinear_d2c, check_order
from .subspace import default_bilinear_T

__all__ = ["fourier", "interpolate_response", "fourier_impulse_response"]


def interpolate_response(data):
    """A callable ``omega -> response`` interpolating FrequencyData.

    log|G| and the unwrapped phase are interpolated linearly in log(omega); outside the
    data band both are held at their end values (so the extrapolation is crude: pass the
    plant itself as a callable to :func:`fourier` whenever it is known).

    Parameters
    ----------
    data : FrequencyData

    Returns
    -------
    callable
        ``f(omega)`` for ``omega`` >= 0 (rad/s), complex ndarray like ``omega``.
    """
    if not isinstance(data, FrequencyData):
        raise DataError(f"data must be a FrequencyData, got {type(data).__name__}")
    logw = np.log(data.omega)
    logmag = np.log(np.abs(data.response))
    phase = np.unwrap(np.angle(data.response))

    def response(omega):
        omega = np.asarray(omega, float)
        lw = np.log(np.maximum(omega, np.finfo(float).tiny))
        return np.exp(np.interp(lw, logw, logmag) + 1j * np.interp(lw, logw, phase))

    return response


def fourier_impulse_response(fun, n_fft, T):
    """Impulse response ``h_k`` (k = 0..n_fft-1) of ``Gd(z) = G(s)``, z = (1+sT/2)/(1-sT/2).

    The circle is sampled at the half-shifted angles ``theta_l = pi (2 l + 1) / n_fft``,
    i.e. at ``omega_l = (2/T) tan(theta_l / 2)``, which never hits omega = 0 or infinity
    (an integrator or an undefined value at infinity never has to be evaluated); the lower
    half circle is the complex conjugate. Then
    ``h_k = (1/n_fft) sum_l Gd(e^{j theta_l}) e^{j theta_l k}``, which equals the true
    coefficients up to the aliasing ``sum_{r != 0} (-1)^r h_{k + r n_fft}``.

    Parameters
    ----------
    fun : callable
        ``omega (ndarray, rad/s) -> complex ndarray`` of the same size.
    n_fft : int
        Samples on the unit circle (even).
    T : float
        Bilinear-map period, s.

    Returns
    -------
    ndarray of float, shape (n_fft,)
    """
    half = n_fft // 2
    theta = np.pi * (2 * np.arange(half) + 1) / n_fft
    omega = (2.0 / T) * np.tan(theta / 2)
    Gu = np.asarray(fun(omega), dtype=complex).reshape(-1)
    if Gu.size != half:
        raise DataError(f"the response callable returned {Gu.size} values for {half} "
                        "frequencies; it must map an array of omega to an array of the same size")
    if not np.all(np.isfinite(Gu)):
        i = int(np.flatnonzero(~np.isfinite(Gu))[0])
        raise DataError(f"the response is not finite at omega={omega[i]!r} rad/s; the Fourier "
                        "method needs a plant that is bounded on the whole imaginary axis")
    Gfull = np.concatenate([Gu, np.conj(Gu[::-1])])           # theta_l, l = 0..n-1
    k = np.arange(n_fft)
    h = np.exp(1j * np.pi * k / n_fft) * np.fft.ifft(Gfull)
    return h.real


def fourier(data_fun_or_data, order, *, n_fft=1024, T=None, n_fir=None):
    """Fourier-transform based model of a given order (no delay).

    Parameters
    ----------
    data_fun_or_data : FrequencyData or callable
        Either a callable ``omega -> response`` (omega: ndarray of float, rad/s, >= 0;
        returns complex ndarray of the same shape) giving the stable plant on the whole
        imaginary axis, or FrequencyData, which is interpolated by
        :func:`interpolate_response` (constant magnitude and phase outside the band).
    order : int
        Model order n >= 1.
    n_fft : int, optional
        Number of samples on the unit circle (even, >= 4). Default 1024.
    T : float, optional
        Bilinear-map period (s). Default: ``2 / geometric mean(omega)`` for data
        (:func:`~freqid_casadi.baselines.subspace.default_bilinear_T`), 2.0 (centre at
        1 rad/s) for a callable.
    n_fir : int, optional
        Length of the FIR kept (coefficients h_0 .. h_{n_fir-1}); default ``n_fft // 2``,
        so that the aliased half of the inverse FFT is discarded. ``order < n_fir <= n_fft``.

    Returns
    -------
    StateSpaceModel
        Continuous time, ``delay = 0``, ``name = "fourier"``.

    Raises
    ------
    DataError, OptionError

    Notes
    -----
    Gu, Khargonekar & Lee, IEEE TAC 34 (1989) 610-618 (SPEC §6):
    ``Gd(z) = G((2/T)(z - 1)/(z + 1)) = sum_k h_k z^{-k}``; the FIR
    ``h_0 + sum_{k=1}^{N-1} h_k z^{-k}`` has the shift realisation ``A`` = down-shift,
    ``B = e_1``, ``C = [h_1 .. h_{N-1}]``, ``D = h_0``; SLICOT AB09AD (discrete time,
    square-root balance & truncate) reduces it to ``order`` states (python-control's
    ``balred`` is continuous-time only), and :func:`bilinear_d2c` maps it back. The
    bilinear map preserves the H-infinity norm, so the discrete-time error bound
    ``2 sum(discarded HSV) + FIR tail`` holds for the continuous model too.
    """
    n = check_order(order)
    n_fft = check_order(n_fft, "n_fft", 4)
    if n_fft % 2:
        raise OptionError(f"n_fft must be even, got {n_fft}")
    if isinstance(data_fun_or_data, FrequencyData):
        fun = interpolate_response(data_fun_or_data)
        T = default_bilinear_T(data_fun_or_data.omega) if T is None else T
    elif callable(data_fun_or_data):
        fun = data_fun_or_data
        T = 2.0 if T is None else T
    else:
        raise DataError("data_fun_or_data must be FrequencyData or a callable omega -> "
                        f"response, got {type(data_fun_or_data).__name__}")
    T = float(T)
    if not np.isfinite(T) or T <= 0:
        raise OptionError(f"T must be a positive number of seconds, got {T!r}")
    n_fir = n_fft // 2 if n_fir is None else check_order(n_fir, "n_fir", 2)
    if not n < n_fir <= n_fft:
        raise OptionError(f"need order < n_fir <= n_fft, got order={n}, n_fir={n_fir}, "
                          f"n_fft={n_fft}; increase n_fft")
    h = fourier_impulse_response(fun, n_fft, T)[:n_fir]
    N = n_fir - 1                                              # states of the FIR
    A = np.eye(N, k=-1)
    B = np.zeros((N, 1))
    B[0, 0] = 1.0
    C = h[1:].reshape(1, N)
    Ar, Br, Cr, _ = ab09ad(A, B, C, n, "D")
    Ac, Bc, Cc, Dc = bilinear_d2c(Ar, Br, Cr, h[0], T)
    return StateSpaceModel(Ac, Bc, Cc, Dc, 0.0, "fourier")
