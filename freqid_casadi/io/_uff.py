"""Universal file format (UFF) dataset 58/58b records, read through pyuff (layer L1).

pyuff (MIT) is an optional dependency (extra ``freqid_casadi[uff]``), imported only when a
UFF file is read. Re-exported by :mod:`freqid_casadi.io.loaders`.
"""

import collections
import warnings

import numpy as np

from ._readfile import DataWarning
from ._table import parse_freq_unit
from ..errors import DataError

__all__ = ["load_uff", "read_uff", "node_name", "record_names", "UFF_FUNCTION_TYPES",
           "RESPONSE_TYPES"]

#: Dataset 58's function types (record 6, field 1), as the UFF standard names them.
UFF_FUNCTION_TYPES = {
    0: "general or unknown function", 1: "time response", 2: "auto spectrum",
    3: "cross spectrum", 4: "frequency response function", 5: "transmissibility",
    6: "coherence", 7: "auto-correlation", 8: "cross-correlation",
    9: "power spectral density", 10: "energy spectral density",
    11: "probability density function", 12: "spectrum",
    13: "cumulative frequency distribution", 14: "peaks valley", 15: "stress/cycles",
    16: "strain/cycles", 17: "orbit", 18: "mode indicator function", 19: "force pattern",
    20: "partial power", 21: "partial coherence", 22: "eigenvalue", 23: "eigenvector",
    24: "shock response spectrum", 25: "finite impulse response filter",
    26: "multiple coherence", 27: "order function", 28: "phase compensation"}
#: Other universal-file datasets, named in the refusal of a file without dataset 58.
_DATASETS = {151: "header", 164: "units", 15: "nodes", 2411: "nodes", 18: "coordinate "
             "systems", 2420: "coordinate systems", 82: "trace lines", 2412: "elements",
             55: "data at nodes: mode shapes or a response at one frequency",
             2414: "analysis data at nodes or elements", 1858: "qualifiers of dataset 58"}
#: The function types read as frequency responses: an FRF, a transmissibility (an FRF
#: between two responses) and "general" (0), which some analysers write for FRFs.
RESPONSE_TYPES = (0, 4, 5)
#: Dataset 58's direction codes (record 6, fields 6 and 9): 1..6 are +X, +Y, +Z and the
#: rotations +RX, +RY, +RZ, their negatives the opposite directions, 0 a scalar.
_DIRECTIONS = {1: "X", 2: "Y", 3: "Z", 4: "RX", 5: "RY", 6: "RZ"}


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
        One per frequency-response record of dataset 58 (a frequency abscissa and a
        function type in :data:`RESPONSE_TYPES`: FRF, transmissibility or general), in
        file order. Other records (coherence, spectra, time records) are skipped with a
        :class:`DataWarning` naming them. Names: the record's first ID line when each
        record has its own, distinct one; else, in a file of several such records, the
        record's response and reference node and direction, as modal-testing tools label
        an FRF (``"12+Z/1+Z"``: response node 12 in +Z over reference node 1 in +Z;
        ``"12+Z"`` without a reference node, ``"12"`` for a scalar direction; ``":k"``
        added when two records name the same pair); else (one record, or a header with
        node 0 for both) the record's first ID line, or ``"<stem>:<k>"``. ``k``: the
        record's number among the file's dataset-58 records.

    Raises
    ------
    DataError
        pyuff missing (install the extra ``freqid_casadi[uff]``), a file pyuff cannot read,
        no frequency-response record (the error names what the records are), a record
        with bad values.
    """
    return read_uff(path, freq_unit=freq_unit, band=band)[1]


def read_uff(path, *, freq_unit=None, band=None, record=None, single=False):
    """:func:`load_uff`, or only its frequency-response record ``record``.

    Parameters
    ----------
    path, freq_unit, band
        As :func:`load_uff`.
    record : int, optional
        0-based among the frequency-response records; None: all of them. Only that record
        is checked and built (a bad value in another record does not refuse it).
    single : bool
        With ``record`` None: build the records only when there is one (else none).

    Returns
    -------
    (int, tuple of FrequencyData)
        The number of frequency-response records, and the records built (all, the one
        asked for, or none).

    Raises
    ------
    DataError
        As :func:`load_uff`; ``record`` out of range.
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
        types = [int(t) for t in uff.get_set_types()]
        sets = [uff.read_sets(i) for i, t in enumerate(types) if t == 58]
    except Exception as exc:            # pyuff raises bare Exception
        raise DataError(f"cannot read {path!r} as a universal file ({exc}); check that it "
                        "is UFF ASCII/binary with dataset 58 records") from None
    if not sets:
        counts = collections.Counter(types)
        held = ", ".join(f"{n} x dataset {t}" + (f" ({_DATASETS[t]})" if t in _DATASETS else "")
                         for t, n in counts.items()) or "no dataset"
        raise DataError(f"{path!r} holds no dataset-58 (function) records: it holds {held}; "
                        "export the FRFs as UFF 58 (function type 4)")
    kinds = [_kind(s) for s in sets]
    keep = [k for k, kind in enumerate(kinds) if kind is None]
    if not keep:
        # the first record's reason, as a file of one record of that kind is told
        raise DataError(f"{path!r} record 0: {kinds[0][1]}" + (
            "" if len(sets) == 1 else
            f" (and no other of its {len(sets)} records is a frequency response: "
            f"{_tally(kinds)})"))
    if len(keep) < len(sets):
        warnings.warn(f"{path!r}: skipped {len(sets) - len(keep)} of its {len(sets)} "
                      f"dataset-58 records, which are not frequency responses ({_tally(kinds)}"
                      f"); kept its {len(keep)} frequency-response record(s), numbered 0.."
                      f"{len(keep) - 1} for record=", DataWarning,
                      stacklevel=2)
    names = record_names(path, sets, keep)
    if record is None:
        if single and len(keep) != 1:
            return len(keep), ()
        return len(keep), tuple(_uff_record(path, k, sets[k], freq_unit, band, name)
                                for k, name in zip(keep, names))
    if isinstance(record, bool) or not isinstance(record, (int, np.integer)) \
            or not 0 <= record < len(keep):
        raise DataError(f"record={record!r} is out of range: {path!r} holds {len(keep)} "
                        f"record(s), numbered 0..{len(keep) - 1}")
    k = keep[int(record)]
    return len(keep), (_uff_record(path, k, sets[k], freq_unit, band, names[int(record)]),)


