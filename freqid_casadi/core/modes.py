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

__all__ = ["Mode", "modes", "modes_of_models", "modes_csv", "modes_markdown",
           "write_modes", "STATUSES"]

STATUSES = ("new", "stable-frequency", "stable-frequency-damping")


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


def _residue(model, pole, j):
    """Residue of ``model`` at ``pole``, a root of its denominator section ``j``."""
    val = np.exp(-pole * model.delay) * model.gain
    if model.integrator:
        val /= pole
    for k, (a, zn, wn, b, zd, wd) in enumerate(model.sections()):
        val *= a * pole ** 2 + 2 * zn * wn * pole + wn ** 2
        if k == j:
            val /= b * (pole - np.conj(pole))
        else:
            val /= b * pole ** 2 + 2 * zd * wd * pole + wd ** 2
    return complex(val)


def modes_of_models(models, n_shared=None):
    """The underdamped poles of the first model's denominator sections (shared by all
    ``models``) with every model's residue, by increasing frequency.

    Parameters
    ----------
    models : sequence of RationalDelayModel (second-order basis, same denominators)
    n_shared : int, optional
        Only the first ``n_shared`` sections are shared (the others are each channel's own,
        :func:`~freqid_casadi.modal.shared.fit_shared`'s channel sections: not modes); default
        all.

    Returns
    -------
    tuple of Mode
    """
    models = list(models)
    if not models or models[0].structure.basis != "second-order":
        return ()
    out = []
    for j, (a, zn, wn, b, zd, wd) in enumerate(models[0].sections()[:n_shared]):
        zeta = zd / np.sqrt(b) if b > 0 else np.inf
        if zeta >= 1.0:                  # real poles (or one at infinity): not a mode
            continue
        pole = complex(wd / np.sqrt(b) * (-zeta + 1j * np.sqrt(1.0 - zeta * zeta)))
        omega_n = abs(pole)
        out.append(Mode(omega_n=float(omega_n), frequency_hz=float(omega_n / (2 * np.pi)),
                        zeta=float(-pole.real / omega_n),
                        residues=tuple(_residue(m, pole, j) for m in models), pole=pole))
    return tuple(sorted(out, key=lambda m: m.omega_n))


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


# ------------------------------------------------------------------------- stabilization
