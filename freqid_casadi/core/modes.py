"""Modal parameters of fitted models and the stabilization diagram (layer L5).

A mode is a pair of complex-conjugate poles ``p = -zeta omega_n + j omega_n sqrt(1 - zeta^2)``
of the (shared) denominator; its mode-shape coefficient in channel ``c`` is the residue of
that channel's model at ``p``, ``lim_{s -> p} (s - p) G_c(s)`` (delay and integrator
included). :func:`modes` gives them for one model, a :class:`~freqid_casadi.fitting.fit.FitResult`
or a :class:`~freqid_casadi.modal.shared.SharedFitResult`; :func:`stabilization` fits a range of
orders and marks every pole as new, stable in frequency, or stable in frequency and damping
against the previous order (SDynPy's tolerances 1 % and 10 % by default).
"""

import csv
import io
from dataclasses import dataclass

import numpy as np

from .._textio import atomic_write_text
from ..errors import DataError, OptionError
from .model import RationalDelayModel

__all__ = ["Mode", "Modes", "modes", "modes_of_models", "modes_csv", "modes_markdown",
           "write_modes", "STATUSES", "ModeShapes", "mode_shapes", "mac", "shapes_csv",
           "REAL_MPC", "resolution_notes"]

STATUSES = ("new", "stable-frequency", "stable-frequency-damping")
#: Modal phase collinearity from which a mode's shape counts as real (its modal constants
#: lie on one line through 0 in the complex plane up to this); below it the shape stays
#: complex in :attr:`ModeShapes.shapes`.
REAL_MPC = 0.9


@dataclass(frozen=True)
class Mode:
    """One mode of a fitted model.

    Attributes
    ----------
    omega_n : float
        Natural frequency |p| in rad/s.
    frequency_hz : float
        ``omega_n / (2 pi)`` in Hz.
    zeta : float
        Damping ratio ``-Re p / |p|`` (dimensionless).
    residues : tuple of complex, length C
        Residue of each channel's model at the pole p (mode-shape coefficients, in the
        channel's units times rad/s).
    pole : complex
        The pole with ``Im p > 0`` (rad/s).
    omega_n_std, zeta_std : float or None
        Standard uncertainties (rad/s, dimensionless); None until computed.
    """

    omega_n: float
    frequency_hz: float
    zeta: float
    residues: tuple
    pole: complex
    omega_n_std: float = None
    zeta_std: float = None


class Modes(tuple):
    """A tuple of :class:`Mode` that is also callable (returning itself), so that
    ``res.modes`` and ``res.modes()`` mean the same for a
    :class:`~freqid_casadi.fitting.fit.FitResult` and a
    :class:`~freqid_casadi.modal.shared.SharedFitResult` (the one was a method, the other
    a field): ``len(res.modes)``, ``res.modes[0].omega_n``, ``for m in res.modes()`` all
    work on both. Equal to the plain tuple of the same modes.

    Parameters
    ----------
    iterable : iterable of Mode, optional
        The modes, by increasing frequency.
    """

    __slots__ = ()

    def __call__(self):
        """The modes themselves (the spelling of a method call)."""
        return self

    def __repr__(self):
        return f"Modes({tuple.__repr__(self)})"


def _residue(model, pole, j):
    """Residue of ``model`` at ``pole``, a root of its denominator section ``j``: the
    product of its factors, or, where that product leaves float64's range midway (a
    model of extreme coefficients), the exponential of the sum of their logarithms."""
    k = model.origin_order
    nums, dens = [np.exp(-pole * model.delay) * model.gain], [pole ** k if k != 1 else pole]
    for i, (a, zn, wn, b, zd, wd) in enumerate(model.sections()):
        nums.append(a * pole ** 2 + 2 * zn * wn * pole + wn ** 2)
        dens.append(b * (pole - np.conj(pole)) if i == j else
                    b * pole ** 2 + 2 * zd * wd * pole + wd ** 2)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        val = nums[0]
        if k:
            val /= dens[0]
        for num, den in zip(nums[1:], dens[1:]):
            val *= num
            val /= den
        if not np.isfinite(val):
            val = np.exp(np.sum(np.log(np.asarray(nums, complex)))
                         - np.sum(np.log(np.asarray(dens[0 if k else 1:], complex))))
    return complex(val)


