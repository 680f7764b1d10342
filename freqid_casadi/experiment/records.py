"""Time-record files and the shipped measured data sets (layer L1).

Readers: :func:`load_records_csv` (``u,y`` CSV), :func:`load_records_table` (a table whose
header names its columns, a LabVIEW measurement file among them; :func:`lvm_segments`
describes the segments of one), :func:`load_daisy` (DaISy whitespace columns),
:func:`load_daq_records` (a data-acquisition export: header lines, then sample number, time
stamp, channels, events; ``.xz`` accepted) and :func:`load_records_mat` (MATLAB variables or
struct fields by name). They share the bounded, regular-file
reading of :mod:`freqid_casadi.io.loaders` and read ASCII decimal numbers only.

Data sets shipped in ``freqid_casadi/datasets`` (see :func:`dataset_path`):

- ``robot_arm.dat``: DaISy 96-009 flexible robot arm (B. De Moor et al., DaISy: Database
  for the Identification of Systems), read by :func:`robot_arm`;
- ``actuator/0A.txt.xz``: raw records of a servo-hydraulic actuator chirp test (MIT, see
  ``actuator/SOURCE.md``), read by :func:`actuator_records`.
"""

import lzma
import math
import numbers
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..io import NUMBER, decode_text, matrix_records, record_axis, shown_cell
from ..errors import DataError, OptionError
from ..io.loaders import (MAX_FILE_BYTES, MAX_ROWS, DataWarning, read_npz_arrays,
                          read_regular_file)
from ._lvm import column_rate, column_start, heading, lvm_layout
from .periodic import _detect_period, frf_from_periodic

__all__ = ["load_records_csv", "load_records_table", "load_daisy", "load_daq_records",
           "load_records_mat", "uniform_rate", "TIME_JITTER", "LvmSegment", "lvm_segments",
           "DaqRecords", "robot_arm",
           "actuator_records", "dataset_path", "ROBOT_ARM_FILE", "ACTUATOR_FILE",
           "SHARED_ENV"]

#: Environment variable naming a shared directory whose ``data/robot_arm.dat`` replaces the
#: shipped copy (optional).
SHARED_ENV = "FREQID_SHARED"
#: File name of the DaISy 96-009 data set.
ROBOT_ARM_FILE = "robot_arm.dat"
#: Path of the actuator records inside the shipped data sets.
ACTUATOR_FILE = "actuator/0A.txt.xz"


def dataset_path(name):
    """Path of a data set shipped with the package (``freqid_casadi/datasets/<name>``).

    Parameters
    ----------
    name : str
        Relative path inside ``datasets/``, e.g. ``"robot_arm.dat"`` or
        ``"actuator/0A.txt.xz"``.

    Raises
    ------
    DataError
        The file is not in the installed package.
    """
    from importlib.resources import files

    path = os.fspath(files("freqid_casadi").joinpath("datasets", *name.split("/")))
    if not os.path.isfile(path):
        raise DataError(f"the data set {name!r} is missing from the installed package "
                        f"({path!r}); reinstall freqid_casadi")
    return path


def _text_lines(path, what="records file"):
    """(path, lines) of a bounded UTF-8 text file, decompressing ``.xz``."""
    path, payload = read_regular_file(path, what)
    if path.lower().endswith(".xz"):
        try:
            dec = lzma.LZMADecompressor()
            payload = dec.decompress(payload, max_length=MAX_FILE_BYTES + 1)
        except lzma.LZMAError as exc:
            raise DataError(f"{path!r} is not a valid .xz file ({exc})") from None
        if len(payload) > MAX_FILE_BYTES or not dec.eof:
            raise DataError(f"{path!r} decompresses to more than {MAX_FILE_BYTES} bytes "
                            "(freqid_casadi.io.loaders.MAX_FILE_BYTES), or is truncated")
    lines = decode_text(path, payload).split("\n")
    if len(lines) > MAX_ROWS + 100:
        raise DataError(f"{path!r} has more than {MAX_ROWS} lines (limit "
                        "freqid_casadi.io.loaders.MAX_ROWS); cut the record or raise that limit")
    return path, lines


def _number(path, line, column, cell):
    cell = cell.strip()
    if not NUMBER.fullmatch(cell):
        raise DataError(f"{path!r} line {line}, column {column!r}: {shown_cell(cell)} is not a "
                        "number (ASCII decimal numbers only); fix or remove that line")
    value = float(cell)
    if not np.isfinite(value):
        raise DataError(f"{path!r} line {line}, column {column!r}: {cell!r} is not finite; "
                        "repair or cut out the bad samples")
    return value


