"""Universal file format (UFF) dataset 58/58b records, read through pyuff (layer L1).

pyuff (MIT) is an optional dependency (extra ``freqid_casadi[uff]``), imported only when a
UFF file is read. Re-exported by :mod:`freqid_casadi.io.loaders`.
"""

import numpy as np

from ._table import parse_freq_unit
from ..errors import DataError

__all__ = ["load_uff"]


def load_uff(path, *, freq_unit=None, band=None):
    """Read every frequency-response record (universal file dataset 58/58b) of a UFF file.

    Parameters
    ----------
    path : str or path-like
    freq_unit : {"Hz", "rad/s"}, optional
        Unit of the abscissa. Default: from the record's abscissa unit label when it names
        rad/s, else Hz (the unit dataset 58 uses for frequency).
    band : (float, float), optional
        Keep only the points with ``lo <= f <= hi`` in that unit.

    Returns
    -------
    tuple of FrequencyData
        One per dataset-58 record whose abscissa is a frequency, in file order, named
        ``"<stem>:<k>"`` or after the record's first ID line.

    Raises
    ------
    DataError
        pyuff missing (install the extra ``freqid_casadi[uff]``), a file pyuff cannot read,
        no dataset-58 records, a record over time or with bad values.
    """
    from ._readfile import parse_band, read_regular_file

    freq_unit = parse_freq_unit(freq_unit)
    band = parse_band(band)
    path, _ = read_regular_file(path)
    try:
        import pyuff
    except ImportError:
        raise DataError("reading UFF files needs pyuff: pip install 'freqid_casadi[uff]' "
                        "(or pip install pyuff)") from None
    try:
        uff = pyuff.UFF(path)
        which = [i for i, t in enumerate(uff.get_set_types()) if int(t) == 58]
        sets = [uff.read_sets(i) for i in which]
    except Exception as exc:            # pyuff raises bare Exception
        raise DataError(f"cannot read {path!r} as a universal file ({exc}); check that it "
                        "is UFF ASCII/binary with dataset 58 records") from None
    if not sets:
        raise DataError(f"{path!r} holds no dataset-58 (function) records; export the FRFs "
                        "as UFF 58")
    return tuple(_uff_record(path, k, s, freq_unit, band) for k, s in enumerate(sets))


def _uff_record(path, k, dset, freq_unit, band=None):
    from ._readfile import _finish, _stem

    where = f"{path!r} record {k}"
    kind = int(dset.get("abscissa_spec_data_type", 18) or 0)
    if kind not in (0, 18):
        raise DataError(f"{where}: abscissa type {kind} is not frequency (18); export a "
                        "frequency response (FRF), not a time record")
    try:
        x = np.asarray(dset["x"], float)
        z = np.asarray(dset["data"])
    except (KeyError, TypeError, ValueError) as exc:
        raise DataError(f"{where}: no abscissa/ordinate data ({exc})") from None
    label = str(dset.get("abscissa_axis_units_lab", "") or "").lower()
    unit = freq_unit or ("rad/s" if "rad" in label else "hz")
    omega = x if unit == "rad/s" else 2 * np.pi * x
    ident = str(dset.get("id1", "") or "").strip()
    name = ident if ident and ident.upper() != "NONE" else f"{_stem(path)}:{k}"
    try:
        return _finish(path, omega, z, name, band=band,
                       scale=1.0 if unit == "rad/s" else 2 * np.pi,
                       file_unit="rad/s" if unit == "rad/s" else "Hz")
    except DataError as exc:
        raise DataError(f"{where}: {exc}") from None