#: Relative difference below which a section's numerator equals its denominator.
IDENTITY_RTOL = 1e-9


def _identity(section):
    """True when a section's numerator ``(a, zeta_n, omega_n)`` equals its denominator
    ``(b, zeta_d, omega_d)`` to :data:`IDENTITY_RTOL`: a factor 1, no pole of the model
    (the sequential loop parks such sections when the data are explained with fewer)."""
    num, den = np.asarray(section[:3], float), np.asarray(section[3:], float)
    return bool(np.all(np.abs(num - den) <= IDENTITY_RTOL * np.maximum(np.abs(den), 1e-300)))


def modes_of_models(models, n_shared=None):
    """The underdamped poles of the first model's denominator sections (shared by all
    ``models``) with every model's residue, by increasing frequency. A section whose
    numerator equals its denominator in every model (a factor 1: its zeros cancel its
    poles) gives no mode.

    Parameters
    ----------
    models : sequence of RationalDelayModel (second-order basis, same denominators)
    n_shared : int, optional
        Only the first ``n_shared`` sections are shared (the others are each channel's own,
        :func:`~freqid_casadi.modal.shared.fit_shared`'s channel sections: not modes); default
        all.

    Returns
    -------
    Modes
        A tuple of Mode (callable: ``modes()`` returns it).
    """
    models = list(models)
    if not models or models[0].structure.basis != "second-order":
        return Modes()
    out = []
    sections = [m.sections() for m in models]
    for j, (a, zn, wn, b, zd, wd) in enumerate(sections[0][:n_shared]):
        zeta = zd / np.sqrt(b) if b > 0 else np.inf
        if zeta >= 1.0:                  # real poles (or one at infinity): not a mode
            continue
        if all(_identity(secs[j]) for secs in sections):
            continue                     # its zeros cancel its poles in every model
        pole = complex(wd / np.sqrt(b) * (-zeta + 1j * np.sqrt(1.0 - zeta * zeta)))
        omega_n = abs(pole)
        out.append(Mode(omega_n=float(omega_n), frequency_hz=float(omega_n / (2 * np.pi)),
                        zeta=float(-pole.real / omega_n),
                        residues=tuple(_residue(m, pole, j) for m in models), pole=pole))
    return Modes(sorted(out, key=lambda m: m.omega_n))


def modes(model_or_result):
    """Modes of one model, a FitResult (one FRF) or a SharedFitResult (all channels).

    Parameters
    ----------
    model_or_result : RationalDelayModel, FitResult or SharedFitResult

    Returns
    -------
    tuple of Mode
        One residue per channel (one for a single model).
    """
    if isinstance(model_or_result, RationalDelayModel):
        return modes_of_models([model_or_result])
    if hasattr(model_or_result, "models"):
        return modes_of_models(model_or_result.models,
                               getattr(model_or_result, "n_shared", None))
    if isinstance(getattr(model_or_result, "model", None), RationalDelayModel):
        return modes_of_models([model_or_result.model])
    raise DataError(f"modes() needs a RationalDelayModel, FitResult or SharedFitResult, got "
                    f"{type(model_or_result).__name__}")


def _mode_rows(mode_list, names):
    header = ["mode", "frequency_hz", "omega_n_rad_s", "zeta", "omega_n_std", "zeta_std"]
    for name in names:
        header += [f"residue_re[{name}]", f"residue_im[{name}]"]
    rows = []
    for i, m in enumerate(mode_list, 1):
        row = [i, repr(m.frequency_hz), repr(m.omega_n), repr(m.zeta),
               "" if m.omega_n_std is None else repr(m.omega_n_std),
               "" if m.zeta_std is None else repr(m.zeta_std)]
        for r in m.residues:
            row += [repr(float(r.real)), repr(float(r.imag))]
        rows.append(row)
    return header, rows


def _names(mode_list, names):
    n = len(mode_list[0].residues) if mode_list else 0
    names = list(names) if names is not None else [f"ch{c + 1}" for c in range(n)]
    if mode_list and len(names) != n:
        raise OptionError(f"names needs one entry per channel ({n}), got {len(names)}")
    return names