def load_records_csv(path):
    """Read an input/output record from a CSV file with the header ``u,y``.

    Lines starting with ``#`` or ``%`` are comments; the header is case-insensitive; a UTF-8
    byte-order mark is accepted. A file without a header (its first line two numbers,
    comma or whitespace separated, as DaISy's ``.dat`` files) is read as u then y, with a
    ``DataWarning`` saying so.

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file.

    Returns
    -------
    u, y : ndarray of float, shape (N,)
        Input and output samples.

    Raises
    ------
    DataError
        Missing file, not a regular file, too large, not UTF-8, bad header, wrong column
        count, non-numeric or non-finite cells, no data rows.
    """
    path, lines = _text_lines(path)
    rows = [(k + 1, t) for k, t in enumerate(lines)
            if t.strip() and not t.lstrip().startswith(("#", "%"))]
    if not rows:
        raise DataError(f"{path!r} is empty: expected a header 'u,y' and data rows")
    sep = "," if "," in rows[0][1] else None
    head = [h.strip().strip("\"'").lower() for h in rows[0][1].split(sep)]
    if all(NUMBER.fullmatch(h) for h in head):          # no header (DaISy): u then y
        import warnings

        from ..io.loaders import DataWarning
        warnings.warn(f"{path!r} has no header: column 1 is read as the input u, column 2 "
                      "as the output y (a header line 'u,y' says so)", DataWarning,
                      stacklevel=2)
        rows = [(0, "u,y")] + rows
    elif head != ["u", "y"]:
        raise DataError(
            f"{path!r}: unrecognised header {shown_cell(rows[0][1].strip())}; the first line must "
            "be 'u,y' (input, output), or the file has no header and two columns, u then y")
    if len(rows) < 2:
        raise DataError(f"{path!r} has a header but no data rows")
    values = np.empty((len(rows) - 1, 2))
    for k, (line, text) in enumerate(rows[1:]):
        cells = text.split(sep)
        if len(cells) != 2:
            raise DataError(f"{path!r} line {line}: expected 2 columns (u,y), got {len(cells)}")
        values[k, 0] = _number(path, line, "u", cells[0])
        values[k, 1] = _number(path, line, "y", cells[1])
    return values[:, 0].copy(), values[:, 1].copy()


#: Column names that give the sampling: a time stamp in every row (s), or a constant in
#: the first rows (an oscilloscope's ``Increment``, a benchmark's ``Fs`` or ``Ts``).
_TIME_NAMES = ("t", "time", "time (s)", "time[s]", "time [s]", "ts", "x-axis")
_RATE_NAMES = {"fs": "rate", "ts": "period", "increment": "period", "dt": "period"}


def load_records_table(path, input=None, output=None, segment=None):
    """Input, output and sampling rate from a text table whose header names its columns.

    The table of :func:`load_records_csv` (``u,y``, or two headerless columns), or any
    comma-, semicolon-, tab- or space-separated table with a header, the input and output
    columns chosen by name (case-insensitive, quotes ignored): a benchmark's
    ``"Force","Voltage","Acceleration1",...,"Fs",``, an oscilloscope's ``CH1,CH2,Start,
    Increment`` with a units line under it, a LabVIEW measurement file (``.lvm``: the
    table after its header, the rate from ``Delta_X``; the tables of a file of several
    segments joined end to end in file order, see :func:`lvm_segments`). The sampling rate
    comes from a time column (``Time``, ``t``, ``ts``, ``x-axis``: its rate when it steps
    uniformly, :func:`uniform_rate`) or a constant column (``Fs``; ``Ts``, ``Increment`` or
    ``dt`` a sampling period), else None.

    Parameters
    ----------
    path : str or os.PathLike
    input, output : str, optional
        The names of the input and output columns; needed unless the header is ``u,y``.
    segment : int, optional
        A LabVIEW measurement file: read its segment ``segment`` alone (1 for the first;
        default all of them, joined). Every segment joined must hold the ``input`` and
        ``output`` columns, sampled at one rate.

    Returns
    -------
    u, y : ndarray of float, shape (N,)
    fs : float or None
        Hz.

    Raises
    ------
    DataError
        As :func:`load_records_csv`; a header whose columns are not chosen (the message
        lists them); segments of a LabVIEW file sampled at different rates.
    OptionError
        ``input`` or ``output`` not a column of the header (or of a segment);
        ``segment`` not a segment of a LabVIEW measurement file.
    """
    _, lines = _text_lines(path)
    layout = lvm_layout(path, lines)
    if layout is not None:
        return _lvm_records(path, layout, input, output, segment)
    where = f"{os.fspath(path)!r}"
    if segment is not None:
        raise OptionError(f"segment={segment!r} (command line --lvm-segment) chooses a "
                          f"segment of a LabVIEW measurement file (.lvm); {where} is not one")
    rows = [(k + 1, t) for k, t in enumerate(lines)
            if t.strip() and not t.lstrip().startswith(("#", "%"))]
    if not rows:
        raise DataError(f"{where} is empty: expected a header and data rows")
    lower = [n.lower() for n in heading(rows[0][1], _separator(rows[0][1]))]
    headerless = all(NUMBER.fullmatch(n) for n in lower)
    if input is None and output is None and (headerless or lower == ["u", "y"]):
        u, y = load_records_csv(path)
        return u, y, None
    u, y, fs, _ = _table_columns(path, rows, input, output)
    if u.size < 2:
        raise DataError(f"{where} has a header but fewer than 2 data rows")
    return u, y, fs


