"""Measured frequency responses published in public repositories, shipped with the package.

Each set is one measured FRF, stored in ``freqid_casadi/datasets/<folder>/`` byte for byte
as published, xz-compressed, beside a ``SOURCE.md`` (repository, commit, path, author,
what was measured, units) and the licence the source asks to keep (``LICENSE``). The
Touchstone files are read by :func:`~freqid_casadi.io.loaders.load_touchstone` (decompressed
into a temporary folder under their published names); pyuff's impact test is a column of
complex numbers whose frequencies (0, 1, ..., 1000 Hz) its README states, read by the small
reader here.

``measured_sets()`` lists the sets, ``measured(name)`` returns one as
:class:`~freqid_casadi.core.data.FrequencyData` (``omega`` in rad/s; a 0 Hz row dropped),
``measured_file(name, folder)`` writes the file as published (to try ``freqid fit`` on it).
Nothing is read before one of these is called.
"""

import lzma
import os
import tempfile
from dataclasses import dataclass

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError

__all__ = ["MeasuredSet", "MEASURED_SETS", "measured_sets", "measured", "measured_file",
           "measured_source"]


@dataclass(frozen=True)
class MeasuredSet:
    """One shipped measured FRF.

    Attributes
    ----------
    name : str
        The key of :func:`measured`.
    folder : str
        Its folder in ``freqid_casadi/datasets/`` (with ``SOURCE.md`` and ``LICENSE``).
    file : str
        The file as published (stored as ``file + ".xz"``).
    parameter : str or None
        The Touchstone parameter (``"S21"``, ...), None for the impact test's text column.
    n_points : int
        Points of :func:`measured` (0 Hz dropped).
    f_min_hz, f_max_hz : float
        Its frequency range, Hz.
    max_sections : int
        The largest order worth trying (the modes, resonances or bumps the source shows):
        the corpus fits ``n_sections=range(1, max_sections + 1)``.
    description : str
        What was measured, and the response's unit.
    licence : str
        The source's licence (full text in the folder's ``LICENSE``).
    sha256 : str
        SHA-256 of the file as published (also in ``SOURCE.md``).
    """

    name: str
    folder: str
    file: str
    parameter: object
    n_points: int
    f_min_hz: float
    f_max_hz: float
    max_sections: int
    description: str
    licence: str
    sha256: str


_IMPACT_SHA256 = ("ae99c87c17747ddc0819dffc6fadaf605385b5e5a0eec43415b724aaccf7223a",
                  "872f58a6e812cd9abed390262bec120d9064738524faff082929dd303a17e340",
                  "2c3a420cbb076fc88532fc625d642295e14cf3b79bcc73d26e759ab33f80b5f6")


def _impact(k):
    return MeasuredSet(
        name=f"impact_{k}", folder="pyuff_impact", file=f"meas_point_{k}.txt", parameter=None,
        n_points=1000, f_min_hz=1.0, f_max_hz=1000.0, max_sections=8,
        description=f"impact test, accelerance (acceleration / force) at response point 1, "
                    f"hammer at point {k}, 0-1000 Hz in 1 Hz steps, six modes in the band "
                    f"(ladisk/pyuff data/meas_point_{k}.txt; units not stated in the source)",
        licence="MIT", sha256=_IMPACT_SHA256[k - 1])


_SKRF = "BSD-3-Clause"

#: Every shipped measured set, by name.
MEASURED_SETS = {s.name: s for s in (
    _impact(1), _impact(2), _impact(3),
    MeasuredSet(name="ring_slot_s11", folder="skrf_ring_slot", file="ring slot measured.s1p",
                parameter="S11", n_points=101, f_min_hz=75e9, f_max_hz=110e9, max_sections=4,
                description="reflection S11 (dimensionless) of a ring-slot resonator, "
                            "measured 75-110 GHz (scikit-rf skrf/data)",
                licence=_SKRF,
                sha256="d916949bdcce147e2d246d9674469042f35bc7b79a3e0683b64b5bf9aad20f4d"),
    MeasuredSet(name="tx190_s21", folder="skrf_tx190", file="190ghz_tx_measured.S2P",
                parameter="S21", n_points=801, f_min_hz=140e9, f_max_hz=220e9,
                max_sections=6,
                description="transmission S21 (dimensionless, gain) of an active 190 GHz "
                            "2-port measured on a R&S ZVA67 VNA, 140-220 GHz (scikit-rf "
                            "vector-fitting example 2)",
                licence=_SKRF,
                sha256="e767b132764a658efa80e89417c801bf92bcdd135e6e7cbd42f4b62074cf8e7b"),
    MeasuredSet(name="resonator_36mm_s21", folder="skrf_resonator",
                file="resonator_36mm.s2p", parameter="S21", n_points=401, f_min_hz=1e9,
                f_max_hz=5e9, max_sections=4,
                description="transmission S21 (dimensionless) of a 36 mm stripline resonator "
                            "on a PCB laminate, two resonances, measured 1-5 GHz on a "
                            "Keysight N5242A (scikit-rf Q-factor example)",
                licence=_SKRF,
                sha256="9fd37c4871cc79aa5aac9934a0c77eac739225c1e2825a393fd7603804ffd1d7"),
    MeasuredSet(name="msl_thru_100_s21", folder="skrf_msl_thru",
                file="P1-MSL_Thru_100-P2.s2p", parameter="S21", n_points=10000,
                f_min_hz=1e6, f_max_hz=10e9, max_sections=4,
                description="transmission S21 (dimensionless) of a 100 mm microstrip line on "
                            "FR-4: a delay of about 0.7 ns with loss, measured 1 MHz-10 GHz "
                            "on an Anritsu MS46524B (scikit-rf TDR example)",
                licence=_SKRF,
                sha256="d6cde91d1abc82e8e00d636548e3d437ad7172964bae269fed87f308340213c4"),
)}