def modes_csv(mode_list, names=None):
    """The modal table as CSV text (full precision): one row per mode, the real and
    imaginary part of each channel's residue as columns.

    Parameters
    ----------
    mode_list : sequence of Mode
    names : sequence of str, optional
        Channel names (default ``ch1``, ``ch2``, ...).
    """
    header, rows = _mode_rows(mode_list, _names(mode_list, names))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def modes_markdown(mode_list, names=None):
    """The modal table as Markdown: frequency, damping, and each channel's residue as
    magnitude and phase (deg).

    Parameters
    ----------
    mode_list : sequence of Mode
    names : sequence of str, optional
        Channel names (default ``ch1``, ``ch2``, ...).
    """
    names = _names(mode_list, names)
    head = "| mode | f (Hz) | omega_n (rad/s) | zeta (%) | " + " | ".join(
        f"residue {n}" for n in names) + " |"
    sep = "|---:|---:|---:|---:|" + "---|" * len(names)
    lines = [head, sep]
    for i, m in enumerate(mode_list, 1):
        res = " | ".join(f"{abs(r):.4g} ∠{np.degrees(np.angle(r)):.1f}°" for r in m.residues)
        lines.append(f"| {i} | {m.frequency_hz:.6g} | {m.omega_n:.6g} | "
                     f"{100 * m.zeta:.4g} | {res} |")
    return "\n".join(lines) + "\n"


def write_modes(mode_list, csv_path=None, md_path=None, names=None):
    """Write the modal table as CSV and/or Markdown (atomically).

    Parameters
    ----------
    mode_list : sequence of Mode
    csv_path, md_path : str, optional
        Files to write (None: not written).
    names : sequence of str, optional
        Channel names.
    """
    if csv_path is not None:
        atomic_write_text(csv_path, modes_csv(mode_list, names))
    if md_path is not None:
        atomic_write_text(md_path, modes_markdown(mode_list, names))


# --------------------------------------------------------------------------- mode shapes


@dataclass(frozen=True, eq=False)
class ModeShapes:
    """Mode shapes of a shared-pole fit (:meth:`SharedFitResult.mode_shapes`).

    Attributes
    ----------
    modal_constants : ndarray of complex, shape (modes, channels)
        The residue of every channel's model at every mode's pole (channel unit x rad/s).
    aligned : ndarray of complex, shape (modes, channels)
        ``modal_constants`` rotated by each mode's principal phase and scaled so that the
        largest component has magnitude 1 and a positive real part (dimensionless): a
        real shape's components lie on the real axis.
    shapes : ndarray, shape (modes, channels)
        Real (``aligned.real``) when every mode's MPC is at least :data:`REAL_MPC`, else
        complex (``aligned``); also what ``numpy.asarray(shapes)`` gives.
    frequency_hz, zeta : ndarray of float, shape (modes,)
    mpc : ndarray of float, shape (modes,)
        Modal phase collinearity in [0, 1] (1: the constants lie on one line, a real
        mode; 0: no preferred phase).
    mpd_deg : ndarray of float, shape (modes,)
        Mean phase deviation (degrees, magnitude-weighted) of the constants from that
        line, in [0, 90].
    is_real : ndarray of bool, shape (modes,)
        ``mpc >= REAL_MPC``.
    coordinates : ndarray of float, shape (channels, d), or None
        The channels' coordinates when given.
    names : tuple of str
        Channel names.
    """

    modal_constants: np.ndarray
    aligned: np.ndarray
    frequency_hz: np.ndarray
    zeta: np.ndarray
    mpc: np.ndarray
    mpd_deg: np.ndarray
    coordinates: np.ndarray = None
    names: tuple = ()

    @property
    def is_real(self):
        return self.mpc >= REAL_MPC

    @property
    def shapes(self):
        return self.aligned.real if np.all(self.is_real) else self.aligned

    def __array__(self, dtype=None, copy=None):
        out = self.shapes
        return out.astype(dtype) if dtype is not None else out.copy()

    def __len__(self):
        return self.aligned.shape[0]


