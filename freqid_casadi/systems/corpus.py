"""A seeded corpus of synthetic frequency responses, the families users bring (issue 26).

:func:`corpus` returns ``n`` :class:`CorpusCase` records; case ``i`` of seed ``s`` is drawn
from its own generator ``numpy.random.default_rng([s, i])`` (:func:`case`), so a case is
the same in any corpus that holds it, and a subset (``corpus(60)``) is the first cases of
the full one. Families (:data:`FAMILIES`, cycled so each is equally represented):

``in-class``
    A product of 1-4 stable, minimum-phase sections (the fitted model class), positive gain.
``modal-collocated``
    ``sum_k r_k / (s^2 + 2 zeta_k w_k s + w_k^2)``, r_k > 0 (interlaced zeros), 2-5 modes,
    sometimes one mode outside the band.
``modal-feedthrough``
    The same plus a feedthrough D (its zeros move above the last mode).
``modal-noncollocated``
    Residues of both signs (a non-collocated sensor): zeros may leave the left half plane
    (``in_class`` says whether they do), with or without a feedthrough.
``negative-gain``
    Minus an in-class product or a collocated modal sum (a sign-inverted sensor).
``integrator``
    ``1/s^k`` (k = 1 or 2) times an in-class product, which a default fit does not declare.
``accelerance``
    ``s^2`` times a collocated receptance (two zeros at the origin).
``high-pass``
    ``s^2 / (s^2 + 2 zeta_0 w_0 s + w_0^2)`` times 1-2 sections.
``band-pass``
    ``w_0 s / (s^2 + 2 zeta_0 w_0 s + w_0^2)`` times 0-2 sections (one zero at the origin).

Every case draws: the band (1-3.5 decades log spaced, 0.7-1.5 decades linear, anywhere
within 1e-3 ... 1e9 rad/s), the number of points (50-5000; 94 % of the cases 50-300,
log-uniform, the others 1000-5000), dampings 0.2 %-15 % (raised where needed so each
resonance spans at least one sample), a delay (half none; the others from a small phase lag
up to 0.85 of the aliasing limit ``pi / max(dw)``), multiplicative complex Gaussian noise
(a fifth noiseless, the others 0.1 %-5 % RMS, flat or varying by up to 10x over the band)
and, for half the noisy cases, the variance given as ``data.weights = 1 / sigma_i^2``.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..core.data import FrequencyData
from ..errors import OptionError

__all__ = ["FAMILIES", "CorpusCase", "CorpusSystem", "case", "corpus", "MAX_POINTS",
           "DAMPING_RANGE", "NOISE_MAX"]

FAMILIES = ("in-class", "modal-collocated", "modal-feedthrough", "modal-noncollocated",
            "negative-gain", "integrator", "accelerance", "high-pass", "band-pass")
#: Most points a case has.
MAX_POINTS = 5000
#: Range the damping ratios are drawn from (log-uniform).
DAMPING_RANGE = (0.002, 0.15)
#: Largest noise RMS (relative).
NOISE_MAX = 0.05
_W_MIN, _W_MAX = 1e-3, 1e9


@dataclass(frozen=True, eq=False)
class CorpusSystem:
    """The true system of a case: ``G(s) = g s^q R(s) M(s) exp(-h s)``.

    Attributes
    ----------
    gain : float
        g (its sign is part of the system).
    origin_power : int
        q: zeros (q > 0) or poles (q < 0) at the origin.
    zeros, poles : ndarray of complex
        Roots of R, in rad/s, paired in order as (s - z_k)/(s - p_k) (equal lengths; a
        section with a constant numerator has its zero pair at infinity, given as nan).
    modes : ndarray of float, shape (K, 3)
        ``(r_k, zeta_k, w_k)`` of ``M(s) = D + sum_k r_k w_k^2 / (s^2 + 2 zeta_k w_k s +
        w_k^2)`` (M = 1 without modes).
    feedthrough : float
        D.
    delay : float
        h, seconds.
    """

    gain: float
    origin_power: int
    zeros: np.ndarray
    poles: np.ndarray
    modes: np.ndarray
    feedthrough: float
    delay: float

    def at(self, s):
        """G at complex ``s`` (array), same shape."""
        s = np.asarray(s, complex)
        g = self.gain * s ** self.origin_power * np.exp(-self.delay * s)
        for z, p in zip(self.zeros, self.poles):
            g = g * ((s - z) if np.isfinite(z) else -p) / (s - p)
        if len(self.modes):
            m = np.full(s.shape, self.feedthrough, complex)
            for r, zeta, w in self.modes:
                m += r * w * w / (s * s + 2 * zeta * w * s + w * w)
            g = g * m
        return g

    def __call__(self, omega):
        """G(j omega), omega in rad/s (array), complex of the same shape."""
        return self.at(1j * np.asarray(omega, float))

    def finite_zeros(self):
        """All zeros except those at the origin (rad/s), from R and the modal sum."""
        out = [z for z in self.zeros if np.isfinite(z)]
        if len(self.modes):
            w_ref = float(np.median(self.modes[:, 2]))
            dens = [np.poly1d([1.0, 2 * zt * w / w_ref, (w / w_ref) ** 2])
                    for _, zt, w in self.modes]
            num = np.poly1d([self.feedthrough])
            for d in dens:
                num = num * d
            for k, (r, _, w) in enumerate(self.modes):
                term = np.poly1d([r * (w / w_ref) ** 2])
                for j, d in enumerate(dens):
                    if j != k:
                        term = term * d
                num = num + term
            out += list(np.roots(num.coeffs) * w_ref) if num.order > 0 else []
        return np.asarray(out, complex)


@dataclass(frozen=True, eq=False)
class CorpusCase:
    """One corpus case: the data, its true system and what is known about it.

    Attributes
    ----------
    name : str
        ``"<family>-<index>"``.
    index, seed : int
    family : str
        One of :data:`FAMILIES`.
    data : FrequencyData
        The (noisy) samples; ``data.weights = 1 / sigma_i^2`` (``|G|^2 / variance``, as
        :mod:`freqid_casadi.experiment` writes them) when ``variance_given``.
    truth : CorpusSystem
        Callable ``omega (rad/s) -> G(j omega)``, noiseless.
    n_sections : int
        Second-order sections of the smallest model of the class that holds the system
        (poles at the origin not counted; outside the class, the sections of its poles).
    delay : float
        True delay, seconds.
    noise : float
        RMS over the points of the relative noise sigma_i (0: exact data).
    sigma : ndarray of float, shape (M,)
        The relative noise RMS at each point.
    variance_given : bool
    gain_sign : int
        Sign of the system's low-frequency gain once its poles and zeros at the origin
        are removed (+1 or -1).
    in_class : bool
        The model class of a default fit holds the system: no pole at the origin and no
        zero in the open right half plane (zeros at the origin are at a bound: inside).
    integrators : int
        Poles at the origin.
    zeros_at_origin : int
    nmp_zeros : int
        Zeros in the open right half plane.
    spacing : {"log", "linear"}
    min_damping : float
        The smallest damping ratio of the system's poles.
    """

    name: str
    index: int
    seed: int
    family: str
    data: FrequencyData
    truth: CorpusSystem
    n_sections: int
    delay: float
    noise: float
    sigma: np.ndarray
    variance_given: bool
    gain_sign: int
    in_class: bool
    integrators: int
    zeros_at_origin: int
    nmp_zeros: int
    spacing: str
    min_damping: float

    @property
    def n_points(self):
        return self.data.n_points

    def resampled(self, n_points, rng):
        """The case's system sampled at ``n_points`` frequencies over its band, as the
        case spaces them, its relative noise profile interpolated in log frequency.

        Parameters
        ----------
        n_points : int
            Frequencies, >= 2.
        rng : numpy.random.Generator
            Draws the complex Gaussian relative noise (``n_points`` real, then as many
            imaginary parts).

        Returns
        -------
        FrequencyData
            rad/s, shape (n_points,); ``weights = 1 / sigma^2`` when the case's variance
            is given (and every sigma > 0).
        """
        w = self.data.omega
        omega = (np.linspace(w[0], w[-1], n_points) if self.spacing == "linear"
                 else np.geomspace(w[0], w[-1], n_points))
        sigma = np.interp(np.log(omega), np.log(w), self.sigma)
        return _noisy(omega, self.truth(omega), sigma, rng,
                      self.variance_given and bool(np.all(sigma > 0)), self.name)


def corpus(n=300, seed=0, *, families=None, max_points=MAX_POINTS):
    """The first ``n`` cases of the corpus of ``seed``.

    Parameters
    ----------
    n : int
        Number of cases (>= 1).
    seed : int
    families : sequence of str, optional
        Keep only these families (the cases keep their indices in the full corpus).
    max_points : int
        Cap on the points of every case (>= 50; smaller than :data:`MAX_POINTS` gives
        cheaper, different cases, e.g. for a test subset).

    Returns
    -------
    tuple of CorpusCase
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise OptionError(f"n must be an integer >= 1, got {n!r}")
    if families is not None:
        bad = [f for f in families if f not in FAMILIES]
        if bad:
            raise OptionError(f"unknown families {bad}: choose from {FAMILIES}")
    cases = (case(i, seed, max_points=max_points) for i in range(int(n)))
    return tuple(c for c in cases if families is None or c.family in families)


