"""Modal parameters of fitted models and the stabilization diagram (layer L5).

A mode is a pair of complex-conjugate poles ``p = -zeta omega_n + j omega_n sqrt(1 - zeta^2)``
of the (shared) denominator; its mode-shape coefficient in channel ``c`` is the residue of
that channel's model at ``p``, ``lim_{s -> p} (s - p) G_c(s)`` (delay and integrator
included). :func:`modes` gives them for one model, a :class:`~freqid_casadi.fit.FitResult`
or a :class:`~freqid_casadi.shared.SharedFitResult`; :func:`stabilization` fits a range of
orders and marks every pole as new, stable in frequency, or stable in frequency and damping
against the previous order (SDynPy's tolerances 1 % and 10 % by default).
"""

import csv
import io
from dataclasses import dataclass

import numpy as np

from ._io import atomic_write_text
from .errors import DataError, OptionError
from .model import RationalDelayModel

__all__ = ["Mode", "modes", "modes_of_models", "modes_csv", "modes_markdown",
           "write_modes", "StabilizationResult", "StabilizationPole", "stabilization",
           "stabilization_csv", "parse_orders", "STATUSES"]

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


def modes_of_models(models):
    """The underdamped poles of the first model's denominator sections (shared by all
    ``models``) with every model's residue, by increasing frequency.

    Parameters
    ----------
    models : sequence of RationalDelayModel (second-order basis, same denominators)

    Returns
    -------
    tuple of Mode
    """
    models = list(models)
    if not models or models[0].structure.basis != "second-order":
        return ()
    out = []
    for j, (a, zn, wn, b, zd, wd) in enumerate(models[0].sections()):
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
        return modes_of_models(model_or_result.models)
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
    imaginary part of each channel's residue as columns."""
    header, rows = _mode_rows(mode_list, _names(mode_list, names))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def modes_markdown(mode_list, names=None):
    """The modal table as Markdown: frequency, damping, and each channel's residue as
    magnitude and phase (deg)."""
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
    """Write the modal table as CSV and/or Markdown (atomically)."""
    if csv_path is not None:
        atomic_write_text(csv_path, modes_csv(mode_list, names))
    if md_path is not None:
        atomic_write_text(md_path, modes_markdown(mode_list, names))


# ------------------------------------------------------------------------- stabilization
@dataclass(frozen=True)
class StabilizationPole:
    """A pole of one order: ``order`` (number of poles of the fit), ``omega_n`` (rad/s),
    ``frequency_hz``, ``zeta`` and ``status`` (one of :data:`STATUSES`)."""

    order: int
    omega_n: float
    frequency_hz: float
    zeta: float
    status: str


@dataclass(frozen=True, eq=False)
class StabilizationResult:
    """Result of :func:`stabilization`.

    Attributes
    ----------
    orders : tuple of int
        Model orders (number of shared poles, 2 x sections).
    poles : tuple of StabilizationPole
        Every underdamped pole of every order.
    modes : tuple of Mode
        The automatically selected physical modes (see :func:`stabilization`), taken from
        the highest order's fit.
    fits : tuple of SharedFitResult
        One per order.
    freq_tol, damping_tol : float
    omega : ndarray of float, shape (M,)
        rad/s.
    summed_magnitude : ndarray of float, shape (M,)
        ``sum_c |Phi_c|`` (the curve the diagram is drawn over).
    """

    orders: tuple
    poles: tuple
    modes: tuple
    fits: tuple
    freq_tol: float
    damping_tol: float
    omega: np.ndarray
    summed_magnitude: np.ndarray

    def poles_of(self, order):
        """The StabilizationPoles of one order."""
        return tuple(p for p in self.poles if p.order == order)


def parse_orders(text):
    """``"2:40:2"`` (start:stop:step, stop included) or ``"4,8,12"`` -> tuple of even ints."""
    try:
        if ":" in str(text):
            parts = [int(t) for t in str(text).split(":")]
            start, stop = parts[0], parts[1]
            step = parts[2] if len(parts) > 2 else 2
            orders = tuple(range(start, stop + 1, step))
        else:
            orders = tuple(int(t) for t in str(text).split(","))
    except (ValueError, IndexError):
        raise OptionError(f"orders must look like 2:40:2 or 4,8,12, got {text!r}") from None
    return _check_orders(orders)


def _check_orders(orders):
    orders = tuple(int(o) for o in orders)
    if not orders or any(o < 2 or o % 2 for o in orders) or list(orders) != sorted(set(orders)):
        raise OptionError(f"orders must be increasing even numbers >= 2 (the number of "
                          f"shared poles), got {orders}")
    return orders