def _separator(first):
    return "," if "," in first else ";" if ";" in first else "\t" if "\t" in first else None


def _table_columns(path, rows, input, output, sep=None, comma=False):
    """``(u, y, fs or None, names)`` of the table ``rows`` (``(line, text)``, the header
    first): the ``input`` and ``output`` columns by name, the rate from its time or rate
    columns; ``sep`` None: found from the header; ``comma``: decimal commas."""
    where = f"{os.fspath(path)!r}"
    sep = _separator(rows[0][1]) if sep is None else sep
    names = heading(rows[0][1], sep)
    lower = [n.lower() for n in names]
    shown = ", ".join(repr(n) for n in names)
    if all(NUMBER.fullmatch(n) for n in names):
        raise OptionError(f"input/output (--input/--output) name columns of a header; "
                          f"{where} has none: its first two columns are read as u then y")
    if input is None or output is None:
        raise DataError(f"{where}: the header names the columns {shown}; choose the "
                        "excitation and the response: input='NAME', output='NAME' (command "
                        "line --input NAME --output NAME)")
    pick = []
    for opt, name in (("input", input), ("output", output)):
        if str(name).strip().lower() not in lower:
            raise OptionError(f"{opt}={name!r} is not a column of {where}; its columns are "
                              f"{shown}")
        pick.append(lower.index(str(name).strip().lower()))
    time = next((j for j, n in enumerate(lower) if n in _TIME_NAMES), None)
    rate = {j: _RATE_NAMES[n] for j, n in enumerate(lower) if n in _RATE_NAMES}
    u, y, t, consts = [], [], [], {}
    for k, (line, text) in enumerate(rows[1:]):
        text = text.replace(",", ".") if comma else text
        cells = [c.strip().strip("\"'") for c in text.split(sep)]
        for j in rate:
            if j < len(cells) and j not in consts and NUMBER.fullmatch(cells[j]):
                consts[j] = float(cells[j])
        if max(pick) >= len(cells):
            raise DataError(f"{where} line {line}: {len(cells)} columns, the header names "
                            f"{len(names)}")
        if k == 0 and not NUMBER.fullmatch(cells[pick[0]]):
            continue                                  # a units line: "Volt,Volt,..."
        u.append(_number(path, line, names[pick[0]], cells[pick[0]]))
        y.append(_number(path, line, names[pick[1]], cells[pick[1]]))
        if time is not None and time != pick[0] and time != pick[1]:
            t.append(_number(path, line, names[time], cells[time])
                     if NUMBER.fullmatch(cells[time]) else np.nan)
    return np.array(u), np.array(y), _table_fs(t, rate, consts), names


_ONE_SEGMENT = "read one segment with segment=K (command line --lvm-segment K)"


def _lvm_records(path, layout, input, output, segment):
    """Input, output and rate of a LabVIEW measurement file: its segments' tables joined
    end to end, or segment ``segment`` alone."""
    sep, comma, parts = layout
    where = f"{os.fspath(path)!r}"
    if segment is not None:
        if isinstance(segment, bool) or not isinstance(segment, numbers.Integral):
            raise OptionError(f"segment must be a segment number (1 for the first), got "
                              f"{segment!r}")
        if not 1 <= segment <= len(parts):
            raise OptionError(f"segment={segment} (command line --lvm-segment {segment}): "
                              f"{where} holds {len(parts)} segment(s); choose 1 to "
                              f"{len(parts)}")
        parts = parts[segment - 1:segment]
    many = len(parts) > 1
    us, ys, rates = [], [], []
    for part in parts:
        if not part.rows:
            raise DataError(f"{where}: segment {part.number} (line {part.line}) has a header "
                            "but no table; export the file again"
                            + (f", or {_ONE_SEGMENT}" if many else ""))
        if many:
            _segment_holds(path, part, sep, input, output, len(parts))
        u, y, fs, names = _table_columns(path, part.rows, input, output, sep, comma)
        rates.append(_segment_rate(path, part, names, input, output, comma) or fs)
        us.append(u)
        ys.append(y)
    u, y = np.concatenate(us), np.concatenate(ys)
    if u.size < 2:
        raise DataError(f"{where} has a header but fewer than 2 data rows")
    known = [(p.number, r) for p, r in zip(parts, rates) if r is not None]
    for number, fs in known[1:]:
        if not math.isclose(fs, known[0][1], rel_tol=1e-6):
            raise DataError(f"the segments of {where} differ in sampling: segment "
                            f"{known[0][0]} at {known[0][1]:g} Hz, segment {number} at "
                            f"{fs:g} Hz (Delta_X); {_ONE_SEGMENT}")
    return u, y, known[0][1] if known else None