def _principal_phase(r):
    """(angle theta, MPC, MPD in degrees) of the constants ``r`` (channels,): ``theta``
    maximises ``sum Re(r e^{-j theta})^2`` (the principal axis of the points (Re, Im))."""
    x, y = r.real, r.imag
    sxx, syy, sxy = x @ x, y @ y, x @ y
    total = sxx + syy
    if not total > 0:
        return 0.0, 0.0, 90.0
    theta = 0.5 * np.arctan2(2 * sxy, sxx - syy)
    lam = np.linalg.eigvalsh(np.array([[sxx, sxy], [sxy, syy]]))
    mpc = float(((lam[1] - lam[0]) / total) ** 2)
    dev = np.angle(r * np.exp(-1j * theta))                       # (-pi, pi]
    dev = np.abs(np.where(np.abs(dev) > np.pi / 2, dev - np.sign(dev) * np.pi, dev))
    mag = np.abs(r)
    mpd = float(np.degrees(np.sum(mag * dev) / np.sum(mag)))
    return float(theta), mpc, mpd


def mode_shapes(mode_list, coordinates=None, names=None):
    """Mode shapes from modes with one residue per channel (see :class:`ModeShapes`).

    Parameters
    ----------
    mode_list : sequence of Mode
        E.g. :attr:`SharedFitResult.modes` or a stabilization's selected modes.
    coordinates : array_like of float, shape (channels,) or (channels, d), optional
        Where each channel was measured (e.g. the hammer positions of a roving-hammer
        test), in any length unit.
    names : sequence of str, optional
        Channel names (default ``ch1``, ``ch2``, ...).

    Returns
    -------
    ModeShapes
    """
    names = tuple(_names(mode_list, names))
    n_ch = len(names)
    r = np.array([m.residues for m in mode_list], complex).reshape(len(mode_list), n_ch)
    aligned = np.zeros_like(r)
    mpc, mpd = np.zeros(len(r)), np.zeros(len(r))
    for i, row in enumerate(r):
        theta, mpc[i], mpd[i] = _principal_phase(row)
        a = row * np.exp(-1j * theta)
        big = a[np.argmax(np.abs(a))] if np.any(a) else 1.0
        sign = 1.0 if big.real >= 0 else -1.0
        aligned[i] = a * sign / max(np.abs(big), 1e-300)
    coords = None
    if coordinates is not None:
        coords = np.asarray(coordinates, float)
        coords = coords.reshape(-1, 1) if coords.ndim == 1 else coords
        if coords.ndim != 2 or coords.shape[0] != n_ch or not np.all(np.isfinite(coords)):
            raise OptionError(f"coordinates must be finite numbers, one row per channel "
                              f"({n_ch}), got shape {np.shape(coordinates)}")
    return ModeShapes(r, aligned, np.array([m.frequency_hz for m in mode_list], float),
                      np.array([m.zeta for m in mode_list], float), mpc, mpd, coords, names)


def _shape_matrix(x, name):
    if isinstance(x, ModeShapes):
        x = x.aligned
    try:
        a = np.asarray(x, complex)
    except (TypeError, ValueError):
        raise OptionError(f"{name} must be an array of mode shapes (modes x channels), got "
                          f"{type(x).__name__}") from None
    a = a.reshape(1, -1) if a.ndim == 1 else a
    if a.ndim != 2 or a.size == 0 or not np.all(np.isfinite(a)):
        raise OptionError(f"{name} must be a finite 1-D shape or a 2-D array (modes x "
                          f"channels), got shape {np.shape(x)}")
    return a


def mac(a, b=None):
    """Modal assurance criterion matrix ``|a_i^H b_j|^2 / ((a_i^H a_i)(b_j^H b_j))``.

    Parameters
    ----------
    a : array_like, shape (modes_a, channels) or (channels,), or ModeShapes
        Shapes as rows (real or complex).
    b : array_like, shape (modes_b, channels) or (channels,), or ModeShapes, optional
        Default ``a`` (the auto-MAC).

    Returns
    -------
    ndarray of float, shape (modes_a, modes_b)
        In [0, 1]; 1 for shapes that differ only by a (complex) factor. A zero shape gives
        0 against every other.

    Raises
    ------
    OptionError
        Not finite, or different numbers of channels.
    """
    A = _shape_matrix(a, "a")
    B = A if b is None else _shape_matrix(b, "b")
    if A.shape[1] != B.shape[1]:
        raise OptionError(f"mac: a has {A.shape[1]} channels per shape and b {B.shape[1]}; "
                          "give both shapes on the same channels (columns)")
    cross = np.abs(np.conj(A) @ B.T) ** 2
    na = np.sum(np.abs(A) ** 2, axis=1)[:, None]
    nb = np.sum(np.abs(B) ** 2, axis=1)[None, :]
    den = na * nb
    return np.where(den > 0, cross / np.where(den > 0, den, 1.0), 0.0)