def _noisy(omega, g, sigma, rng, given, name):
    """FrequencyData ``g (1 + sigma n)``, ``n`` complex Gaussian of unit RMS drawn from
    ``rng`` (the real parts, then the imaginary ones); ``weights = 1 / sigma^2`` (``|G|^2 /
    variance``, as measured) when the variance is ``given``."""
    n = (rng.standard_normal(omega.size) + 1j * rng.standard_normal(omega.size)) / math.sqrt(2)
    weights = 1 / sigma ** 2 if given else None
    return FrequencyData(omega, g * (1 + sigma * n), name, weights)


def case(index, seed=0, *, max_points=MAX_POINTS):
    """Case ``index`` of the corpus of ``seed`` (family ``FAMILIES[index % 9]``).

    Parameters
    ----------
    index, seed : int
        ``index >= 0``.
    max_points : int
        Cap on the number of points (50 ... 5000).

    Returns
    -------
    CorpusCase
    """
    for name, v in (("index", index), ("seed", seed), ("max_points", max_points)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise OptionError(f"{name} must be an integer >= 0, got {v!r}")
    if not 50 <= max_points <= MAX_POINTS:
        raise OptionError(f"max_points must be in [50, {MAX_POINTS}], got {max_points}")
    rng = np.random.default_rng([int(seed), int(index)])
    family = FAMILIES[index % len(FAMILIES)]
    omega, spacing = _grid(rng, max_points)
    system, n_sec = _BUILDERS[family](rng, omega)
    system = _with_delay(rng, system, omega)
    sigma = _noise_profile(rng, omega)
    noise = math.sqrt(float(np.mean(sigma ** 2)))
    given = bool(noise > 0 and rng.random() < 0.5)
    name = f"{family}-{index}"
    data = _noisy(omega, system(omega), sigma, rng, given, name)
    zeros = system.finite_zeros()
    nmp = int(np.sum(zeros.real > 1e-9 * np.abs(zeros)))
    q = system.origin_power
    sign = _gain_sign(system, zeros)
    sigma = sigma.copy()
    sigma.flags.writeable = False
    return CorpusCase(
        name=name, index=int(index), seed=int(seed), family=family, data=data, truth=system,
        n_sections=n_sec, delay=system.delay, noise=noise, sigma=sigma, variance_given=given,
        gain_sign=sign, in_class=bool(nmp == 0 and q >= 0), integrators=max(-q, 0),
        zeros_at_origin=max(q, 0), nmp_zeros=nmp, spacing=spacing,
        min_damping=_min_damping(system))


# -- drawing ----------------------------------------------------------------------------

def _loguniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _grid(rng, max_points):
    """The frequencies of a case (rad/s) and their spacing."""
    spacing = "log" if rng.random() < 0.7 else "linear"
    u = rng.random()
    m = (_loguniform(rng, 50, 300) if u < 0.94 else _loguniform(rng, 1000, MAX_POINTS))
    m = int(min(max_points, max(50, round(m))))
    if spacing == "log":
        decades = rng.uniform(1.0, 3.5)
        lo = 10 ** rng.uniform(math.log10(_W_MIN), math.log10(_W_MAX) - decades)
        omega = np.logspace(math.log10(lo), math.log10(lo) + decades, m)
    else:
        decades = rng.uniform(0.7, 1.5)
        hi = 10 ** rng.uniform(math.log10(_W_MIN) + decades, math.log10(_W_MAX))
        omega = np.linspace(hi / m, hi, m) if decades >= math.log10(m) else \
            np.linspace(hi * 10 ** -decades, hi, m)
    return omega, spacing


def _local_step(omega, w):
    """Relative spacing dw / w of the grid near ``w`` (outside the band: at its edge)."""
    i = int(np.clip(np.searchsorted(omega, w), 1, omega.size - 1))
    return float((omega[i] - omega[i - 1]) / omega[i - 1])


def _damping(rng, omega, w):
    """A damping ratio in :data:`DAMPING_RANGE`, raised so the resonance at ``w`` spans at
    least one sample (half-power bandwidth 2 zeta w >= local dw)."""
    zeta = _loguniform(rng, *DAMPING_RANGE)
    return float(min(0.5, max(zeta, 0.5 * _local_step(omega, w))))


def _frequencies(rng, omega, k, margin=0.08):
    """``k`` frequencies log-uniform inside the band (away from its edges by ``margin``
    of its width in decades), at least 12 % apart; fewer if they do not fit."""
    lo, hi = math.log10(omega[0]), math.log10(omega[-1])
    a, b = lo + margin * (hi - lo), hi - margin * (hi - lo)
    out = []
    for _ in range(50 * k):
        if len(out) == k:
            break
        w = 10 ** rng.uniform(a, b)
        if all(abs(math.log(w / v)) > math.log(1.12) for v in out):
            out.append(w)
    return sorted(out)


def _pair(w, zeta):
    r = -zeta * w + 1j * w * math.sqrt(max(1 - zeta * zeta, 0.0))
    return (r, np.conj(r))


def _sections(rng, omega, k):
    """``k`` unit-DC minimum-phase sections: (zeros, poles) root lists."""
    zeros, poles = [], []
    for wp in _frequencies(rng, omega, k):
        zp = _damping(rng, omega, wp)
        poles += _pair(wp, zp)
        if rng.random() < 0.25:                 # a constant numerator: zero pair at infinity
            zeros += [np.nan, np.nan]
            continue
        wz = wp * 10 ** rng.uniform(-0.3, 0.3)
        zeros += _pair(wz, _damping(rng, omega, wz))
    return zeros, poles


def _dc(zeros, poles):
    """The factor that gives the paired sections unit DC gain."""
    g = 1.0
    for z, p in zip(zeros, poles):
        g *= abs(p) / (abs(z) if np.isfinite(z) else 1.0)
        g /= 1.0 if np.isfinite(z) else abs(p)
    return g


def _system(rng, zeros=(), poles=(), modes=(), d=0.0, q=0, sign=1):
    zeros, poles = np.asarray(zeros, complex), np.asarray(poles, complex)
    gain = sign * _loguniform(rng, 1e-3, 1e3) * _dc(zeros, poles)
    return CorpusSystem(gain=gain, origin_power=q, zeros=zeros, poles=poles,
                        modes=np.asarray(modes, float).reshape(-1, 3), feedthrough=float(d),
                        delay=0.0)


def _modes(rng, omega, k, signs="positive", out_of_band=None):
    """``k`` in-band modes ``(r, zeta, w)`` (residues of unit static sum scale), and maybe
    one outside the band."""
    ws = _frequencies(rng, omega, k)
    if out_of_band is None:
        out_of_band = rng.random() < 0.3
    if out_of_band:
        ws.append(omega[-1] * rng.uniform(2, 10) if rng.random() < 0.7
                  else omega[0] / rng.uniform(2, 10))
    modes = []
    for j, w in enumerate(sorted(ws)):
        r = _loguniform(rng, 0.2, 1.0) / len(ws)
        if signs == "mixed" and j > 0 and rng.random() < 0.5:
            r = -r
        modes.append((r, _damping(rng, omega, w), w))
    return modes


def _in_class(rng, omega, sign=1):
    k = int(rng.integers(1, 5))
    z, p = _sections(rng, omega, k)
    return _system(rng, z, p, sign=sign), len(p) // 2


def _collocated(rng, omega, feedthrough=False, sign=1):
    modes = _modes(rng, omega, int(rng.integers(2, 6)))
    d = _loguniform(rng, 0.05, 0.5) * sum(m[0] for m in modes) if feedthrough else 0.0
    return _system(rng, modes=modes, d=d, sign=sign), len(modes)


def _noncollocated(rng, omega):
    modes = _modes(rng, omega, int(rng.integers(2, 6)), signs="mixed")
    d = (_loguniform(rng, 0.05, 0.5) * sum(abs(m[0]) for m in modes)
         * (1 if rng.random() < 0.5 else -1) if rng.random() < 0.5 else 0.0)
    return _system(rng, modes=modes, d=d), len(modes)


def _negative(rng, omega):
    if rng.random() < 0.5:
        return _in_class(rng, omega, sign=-1)
    return _collocated(rng, omega, feedthrough=rng.random() < 0.5, sign=-1)


def _integrator(rng, omega):
    k = int(rng.integers(1, 4))
    z, p = _sections(rng, omega, k)
    q = -1 if rng.random() < 0.6 else -2
    return _system(rng, z, p, q=q), len(p) // 2


def _accelerance(rng, omega):
    modes = _modes(rng, omega, int(rng.integers(2, 5)))
    sys_ = _system(rng, modes=modes, q=2)
    # s^2 * receptance: scale so |G| is O(gain) in the band
    w0 = math.sqrt(omega[0] * omega[-1])
    return _rescale(sys_, 1 / w0 ** 2), len(modes)


def _highpass(rng, omega, order=2):
    w0 = _frequencies(rng, omega, 1, margin=0.05)[0]
    z0 = rng.uniform(0.3, 0.7) if order == 2 else rng.uniform(0.2, 0.7)
    k = int(rng.integers(1, 3)) if order == 2 else int(rng.integers(0, 3))
    z, p = _sections(rng, omega, k)
    z, p = [np.nan, np.nan] + z, list(_pair(w0, z0)) + p
    sys_ = _system(rng, z, p, q=order)
    # the dc factor made the (nan, pair) section w0^2 / (s^2 ...): divide w0^order back out
    return _rescale(sys_, 1 / w0 ** order), len(p) // 2


def _bandpass(rng, omega):
    return _highpass(rng, omega, order=1)


def _rescale(system, factor):
    return CorpusSystem(system.gain * factor, system.origin_power, system.zeros,
                        system.poles, system.modes, system.feedthrough, system.delay)


_BUILDERS = {
    "in-class": _in_class,
    "modal-collocated": lambda rng, w: _collocated(rng, w),
    "modal-feedthrough": lambda rng, w: _collocated(rng, w, feedthrough=True),
    "modal-noncollocated": _noncollocated,
    "negative-gain": _negative,
    "integrator": _integrator,
    "accelerance": _accelerance,
    "high-pass": _highpass,
    "band-pass": _bandpass,
}


def _with_delay(rng, system, omega):
    """Half the cases without a delay; the others with a phase lag at the top of the band
    from 0.1 rad, or (a third of them) 0.1-0.85 of the aliasing limit pi / max(dw)."""
    u = rng.random()
    if u < 0.5:
        h = 0.0
    elif u < 5 / 6:
        h = _loguniform(rng, 0.1, 3.0) / omega[-1]
    else:
        h = rng.uniform(0.1, 0.85) * math.pi / float(np.max(np.diff(omega)))
    return CorpusSystem(system.gain, system.origin_power, system.zeros, system.poles,
                        system.modes, system.feedthrough, float(h))


def _noise_profile(rng, omega):
    """Relative noise RMS per point: a fifth zero, else 0.1 %-5 % flat or sloped (up to
    10x over the band, RMS kept)."""
    if rng.random() < 0.2:
        return np.zeros(omega.size)
    sigma = _loguniform(rng, 1e-3, NOISE_MAX)
    t = np.linspace(-0.5, 0.5, omega.size)
    shape = 10 ** (rng.uniform(-1, 1) * t) if rng.random() < 0.5 else np.ones(omega.size)
    shape /= math.sqrt(float(np.mean(shape ** 2)))
    return sigma * shape


def _gain_sign(system, zeros):
    """Sign of the low-frequency gain with the roots at the origin removed."""
    s = 1e-9 * min([abs(p) for p in system.poles] + [m[2] for m in system.modes]
                   + [abs(z) for z in zeros if abs(z) > 0] + [1.0])
    reduced = CorpusSystem(system.gain, 0, system.zeros, system.poles, system.modes,
                           system.feedthrough, 0.0)
    return 1 if reduced.at(np.array([s]))[0].real > 0 else -1


def _min_damping(system):
    zs = [-p.real / abs(p) for p in system.poles]
    zs += [m[1] for m in system.modes]
    return float(min(zs)) if zs else float("nan")