def measured_sets():
    """The shipped measured FRFs.

    Returns
    -------
    tuple of MeasuredSet
        In a fixed order (pyuff's impact test, then scikit-rf's network measurements).
    """
    return tuple(MEASURED_SETS.values())


def _spec(name):
    if not isinstance(name, str) or name not in MEASURED_SETS:
        raise DataError(f"no measured set {name!r}: choose one of "
                        f"{', '.join(MEASURED_SETS)} (freqid_casadi.systems.measured_sets())")
    return MEASURED_SETS[name]


def _stored(spec, file=None):
    """Path of a file of ``spec``'s folder in the installed package."""
    from importlib.resources import files

    path = os.fspath(files("freqid_casadi").joinpath("datasets", spec.folder,
                                                      file or spec.file + ".xz"))
    if not os.path.isfile(path):
        raise DataError(f"the measured set {spec.name!r} is missing from the installed "
                        f"package ({path!r}); reinstall freqid_casadi")
    return path


def measured_source(name):
    """The ``SOURCE.md`` text of a set: repository, commit, path, author, licence, units.

    Parameters
    ----------
    name : str
        A name of :func:`measured_sets`.

    Returns
    -------
    str
    """
    with open(_stored(_spec(name), "SOURCE.md"), encoding="utf-8") as f:
        return f.read()


def measured_file(name, folder):
    """Write a set's file as published (decompressed, same bytes, same name) into a folder.

    Parameters
    ----------
    name : str
        A name of :func:`measured_sets`.
    folder : str or os.PathLike
        An existing folder.

    Returns
    -------
    str
        The written file's path, e.g. ``folder/resonator_36mm.s2p`` (``freqid fit`` reads
        it; the impact test's text column has no frequencies and needs :func:`measured`).

    Raises
    ------
    DataError
        Unknown ``name``, or the folder does not exist.
    """
    spec = _spec(name)
    if not os.path.isdir(folder):
        raise DataError(f"folder {os.fspath(folder)!r} does not exist: create it first")
    with lzma.open(_stored(spec)) as f:
        payload = f.read()
    path = os.path.join(os.fspath(folder), spec.file)
    with open(path, "wb") as f:
        f.write(payload)
    return path


def _read_impact(spec):
    """pyuff's ``meas_point_k.txt``: 1001 lines ``(re+imj)``, at 0, 1, ..., 1000 Hz (the
    frequencies its README gives); the 0 Hz line (pyuff sets it to NaN) is dropped."""
    with lzma.open(_stored(spec), "rt", encoding="ascii") as f:
        lines = [line.strip() for line in f if line.strip()]
    try:
        values = np.array([complex(line) for line in lines])
    except ValueError as exc:
        raise DataError(f"measured set {spec.name!r}: {exc}; the stored file is damaged, "
                        "reinstall freqid_casadi") from None
    hz = np.arange(values.size, dtype=float)
    return FrequencyData(2 * np.pi * hz[1:], values[1:], name=spec.name)


def measured(name):
    """One shipped measured FRF.

    Parameters
    ----------
    name : str
        A name of :func:`measured_sets`, e.g. ``"resonator_36mm_s21"``.

    Returns
    -------
    FrequencyData
        ``omega`` in rad/s, ``name`` the set's name; its description, source and licence in
        :data:`MEASURED_SETS` and :func:`measured_source`.

    Raises
    ------
    DataError
        Unknown ``name``, or the set is missing from the installation.
    """
    spec = _spec(name)
    if spec.parameter is None:
        return _read_impact(spec)
    from ..io.loaders import load_touchstone

    with tempfile.TemporaryDirectory(prefix="freqid-measured-") as tmp:
        return load_touchstone(measured_file(name, tmp), name, parameter=spec.parameter)