def _segment_holds(path, part, sep, input, output, count):
    """OptionError when segment ``part`` of a file of ``count`` segments, all read, lacks
    the ``input`` or the ``output`` column."""
    names = heading(part.rows[0][1], sep)
    lower = [n.lower() for n in names]
    for opt, name in (("input", input), ("output", output)):
        if name is not None and str(name).strip().lower() not in lower:
            raise OptionError(f"{opt}={name!r} is not a column of segment {part.number} "
                              f"(line {part.line}) of {os.fspath(path)!r}, one of its {count} "
                              f"segments: its columns are "
                              f"{', '.join(repr(c) for c in names)}; {_ONE_SEGMENT}")


def _segment_rate(path, part, names, input, output, comma):
    """Hz of a segment's ``input`` and ``output`` columns from their ``Delta_X`` (None when
    its header gives none); DataError when the two differ."""
    lower = [n.lower() for n in names]
    rates = [column_rate(part.fields, lower.index(str(c).strip().lower()), comma)
             for c in (input, output)]
    if None not in rates and not math.isclose(*rates, rel_tol=1e-6):
        raise DataError(f"{os.fspath(path)!r} segment {part.number}: the input column "
                        f"{input!r} is sampled at {rates[0]:g} Hz, the output {output!r} at "
                        f"{rates[1]:g} Hz (Delta_X); resample one of them to the other's rate")
    return rates[0] if rates[0] is not None else rates[1]


@dataclass(frozen=True)
class LvmSegment:
    """One segment of a LabVIEW measurement file (``.lvm``): a header, then a table.

    Attributes
    ----------
    number : int
        1 for the first segment.
    line : int
        Line of its table's heading (``X_Value ...``), counted from 1.
    columns : tuple of str
        The heading's column names.
    fs : float or None
        Sampling rate in Hz from the ``Delta_X`` of its first channel, or None.
    samples : int
        Rows of its table.
    start : float or None
        Its start (``Date`` and ``Time`` of its first channel) in seconds after midnight
        before the first segment's date, or None when the header does not give it.
    """

    number: int
    line: int
    columns: tuple
    fs: object
    samples: int
    start: object


def lvm_segments(path):
    """The segments of a LabVIEW measurement file (``.lvm``), in file order.

    A file written with one header per segment (``Multi_Headings Yes``) holds a header and a
    table for every call of the writer: consecutive pieces of one acquisition (each starts
    where the one before ends: ``start`` plus ``samples / fs``) or separate ones (a gap).
    :func:`load_records_table` joins their tables end to end, or reads one.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.lvm`` file.

    Returns
    -------
    tuple of LvmSegment

    Raises
    ------
    DataError
        Not a LabVIEW measurement file (first line ``LabVIEW Measurement``).
    """
    _, lines = _text_lines(path)
    layout = lvm_layout(path, lines)
    if layout is None:
        raise DataError(f"{os.fspath(path)!r} is not a LabVIEW measurement file: its first "
                        "line is not 'LabVIEW Measurement'")
    sep, comma, parts = layout
    out, day0 = [], None
    for part in parts:
        names = heading(part.rows[0][1], sep) if part.rows else []
        column = next((j for j, c in enumerate(names) if c.lower() != "x_value"), 1)
        begin, start = column_start(part.fields, column), None
        if begin is not None:
            day0 = begin[0] if day0 is None else day0
            start = (begin[0] - day0) * 86400.0 + begin[1]
        out.append(LvmSegment(part.number, part.line, tuple(names),
                              column_rate(part.fields, column, comma),
                              max(len(part.rows) - 1, 0), start))
    return tuple(out)


def _table_fs(t, rate, consts):
    """Hz from a time column (its median step, when every row has one) or a constant
    column (:data:`_RATE_NAMES`), else None."""
    fs = uniform_rate(t) if len(t) > 1 else None
    if fs is not None:
        return fs
    for j, kind in rate.items():
        value = consts.get(j)
        if value is not None and value > 0:
            return float(value if kind == "rate" else 1.0 / value)
    return None