def _point(node, direction):
    """``"12+Z"``: a node and its direction code (:data:`_DIRECTIONS`; ``"12"`` for 0, a
    scalar, or a code outside the standard's)."""
    axis = _DIRECTIONS.get(abs(direction))
    return f"{node}{'+' if direction > 0 else '-'}{axis}" if axis else f"{node}"


def node_name(dset):
    """The label of a dataset-58 record's degrees of freedom, as modal-testing tools write
    it: ``"12+Z/1+Z"`` (response node and direction over reference node and direction),
    ``"12+Z"`` when the reference node is 0 (none given).

    Parameters
    ----------
    dset : dict
        The record as pyuff reads it (``rsp_node``, ``rsp_dir``, ``ref_node``,
        ``ref_dir``).

    Returns
    -------
    str or None
        None when the header gives no node (both nodes 0, or fields missing).
    """
    try:
        rsp, rsp_dir, ref, ref_dir = (int(dset.get(key) or 0) for key in (
            "rsp_node", "rsp_dir", "ref_node", "ref_dir"))
    except (TypeError, ValueError):
        return None
    if rsp <= 0 and ref <= 0:
        return None
    label = _point(rsp, rsp_dir)
    return label if ref <= 0 else f"{label}/{_point(ref, ref_dir)}"


def record_names(path, sets, keep):
    """Names of the records ``sets[k]`` for ``k`` in ``keep`` (see :func:`load_uff`):
    each record's first ID line when every record has its own (the user's labels); else,
    when several records are read and the header gives them, node labels
    (:func:`node_name`), ``":k"`` added to a label two records share; else the first ID
    line or ``"<stem>:<k>"``.

    Parameters
    ----------
    path : str
        The file (its stem names a record without a label).
    sets : list of dict
        The file's dataset-58 records, as pyuff reads them.
    keep : list of int
        The indices of ``sets`` that are frequency responses.

    Returns
    -------
    list of str
        One name per index of ``keep``.
    """
    from ._readfile import _stem

    idents = [str(sets[k].get("id1", "") or "").strip() for k in keep]
    labelled = all(i and i.upper() != "NONE" for i in idents) and len(set(idents)) == len(keep)
    labels = [node_name(sets[k]) if len(keep) > 1 and not labelled else None for k in keep]
    shared = collections.Counter(labels)
    names = []
    for k, label, ident in zip(keep, labels, idents):
        if label is None:
            label = ident if ident and ident.upper() != "NONE" else f"{_stem(path)}:{k}"
        elif shared[label] > 1:
            label = f"{label}:{k}"
        names.append(label)
    return names


def _kind(dset):
    """None for a frequency-response record of dataset 58, else ``(what it is, why it is
    not read)``."""
    kind = int(dset.get("abscissa_spec_data_type", 18) or 0)
    if kind not in (0, 18):
        return "time record", (f"abscissa type {kind} is not frequency (18); export a "
                               "frequency response (FRF), not a time record")
    func = int(dset.get("func_type", 0) or 0)
    if func not in RESPONSE_TYPES:
        name = UFF_FUNCTION_TYPES.get(func, "non-standard function")
        return name, (f"a {name} (UFF function type {func}), not a frequency response; "
                      "export the FRF (type 4) or a transmissibility (type 5)")
    return None


def _tally(kinds):
    """'2 coherence, 1 time record' of the records that are not frequency responses."""
    counts = collections.Counter(kind[0] for kind in kinds if kind is not None)
    return ", ".join(f"{n} {label}" for label, n in counts.items())


def _uff_record(path, k, dset, freq_unit, band, name):
    from ._readfile import _finish

    where = f"{path!r} record {k}"
    try:
        x = np.asarray(dset["x"], float)
        z = np.asarray(dset["data"])
    except (KeyError, TypeError, ValueError) as exc:
        raise DataError(f"{where}: no abscissa/ordinate data ({exc})") from None
    label = str(dset.get("abscissa_axis_units_lab", "") or "").lower()
    unit = freq_unit or ("rad/s" if "rad" in label else "hz")
    omega = x if unit == "rad/s" else 2 * np.pi * x
    zero = (z == 0) & (x != 0)
    if zero.any() and zero.size == x.size:
        # an analyser's quantised or blanked bins: the relative error is not defined there
        shown = ", ".join(f"{v:.6g}" for v in x[zero][:5]) + (", ..." if zero.sum() > 5 else "")
        warnings.warn(f"{where}: dropped {int(zero.sum())} point(s) whose response is exactly "
                      f"0 (at {shown} {'rad/s' if unit == 'rad/s' else 'Hz'}): the relative "
                      "error is not defined there", DataWarning, stacklevel=4)
        x, z, omega = x[~zero], z[~zero], omega[~zero]
    try:
        return _finish(path, omega, z, name, band=band,
                       scale=1.0 if unit == "rad/s" else 2 * np.pi,
                       file_unit="rad/s" if unit == "rad/s" else "Hz")
    except DataError as exc:
        raise DataError(f"{where}: {exc}") from None