def shapes_csv(shapes):
    """The mode shapes as CSV text: one row per channel (name, coordinates, then per mode
    the aligned shape's real and imaginary part), a header naming each mode by frequency,
    and two last rows ``mpc`` and ``mpd_deg``.

    Parameters
    ----------
    shapes : ModeShapes
    """
    d = 0 if shapes.coordinates is None else shapes.coordinates.shape[1]
    header = ["channel"] + [f"x{k + 1}" for k in range(d)]
    for i, f in enumerate(shapes.frequency_hz, 1):
        header += [f"mode{i}_{f:.6g}Hz_re", f"mode{i}_{f:.6g}Hz_im"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for c, name in enumerate(shapes.names):
        row = [name] + ([] if d == 0 else [repr(float(v)) for v in shapes.coordinates[c]])
        for i in range(len(shapes)):
            z = shapes.aligned[i, c]
            row += [repr(float(z.real)), repr(float(z.imag))]
        w.writerow(row)
    for label, vals in (("mpc", shapes.mpc), ("mpd_deg", shapes.mpd_deg)):
        w.writerow([label] + [""] * d + [x for v in vals for x in (repr(float(v)), "")])
    return buf.getvalue()


def _spacing(omega, w):
    """Local frequency spacing (rad/s) of the grid ``omega`` at ``w``."""
    i = int(np.clip(np.searchsorted(omega, w), 1, omega.size - 1))
    return float(omega[i] - omega[i - 1])


def resolution_notes(omega, responses, mode_list=()):
    """Resonances narrower than the frequency spacing (e.g. after a decimation), as
    sentences (empty when there is none).

    A resonance is under-resolved when its half-power bandwidth ``2 zeta omega_n`` is
    smaller than the spacing of the grid there: the data then hold it in one or two points
    and a fit cannot place its pole (taking every 8th point of a lightly damped test turns
    each resonance into one point). Found from the data (a local maximum of the channels'
    summed normalised magnitudes ``sum_c |Phi_c| / max |Phi_c|``, at least 5 % of its
    largest, with both neighbours below half of it) and from fitted modes when given.

    Parameters
    ----------
    omega : ndarray of float, shape (M,)
        rad/s, increasing.
    responses : ndarray of complex, shape (C, M) or (M,)
    mode_list : sequence of Mode, optional

    Returns
    -------
    list of str
    """
    omega = np.asarray(omega, float)
    mag = np.abs(np.atleast_2d(responses))
    notes = []
    if omega.size >= 3:
        # the channels' normalised magnitudes summed: a resonance is in (most) channels,
        # a noise spike in one
        tot = np.sum(mag / np.maximum(np.max(mag, axis=1, keepdims=True), 1e-300), axis=0)
        mid = tot[1:-1]
        peak = (mid > 2 * tot[:-2]) & (mid > 2 * tot[2:]) & (mid >= 0.05 * np.max(tot))
        idx = np.nonzero(peak)[0] + 1
        if idx.size:
            hz = ", ".join(f"{omega[i] / (2 * np.pi):.6g}" for i in idx[:8])
            more = f" and {idx.size - 8} more" if idx.size > 8 else ""
            notes.append(
                f"{idx.size} resonance peak(s) of the data at {hz}{more} Hz are single "
                f"points (both neighbours below half the peak): the peaks are narrower "
                f"than the frequency spacing, so a fit cannot place their poles; fit the "
                f"undecimated data, or a band around the modes at full resolution")
    for m in mode_list:
        width, dw = 2 * m.zeta * m.omega_n, _spacing(omega, m.omega_n)
        if 0 < width < dw:
            notes.append(
                f"the mode at {m.frequency_hz:.6g} Hz has a half-power bandwidth of "
                f"{width / (2 * np.pi):.3g} Hz, narrower than the frequency spacing "
                f"{dw / (2 * np.pi):.3g} Hz there: at most one point of the data lies in "
                "its half-power band, so its damping rests on the points beside the peak "
                "(noise there moves it; was the grid decimated?)")
    return notes


# ------------------------------------------------------------------------- stabilization