def load_daisy(path, columns=(0, 1)):
    """Read a DaISy-style whitespace-separated data file (one sample per line).

    Parameters
    ----------
    path : str or path-like
        The ``.dat`` file; blank lines and lines starting with ``#`` or ``%`` are skipped.
    columns : (int, int), default (0, 1)
        Zero-based columns of the input and the output.

    Returns
    -------
    u, y : ndarray of float, shape (N,)

    Raises
    ------
    DataError
        Missing or unreadable file, no data, ragged rows, too few columns, non-numeric or
        non-finite values.
    """
    try:
        cu, cy = (_index(c) for c in columns)
    except (TypeError, ValueError):
        raise OptionError(f"columns must be two column indices, got {columns!r}") from None
    if cu < 0 or cy < 0:
        raise OptionError(f"columns must be >= 0, got {columns!r}")
    path, lines = _text_lines(path, "data file")
    data, width = [], None
    for k, text in enumerate(lines):
        cells = text.split()
        if not cells or cells[0].startswith(("#", "%")):
            continue
        line = k + 1
        if width is None:
            width = len(cells)
            if width <= max(cu, cy):
                raise DataError(
                    f"{path!r} line {line}: {width} column(s), but columns={tuple(columns)} "
                    "needs the input and output columns; check the file or columns")
        elif len(cells) != width:
            raise DataError(
                f"{path!r} line {line}: {len(cells)} columns, expected {width} as on the first "
                "data line")
        data.append([_number(path, line, f"column {j}", c) for j, c in enumerate(cells)])
    if not data:
        raise DataError(f"{path!r} holds no data lines: expected columns input output")
    values = np.array(data)
    return values[:, cu].copy(), values[:, cy].copy()