def _match(prev, cur, freq_tol, damping_tol):
    """Status of each (omega_n, zeta) of ``cur`` against the poles of ``prev`` and the index
    of its match in ``prev`` (or None). One-to-one: the closest pairs (relative frequency
    distance) are matched first, so a spurious pole beside a physical one stays "new"."""
    pairs = sorted((abs(pw - w) / w, i, j) for i, (w, _) in enumerate(cur)
                   for j, (pw, _) in enumerate(prev))
    match, used = [None] * len(cur), set()
    for dist, i, j in pairs:
        if dist <= freq_tol and match[i] is None and j not in used:
            match[i] = j
            used.add(j)
    status = []
    for i, (w, z) in enumerate(cur):
        if match[i] is None:
            status.append("new")
        elif abs(prev[match[i]][1] - z) <= damping_tol * max(z, 1e-12):
            status.append("stable-frequency-damping")
        else:
            status.append("stable-frequency")
    return status, match


def _classify(prev, cur, freq_tol, damping_tol):
    """Statuses of :func:`_match`."""
    return _match(prev, cur, freq_tol, damping_tol)[0]


def stabilization(datas, orders=tuple(range(2, 41, 2)), *, freq_tol=0.01, damping_tol=0.10,
                  min_stable=3, progress=False, **fit_options):
    """Stabilization diagram: shared-pole fits of a range of orders.

    Parameters
    ----------
    datas : sequence of FrequencyData
        As :func:`~freqid_casadi.shared.fit_shared`.
    orders : sequence of int
        Even model orders (number of poles) ``2 n_sections``, increasing.
    freq_tol : float
        A pole is stable in frequency when a pole of the previous order lies within
        ``freq_tol`` (relative, default 1 %).
    damping_tol : float
        ... and stable in damping when that pole's damping ratio is within ``damping_tol``
        (relative, default 10 %).
    min_stable : int
        A pole of the highest order is selected as a physical mode when it and its
        predecessors were "stable-frequency-damping" over the last ``min_stable`` orders.
    progress : bool
    **fit_options
        Passed to :func:`~freqid_casadi.shared.fit_shared` (integrator, delay, zeros, ...).

    Returns
    -------
    StabilizationResult
    """
    from .shared import fit_shared

    orders = _check_orders(orders)
    if not (0 < freq_tol < 1 and 0 < damping_tol < 10):
        raise OptionError(f"freq_tol must be in (0, 1) and damping_tol in (0, 10), got "
                          f"{freq_tol}, {damping_tol}")
    fits, poles, prev, history = [], [], [], []
    for order in orders:
        res = fit_shared(datas, order // 2, **fit_options)
        fits.append(res)
        cur = [(m.omega_n, m.zeta) for m in res.modes]
        status, match = _match(prev, cur, freq_tol, damping_tol)
        history.append((status, match))
        poles += [StabilizationPole(order, w, w / (2 * np.pi), z, s)
                  for (w, z), s in zip(cur, status)]
        if progress:
            import sys
            print(f"  order {order}: {len(cur)} modes, "
                  f"{status.count('stable-frequency-damping')} stable", file=sys.stderr)
        prev = cur
    selected = _select(fits[-1].modes, history, min_stable)
    d0 = fits[0].datas
    return StabilizationResult(
        orders=orders, poles=tuple(poles), modes=selected, fits=tuple(fits),
        freq_tol=float(freq_tol), damping_tol=float(damping_tol), omega=d0[0].omega,
        summed_magnitude=np.sum([np.abs(d.response) for d in d0], axis=0))


def _select(last, history, min_stable):
    """Modes of the highest order whose chain of matched predecessors was "stable-frequency-
    damping" at each of the last ``min_stable`` orders."""
    k = min(int(min_stable), len(history) - 1)
    keep = []
    for i, mode in enumerate(last):
        idx, ok = i, True
        for status, match in history[::-1][:k]:
            if status[idx] != "stable-frequency-damping":
                ok = False
                break
            idx = match[idx]
        if ok:
            keep.append(mode)
    return tuple(keep)


def stabilization_csv(result):
    """CSV text: order, frequency_hz, omega_n, zeta, status, selected (one row per pole)."""
    chosen = {m.omega_n for m in result.modes}
    top = result.orders[-1]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["order", "frequency_hz", "omega_n_rad_s", "zeta", "status", "selected"])
    for p in result.poles:
        w.writerow([p.order, repr(p.frequency_hz), repr(p.omega_n), repr(p.zeta), p.status,
                    int(p.order == top and p.omega_n in chosen)])
    return buf.getvalue()