def _index(value):
    """operator.index that rejects bools."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(value)
    return int(value)


# --------------------------------------------------------------------------- DAQ export

@dataclass(frozen=True)
class DaqRecords:
    """Channels of a data-acquisition export.

    Attributes
    ----------
    fs : float or None
        Sampling rate in Hz (from the header; None when a ``.mat`` file does not give it).
    channels : dict of str to ndarray of float, shape (N,)
        Samples of every channel, by the header's name (e.g. ``"CHANNEL0"``), read-only.
    events : tuple of (int, str)
        ``(sample index, text)`` of every event mark (e.g. ``"DAQ Start"``).
    header : dict of str to str
        The ``key: value`` header lines.
    matrices : dict of str to ndarray
        A ``.mat`` file's numeric arrays of two or more dimensions (singleton dimensions
        squeezed), by MATLAB name, read-only; empty for other files.
    others : dict of str to ndarray of float
        A ``.mat`` file's real vectors of 16 or more samples but another length than the
        records (a generator's one period, beside records of several), read-only; empty
        for other files.
    """

    fs: float
    channels: dict
    events: tuple = ()
    header: dict = field(default_factory=dict)
    matrices: dict = field(default_factory=dict)
    others: dict = field(default_factory=dict)

    @property
    def n_samples(self):
        """Number of samples N per channel."""
        return next(iter(self.channels.values())).size

    def realisations(self, name):
        """The records of the matrix ``name`` (its rows, or its columns, as
        ``load_records_mat`` reads them: ``uval(1,:)``, ``uval(2,:)``, ...) as an (R, N)
        float array, or None when ``name`` is no such matrix of the records' length.

        Parameters
        ----------
        name : str

        Returns
        -------
        ndarray of float, shape (R, N), or None
        """
        m = self.matrices.get(name)
        axis = (None if m is None or m.dtype.kind not in "iuf" else
                record_axis(m, MAX_MATRIX_RECORDS))
        if axis is None:
            return None
        rows = np.asarray(m if axis == 0 else m.T, float)
        return rows if rows.shape[1] == self.n_samples else None


def _daq_header(path, lines):
    first = lines[0].split(":", 1) if lines else [""]
    try:
        n_head = int(first[1]) if first[0].strip().lower() == "header size" else -1
    except (IndexError, ValueError):
        n_head = -1
    if not 2 <= n_head <= min(len(lines), 1000):
        raise DataError(f"{path!r} line 1: expected 'Header Size: N' (a DAQ export with N "
                        f"header lines), got {shown_cell(lines[0].strip() if lines else '')}")
    header = {}
    for text in lines[1:n_head - 1]:
        key, _, value = text.partition(":")
        header[key.strip()] = value.strip()
    names = [c.strip() for c in lines[n_head - 1].split(",")]
    chans = [j for j, c in enumerate(names) if c.upper().startswith("CHANNEL")]
    if not chans or chans != list(range(2, 2 + len(chans))):
        raise DataError(f"{path!r} line {n_head}: expected 'Sample Number, Date/Time, "
                        f"CHANNEL0, ...', got {shown_cell(lines[n_head - 1].strip())}")
    try:
        fs = float(header.get("Sampling Rate", ""))
    except ValueError:
        fs = float("nan")
    if not (np.isfinite(fs) and fs > 0):
        raise DataError(f"{path!r}: the header has no valid 'Sampling Rate: HZ' line")
    return n_head, header, [names[j] for j in chans], fs


def load_daq_records(path):
    """Read a data-acquisition export (as in the shipped actuator test; ``.xz`` accepted).

    Layout: line 1 ``Header Size: H``; ``key: value`` lines (``Sampling Rate: 1000``,
    ``Sample Count: N``, ...); line H ``Sample Number, Date/Time, CHANNEL0, ..., Events``;
    then one comma-separated row per sample: sample number, time stamp, the channels and
    optional event texts.

    Parameters
    ----------
    path : str or os.PathLike
        The export (plain text, or ``.xz``-compressed).

    Returns
    -------
    DaqRecords

    Raises
    ------
    DataError
        Not such a file, a bad header, non-numeric or non-finite samples (naming the line),
        a sample count that differs from the header's, samples out of order.
    """
    path, lines = _text_lines(path)
    lines = [t.rstrip("\r") for t in lines]
    n_head, header, names, fs = _daq_header(path, lines)
    n_ch = len(names)
    cols = [[] for _ in range(n_ch)]
    events = []
    for k in range(n_head, len(lines)):
        text = lines[k]
        if not text.strip():
            continue
        cells = text.split(",")
        if len(cells) < 2 + n_ch:
            raise DataError(f"{path!r} line {k + 1}: expected sample number, time stamp and "
                            f"{n_ch} channels, got {len(cells)} fields")
        for j in range(n_ch):
            cols[j].append(_number(path, k + 1, names[j], cells[2 + j]))
        if len(cells) > 2 + n_ch:
            events.append((len(cols[0]) - 1, ", ".join(c.strip() for c in cells[2 + n_ch:])))
    n = len(cols[0])
    if n < 2:
        raise DataError(f"{path!r} holds {n} sample(s): expected a record after the header")
    count = header.get("Sample Count")
    if count is not None and count.isdigit() and int(count) != n:
        raise DataError(f"{path!r}: the header says Sample Count: {count}, the file holds {n} "
                        "samples; the file is truncated or damaged")
    channels = {}
    for name, values in zip(names, cols):
        arr = np.array(values)
        arr.setflags(write=False)
        channels[name] = arr
    return DaqRecords(fs, channels, tuple(events), header)


def actuator_records(path=None):
    """Raw records of the servo-hydraulic actuator chirp test shipped with the package.

    Input: ``CHANNEL2`` (commanded displacement, x10 mm); output: ``CHANNEL0`` (measured
    displacement, x10 mm); ``CHANNEL1`` force (x9806.65 N); fs = 1000 Hz, 61 500 samples of
    a chirp of about 0.5-20 Hz. Source and license: ``datasets/actuator/SOURCE.md`` (MIT,
    github.com/DanielMaurelE/vRTHS_AMBC_MRdamper).

    Parameters
    ----------
    path : str or path-like, optional
        Another export in the same format (default: the shipped ``0A.txt.xz``).

    Returns
    -------
    DaqRecords
    """
    return load_daq_records(dataset_path(ACTUATOR_FILE) if path is None else path)


# --------------------------------------------------------------------------- robot arm

def _find_robot_arm():
    env = os.environ.get(SHARED_ENV)
    if env:
        for c in (os.path.join(env, "data", ROBOT_ARM_FILE), os.path.join(env, ROBOT_ARM_FILE)):
            if os.path.isfile(c):
                return c
        raise DataError(
            f"{SHARED_ENV}={env!r} holds neither data/{ROBOT_ARM_FILE} nor {ROBOT_ARM_FILE}; "
            f"unset {SHARED_ENV} to use the copy shipped with the package, or pass path=")
    return dataset_path(ROBOT_ARM_FILE)


def robot_arm(path=None):
    """Frequency response of the DaISy flexible robot arm (data set 96-009).

    Input: measured reaction torque (column 1); output: arm acceleration (column 2); 1024
    samples of a periodic excitation on the odd DFT bins. The sampling time is not given,
    so ``omega`` is normalised (rad/sample).

    Parameters
    ----------
    path : str or path-like, optional
        The ``robot_arm.dat`` file. Default: the copy shipped in
        ``freqid_casadi/datasets``, or ``$FREQID_SHARED/data/robot_arm.dat`` when that
        environment variable is set.

    Returns
    -------
    FrfEstimate
        One period of 1024 samples (``n_periods = 1``, so ``variance``, ``coherence`` and
        the weights are None) at the odd bins ``1, 3, ..., K``.

    Raises
    ------
    DataError
        The file cannot be found or read, or is malformed.

    Notes
    -----
    The period is taken from the data: the shortest divisor of the record length over which
    the input repeats (within 20% RMS). No shorter period than 1024 does: the input is
    *anti*-periodic over 512 samples (``u[n + 512] ~ -u[n]``, 6% RMS residual), the
    signature of an odd-bin excitation. The band ``K`` is the highest odd bin whose input
    power is within 20 dB of the maximum (K = 201); every odd bin below it is kept,
    including the dip of the measured torque near bins 57-61 at the arm's first resonance,
    where the FRF stays smooth. The even bins carry only noise and distortion (< -22 dB).
    Cite: B. De Moor et al., DaISy: Database for the Identification of Systems, 96-009.
    """
    path = _find_robot_arm() if path is None else path
    u, y = load_daisy(path)
    period = _detect_period(u, 0.2)
    probe = frf_from_periodic(u, y, period)
    top = int(probe.bins.max())
    bins = np.arange(1, top + 1, 2) if np.all(probe.bins % 2 == 1) else probe.bins
    return frf_from_periodic(u, y, period, bins=bins,
                             name="robot_arm (DaISy 96-009)")


_FS_NAMES = ("fs", "samplerate", "sample_rate", "sampling_rate", "samplingrate",
             "sampling_frequency", "srate", "sf")
_DT_NAMES = ("dt", "ts", "sample_time", "sampling_interval", "delta_t")
_T_NAMES = ("t", "time", "times", "tt", "t_s", "time_s")


def _mat_fs(path, arrays, n):
    """Sampling rate (Hz) that a ``.mat`` file states: a scalar ``fs`` (or ``SampleRate``
    ...) or ``dt``/``Ts`` (s), else a time vector ``t``/``time``/``times`` of the records'
    length, or one more or less (whose unit the file does not say: a published motor
    bench's ``time`` counts microseconds beside ``fs`` = 2500); None. A time vector whose
    rate differs from the stated one by other than a power of 1000 (ms, us stamps), or
    one a stamp off the records, is noted."""
    stated = stamped = None
    for key, arr in arrays.items():
        last = key.rsplit(".", 1)[-1].lower()
        value = float(arr) if arr.size == 1 and arr.dtype.kind in "iuf" else None
        if value is not None and np.isfinite(value) and value > 0 and stated is None:
            if last in _FS_NAMES:
                stated = (value, key)
            elif last in _DT_NAMES:
                stated = (1.0 / value, key)
        if last in _T_NAMES and arr.ndim == 1 and abs(arr.size - n) <= 1 and \
                arr.size > 1 and stamped is None:     # (0:dt:T beside T/dt samples)
            fs = uniform_rate(arr)
            if fs is not None:
                stamped = (fs, key, arr.size)
    if stated is None and stamped is not None and stamped[2] != n:
        warnings.warn(f"{path!r}: the sampling rate {stamped[0]:.6g} Hz from the steps of "
                      f"{stamped[1]} ({stamped[2]} stamps for {n} samples)", DataWarning,
                      stacklevel=3)
    if stated is None:
        return None if stamped is None else stamped[0]
    if stamped is not None:
        power = math.log(stated[0] / stamped[0], 1000.0)
        if abs(power - round(power)) > 1e-3:
            warnings.warn(f"{path!r}: {stamped[1]} steps at {stamped[0]:.6g} per unit, "
                          f"{stated[1]} says {stated[0]:.6g} Hz: used {stated[1]}",
                          DataWarning, stacklevel=3)
    return stated[0]


#: Largest spread of a time column's steps, relative to their mean, read as uniform
#: sampling: time stamps written with a few digits jitter by 1e-5 to 1e-4 of a step (a
#: published EMPS record: 4e-5 at 1 ms).
TIME_JITTER = 1e-3


def uniform_rate(t):
    """The sampling rate (Hz) of time stamps ``t`` (s) when they step uniformly (within
    :data:`TIME_JITTER`), from the whole span; else None.

    Parameters
    ----------
    t : array_like of float, shape (N,)

    Returns
    -------
    float or None
    """
    t = np.asarray(t, float).ravel()
    step = np.diff(t)
    if step.size == 0 or not np.all(np.isfinite(step)) or not np.all(step > 0):
        return None
    if np.ptp(step) > TIME_JITTER * step.mean():
        return None
    return float((t.size - 1) / (t[-1] - t[0]))


#: Most rows (or columns) of a matrix read as records, one each (``Acceleration(2,:)``).
MAX_MATRIX_RECORDS = 64


def _matrix_rows(arrays):
    """``arrays`` with each real matrix of a few rows (or columns) of samples, as a
    benchmark stores its sensors (``Acceleration``, 3 x 73728, or 3 x 1 x 49152), also
    given row by row as vectors named as MATLAB indexes them: ``Acceleration(2,:)``
    (``(:,2)`` for columns; :func:`~freqid_casadi.io.matrix_records`)."""
    return {**arrays, **matrix_records(arrays, MAX_MATRIX_RECORDS)}


def load_records_mat(path, min_records=2):
    """Time records of a MATLAB ``.mat`` file (v4 to v7.2; Octave's text format; a NumPy
    ``.npz`` archive by the same rules), by variable name.

    Parameters
    ----------
    path : str or os.PathLike
        Arrays of samples as variables (``u``, ``y``) or struct fields (``meas.input``,
        ``run(2).force``; each row of a matrix of a few rows, ``Acceleration(2,:)``, or
        column, ``(:,2)``); the sampling rate, if the file gives it, as a scalar ``fs``
        (``SampleRate``, ``Fs``, ...), ``dt``/``Ts`` in seconds, or a time vector ``t``.
    min_records : {2, 1}, default 2
        Fewest records of one length the file must hold: 2 for a file of inputs and
        outputs, 1 for a file that holds only the input or only the output (a benchmark
        that publishes ``uval`` and ``yval`` in two files).

    Returns
    -------
    DaqRecords
        ``channels``: every real vector of the records' length (the most common length of
        at least 16 samples), by MATLAB path; ``fs`` in Hz, or None when the file does not
        give it; ``header`` the other scalars (as text).

    Raises
    ------
    DataError
        Not a readable ``.mat`` file, or fewer than ``min_records`` real vectors of one
        length (no records).
    OptionError
        ``min_records`` not 1 or 2.
    """
    from ..io import read_mat_arrays

    if min_records not in (1, 2) or isinstance(min_records, bool):
        raise OptionError(f"min_records must be 1 or 2, got {min_records!r}")
    path, payload = read_regular_file(path, "records file")
    arrays = _matrix_rows(read_npz_arrays(path, payload)
                          if str(path).lower().endswith(".npz") else
                          read_mat_arrays(path, payload, MAX_FILE_BYTES // 8))
    vectors = {k: a for k, a in arrays.items()
               if a.ndim == 1 and a.size >= 16 and a.dtype.kind in "iuf"}
    sizes = [a.size for k, a in vectors.items()
             if k.rsplit(".", 1)[-1].lower() not in _T_NAMES]     # a time vector is no record
    if not sizes or max(sizes.count(n) for n in set(sizes)) < min_records:
        found = ", ".join(f"{k} {a.shape}" for k, a in list(arrays.items())[:8])
        what = ("two or more real vectors of one length" if min_records == 2 else
                "a real vector of 16 or more samples")
        raise DataError(f"{path!r} holds no time records ({what}): found "
                        f"{found or 'nothing numeric'}; save the input and output samples as "
                        "vectors, e.g. save(f, 'u', 'y', 'fs', '-v7')")
    n = max(set(sizes), key=lambda m: (sizes.count(m), m))
    channels = {}
    for key, a in vectors.items():
        if a.size == n and key.rsplit(".", 1)[-1].lower() not in _T_NAMES:
            v = np.array(a, float)
            if not np.all(np.isfinite(v)):
                i = int(np.flatnonzero(~np.isfinite(v))[0])
                raise DataError(f"{path!r}: variable {key!r} sample {i + 1} is {v[i]!r}, not "
                                "finite; repair or cut out the bad samples")
            v.flags.writeable = False
            channels[key] = v
    others = {k: np.array(a, float) for k, a in vectors.items()
              if a.size != n and k.rsplit(".", 1)[-1].lower() not in _T_NAMES}
    for v in others.values():
        v.flags.writeable = False
    header = {k: repr(a.item()) for k, a in arrays.items() if a.size == 1}
    matrices = {}
    for key, a in arrays.items():
        m = np.squeeze(a)
        if m.ndim >= 2 and m.dtype.kind in "iuf":
            m.flags.writeable = False
            matrices[key] = m
    return DaqRecords(_mat_fs(path, arrays, n), channels, (), header, matrices, others)
