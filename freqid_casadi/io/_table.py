"""The text-table parser behind :mod:`freqid_casadi.io.loaders` (L1).

Columns are named with the vocabulary of :mod:`freqid_casadi.io._columns` (re-exported here):
a header line, the ``columns=`` option, the variable names of a ``.mat`` file. Numbers are
ASCII decimal literals only: Python's ``float`` would also take ``1_0`` and non-ASCII
digits, which a data file never means.
"""

import cmath
import math
import re
import warnings
from dataclasses import dataclass, replace

import numpy as np

from ._columns import (_UNITS, COLUMN_HELP, DERIVED, ChannelChoice, Column, _layout_problem,
                       _quantity, columns_option, one_layout, parse_columns, parse_freq_unit,
                       recognise, several_responses, time_column, time_records, unquoted,
                       with_parameter, written_values)
from ._decode import decode_text
from ._headerless import WRAP_JUMP, check_guessed, suffix_columns
from ._same import check_same
from ._sweeps import one_sweep
from ._readfile import DataWarning
from ..errors import DataError, OptionError

__all__ = ["Column", "Table", "parse_columns", "parse_freq_unit", "read_table",
           "table_response", "COLUMN_HELP"]

_F = r"(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
NUMBER = re.compile(rf"[+-]?(?:{_F}|inf|infinity|nan)", re.ASCII | re.IGNORECASE)
_CPLX = re.compile(rf"[+-]?{_F}(?:[+-](?:{_F})?j)?|[+-]?(?:{_F})?j", re.ASCII)
_DECIMAL_COMMA = re.compile(r"(?<=\d),(?=\d)", re.ASCII)
#: Marks of a comment line: ``#``, ``%`` (MATLAB), ``!`` (Touchstone) and ``*`` (Room EQ
#: Wizard's and ARTA's exports, FRD files).
COMMENTS = ("#", "%", "!", "*")
_CELL_MARK = re.compile(r"\t[#%!*]\t")
#: LTspice's export of an AC analysis: a polar cell ``(<dB>dB,<deg>°)`` (the degree sign
#: in any encoding's reading), a Cartesian cell ``<re>,<im>`` (both in exponent form, as
#: LTspice writes them: a decimal comma ``1,5`` is not one), and a trace name ``V(out)``,
#: ``I(R1)``, ``V(out)/V(in)`` beside the header's ``Freq.`` (Hz).
_LT_POLAR = re.compile(rf"\(\s*([+-]?{_F})\s*(dB)?\s*,\s*([+-]?{_F})\s*[^\d\s,()]{{1,2}}\s*\)",
                       re.ASCII)
_LT_CARTESIAN = re.compile(r"([+-]?\d+\.\d*[eE][+-]?\d+),([+-]?\d+\.\d*[eE][+-]?\d+)",
                           re.ASCII)
_LT_TRACE = re.compile(r"[VI][a-z]?\(.+\).*", re.IGNORECASE)
#: The line before each run of an LTspice export with ``.step`` (``.mc``: ``Run: 1/100``).
_LT_STEP = re.compile(r"\s*Step Information:\s*(.*?)\s*(?:\(\s*(?:Step|Run):\s*\d+\s*/\s*"
                      r"\d+\s*\))?\s*$", re.IGNORECASE)
#: One whitespace-separated cell of a line with decimal commas: ``-14,210``, ``20``, ``1,5e-3``.
_COMMA_CELL = re.compile(r"[+-]?\d+(?:,\d+)?(?:[eE][+-]?\d+)?", re.ASCII)


@dataclass
class Table:
    """Parsed columns: ``values[role]`` (float, or complex for 'complex'), ``rows`` the file
    line (or matrix row) of each sample, ``where`` 'line' or 'row'."""

    path: str
    columns: tuple
    values: dict
    rows: np.ndarray
    where: str = "line"

    @property
    def lines(self):
        """File line of every row (None for a matrix)."""
        return self.rows if self.where == "line" else None

    def label(self, role):
        return next(c.label for c in self.columns if c.role == role)

    def unit(self, role):
        return next(c.unit for c in self.columns if c.role == role)

    def at(self, i):
        return f"{self.path!r} {self.where} {int(self.rows[i])}"


# --------------------------------------------------------------------------- text

def _separator(first):
    if _spaced_commas(first):
        return None
    return next((sep for sep in (";", "\t", ",") if sep in first), None)


def _spaced_commas(text):
    """True for a line of two or more whitespace-separated numbers written with decimal
    commas and no points (``20,000 72,431 -14,210``: Room EQ Wizard's export in a German
    locale); a comma-separated line (``20, 0, 6``, ``1,2,3``) is not one."""
    cells = text.split()
    return len(cells) >= 2 and "," in text and all(_COMMA_CELL.fullmatch(c) for c in cells)


def _splitter(sep):
    if sep is None:
        return _split_space
    if sep == "\t":
        return lambda line: _trimmed([c.strip() for c in line.split(sep)])
    return lambda line: (_quoted_cells(line, sep) if '"' in line else
                         [c.strip() for c in line.split(sep)])


def _quoted_cells(line, sep):
    """Cells of a line whose quoted cells may hold the separator (a field solver's
    ``"mag(S(Port1,Port1)) []"``), each in its quotes as written."""
    cells, cell, quoted = [], [], False
    for ch in line:
        if ch == '"' and (quoted or not "".join(cell).strip()):   # (Z" as ZView writes Z'')
            quoted = not quoted
        if ch == sep and not quoted:
            cells.append("".join(cell).strip())
            cell = []
        else:
            cell.append(ch)
    return cells + ["".join(cell).strip()]


def _trimmed(cells):
    """``cells`` without the empty cell a trailing tab leaves (``1\t2\t3\t``, as some
    analysers end every line)."""
    return cells[:-1] if len(cells) > 1 and cells[-1] == "" else cells


def _tab_led_tables(rows):
    """``rows`` with the leading tab of each line of a tab-led table removed: a run of
    three or more lines that begin with a tab, the first of them not numbers (a header),
    to the end of the file or the next line that does not (Gamry's ``\tPt\tTime\tFreq``,
    its units line and rows). A table whose first column is only sometimes empty has no
    such run and keeps its empty cells."""
    out, k = list(rows), 0
    while k < len(out):
        if not out[k][1].startswith("\t"):
            k += 1
            continue
        end = k
        while end < len(out) and out[end][1].startswith("\t"):
            end += 1
        head = [c.strip() for c in out[k][1].split("\t") if c.strip()]
        if end - k >= 3 and head and not all(_is_value(c) for c in head):
            out[k:end] = [(line, text[1:]) for line, text in out[k:end]]
        k = end
    return out


def _fast_values(rows, cols, sep):
    """All cells as floats, shape (rows, columns), when every row is plain numbers (one regex
    per row, C-speed conversion); None otherwise (the slow path then names the bad cell)."""
    if any(c.role in ("complex", "skip") for c in cols):
        return None
    num = r"[ \t]*[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?[ \t]*"
    gap = r"[ \t]+" if sep is None else re.escape(sep)
    tail = r"\t?" if sep == "\t" else ""
    row = re.compile(rf"{num}(?:{gap}{num}){{{len(cols) - 1}}}{tail}", re.ASCII)
    if not all(row.fullmatch(text) for _, text in rows):
        return None
    joined = "\n".join(text for _, text in rows)
    cells = (joined if sep is None else joined.replace(sep, " ")).split()
    if len(cells) != len(rows) * len(cols):
        return None
    return np.array(cells, dtype=float).reshape(len(rows), len(cols))


def _split_space(line):
    out = []
    for tok in line.split():
        if out and tok[:1] in "[(" and not _is_value(tok):
            out[-1] = f"{out[-1]} {tok}"
        else:
            out.append(tok)
    return out




def _complex_text(cell):
    s = cell.replace(" ", "")
    if s.startswith("(") and s.endswith(")"):
        s = s[1:-1]
    return s[:-1] + "j" if s.endswith("i") else s


def _is_value(cell):
    cell = unquoted(cell)
    return bool(NUMBER.fullmatch(cell) or _CPLX.fullmatch(_complex_text(cell))
                or _ltspice_value(cell) is not None)


def _ltspice_value(cell):
    """The complex number of an LTspice export's cell, or None: polar ``(-6.02e+000dB,
    -1.80e+002°)`` (dB or, without it, linear magnitude; the phase in degrees) or
    Cartesian ``-5.0e-001,-6.1e-017``."""
    m = _LT_POLAR.fullmatch(cell)
    if m:
        mag = float(m.group(1))
        mag = 10.0 ** (mag / 20.0) if m.group(2) else mag
        return complex(mag * cmath.exp(1j * math.radians(float(m.group(3)))))
    m = _LT_CARTESIAN.fullmatch(cell)
    return complex(float(m.group(1)), float(m.group(2))) if m else None


def shown_cell(cell):
    """``repr`` of a table cell for an error message, cut to 40 characters."""
    return repr(cell if len(cell) <= 40 else cell[:37] + "...")


def _content(path, text, max_rows):
    rows, comment = [], None
    for k, line in enumerate(text.split("\n")):
        line = line.rstrip()
        # (a tab-separated row whose first cell is '#', as Gamry heads its units, is no
        # comment: '\t#\ts\tHz\tohm')
        if line.lstrip().startswith(COMMENTS) and not _CELL_MARK.match(line):
            note = line.lstrip().lstrip("".join(COMMENTS)).strip()  # '## f re im' too
            comment = (k + 1, note) if not rows and note else comment
        elif line.strip():
            rows.append((k + 1, line))
            if len(rows) > max_rows + 1:
                raise DataError(
                    f"{path!r} has more than {max_rows} data rows (limit "
                    "freqid_casadi.io.loaders.MAX_ROWS); thin the data or raise that limit")
    if not rows:
        raise DataError(f"{path!r} is empty: expected a header such as 'omega,real,imag' "
                        "and data rows")
    return _comment_header(path, rows, comment)


def _comment_header(path, rows, comment):
    """``rows`` led by the last comment line before the data when the data have no header
    and that line names every column (``% f [Hz]  Re  Im``, as analysers write); a
    DataError when it names a first column of time (``## sample,0 (F144/W_0d_0) ,...``,
    an acoustics program's impulse responses)."""
    sep = _separator(rows[0][1])
    first = _row_cells(rows[0][1])
    if comment is None or not all(_is_value(c) for c in first):
        return rows
    cells = _splitter(sep)(comment[1]) if sep and sep in comment[1] else \
        _split_space(comment[1])
    if len(cells) == len(first) > 1 and time_column(unquoted(cells[0])):
        raise DataError(time_records(path, cells))
    cols = one_layout([recognise(unquoted(c)) for c in cells])
    if len(cells) != len(first) or None in cols or _layout_problem(cols):
        return rows
    return [(comment[0], (sep or " ").join(cells))] + rows


def _header_columns(path, cells, parameter=None, line=1):
    cols = [recognise(unquoted(c)) for c in cells]
    traces = [unquoted(c) for c in cells[1:]]
    ltspice = unquoted(cells[0]) == "Freq." and traces and all(map(_LT_TRACE.fullmatch, traces))
    if ltspice:
        # LTspice's export of an AC analysis: frequencies in Hz, each trace one complex
        # column (polar dB and degrees, or Cartesian)
        cols = [Column("freq", "hz", "Freq.")] + [Column("complex", None, unquoted(c))
                                                  for c in cells[1:]]
    if parameter is not None and None not in cols:
        cols = with_parameter(cols, parameter, repr(path))
    if not (ltspice and len(traces) > 1):        # (LTspice's traces are other signals)
        cols = one_layout(cols)
    problem, choices = None, []
    if cols[0] is None and len(cells) > 1 and time_column(unquoted(cells[0])):
        raise DataError(time_records(path, [unquoted(c) for c in cells]))
    if any(c is None for c in cols) and not ltspice:
        cols = _known_layout(path, cells, cols, parameter)
    if any(c is None for c in cols):
        bad = cells[[c is None for c in cols].index(True)]
        problem = f"column {unquoted(bad)!r} is not a known name"
    else:
        problem = _layout_problem(cols)
        if problem:
            more, choices = several_responses(cells, cols, traces if ltspice else ())
            problem += more
    if problem:
        raise ChannelChoice(
            f"{path!r}: unrecognised header {','.join(unquoted(c) for c in cells)!r} "
            f"({problem}); "
            f"{'the first line' if line == 1 else f'the header (line {line})'} must be "
            "'omega,real,imag' or "
            "'omega,magnitude_db,phase_deg' (rad/s), or another layout such as "
            "'freq_hz,mag_db,phase_deg'; or pass columns=... (command line --columns) to "
            f"{COLUMN_HELP}", choices)
    derived = [repr(c.label) for c in cols if c.unit == DERIVED]
    if derived:
        warnings.warn(f"{path!r}: skipped {', '.join(derived)}: a quantity the analyser "
                      "derives from the response (an equivalent resistance, inductance or "
                      "capacitance, a quality or dissipation factor), not the response",
                      DataWarning, stacklevel=5)
    return tuple(cols)


def _known_layout(path, cells, cols, parameter):
    """``cols`` with the columns of unknown names skipped, when the known ones give one
    frequency and one complete response (an impedance analyser's export beside its
    time, potential, current and cycle columns), with a :class:`DataWarning` naming
    what was read and what was left out; ``cols`` as given otherwise."""
    trial = tuple(Column("skip", None, unquoted(cells[j])) if c is None else c
                  for j, c in enumerate(cols))
    if parameter is not None:
        try:
            trial = with_parameter(trial, parameter, repr(path))
        except DataError:
            return cols
    trial = one_layout(trial)
    if _layout_problem(trial) and any(_quantity(c.label) == "z" for c in trial):
        # an impedance analyser's export: the impedance, not the quantities derived from
        # it (EC-Lab's Re(M), Re(Permittivity), ... beside Re(Z)/Ohm)
        trial = one_layout(tuple(
            c if c.role in ("freq", "skip") or _quantity(c.label) == "z"
            else Column("skip", None, c.label) for c in trial))
    roles = {c.role for c in trial} - {"freq", "skip"}
    if [c.role for c in trial].count("freq") != 1 or _layout_problem(trial) \
            or roles == {"complex"}:
        # (a column named as a complex quantity, Z or H, beside a phase of a name the
        # reader does not know, 'θz(°)', is a magnitude: the whole header is asked for)
        return cols
    unknown = ", ".join(repr(unquoted(cells[j])) for j, c in enumerate(cols) if c is None)
    read = ", ".join(repr(c.label) for c in trial if c.role != "skip")
    warnings.warn(f"{path!r}: read {read}; left out columns of names the reader does not "
                  f"know: {unknown}; to read others, pass columns=... (command line "
                  "--columns)", DataWarning, stacklevel=5)
    return trial


def _default_columns(path, cells):
    by_suffix = suffix_columns(path, len(cells))
    if by_suffix is not None:
        return by_suffix
    if len(cells) == 3:
        return (Column("freq", None, "frequency"), Column("re", None, "real"),
                Column("im", None, "imag"))
    if len(cells) == 2 and not NUMBER.fullmatch(unquoted(cells[1])):
        return Column("freq", None, "frequency"), Column("complex", None, "response")
    example = ",".join(["freq_hz", "mag_db", "phase_deg"] + ["skip"] * (len(cells) - 3))
    records = (" If it holds time records (input and output samples), estimate the "
               "frequency response first: freqid frf FILE --out frf.csv (see freqid frf "
               "--help)." if len(cells) == 2 else "")
    raise DataError(
        f"{path!r} has no header and {len(cells)} columns: cannot tell what they are; pass "
        f"columns=... (command line --columns), e.g. columns='{example}', to "
        f"{COLUMN_HELP}; or add a header line.{records}")


def _resolve_units(path, cols, freq_unit, header):
    """Columns with the frequency unit filled in from ``freq_unit``; ``header`` is the
    header's text (None for a headerless file or a matrix)."""
    freq = next(c for c in cols if c.role == "freq")
    if freq.unit is None:
        if freq_unit is None:
            what = (f"unrecognised header {header!r}: column {freq.label!r} has no unit"
                    if header else "it has no header line" + (
                        "; its columns are read as frequency, real, imaginary unless columns="
                        "'freq_hz,mag_db,phase_deg' (--columns) says otherwise"
                        if [c.role for c in cols] == ["freq", "re", "im"]
                        and cols[1].label == "real" else ""))
            phase = [c for c in cols if c.role == "phase" and c.unit is None]
            also = (f"; the phase column {phase[0].label!r} does not give its unit either: "
                    "name it phase_deg or phase_rad (or 'phase [deg]')" if phase else "")
            raise DataError(
                f"{path!r}: the frequency unit is unknown ({what}): pass freq_unit='Hz' or "
                "freq_unit='rad/s' (command line --freq-unit hz|rad/s), or name the column "
                f"'omega' (rad/s) or 'freq_hz' / 'f [Hz]' (Hz) in a header{also}")
        freq_unit_col = Column("freq", freq_unit, freq.label)
        cols = tuple(freq_unit_col if c is freq else c for c in cols)
    elif freq_unit is not None and freq_unit != freq.unit:
        raise DataError(f"{path!r}: freq_unit={freq_unit!r} contradicts column {freq.label!r} "
                        f"({freq.unit}); drop freq_unit or fix the header")
    phase = [c for c in cols if c.role == "phase"]
    if phase and phase[0].unit is None:
        raise DataError(f"{path!r}: phase column {phase[0].label!r} does not give its unit; "
                        "name it phase_deg or phase_rad (or 'phase [deg]'), or pass columns=")
    return cols


def _parse_cell(table_path, line, col, cell):
    cell = unquoted(cell)
    if col.role == "complex":
        text = _complex_text(cell)
        if _CPLX.fullmatch(text):
            return complex(text)
        value = _ltspice_value(cell)
        if value is not None:
            return value
    elif NUMBER.fullmatch(cell):
        return float(cell)
    hint = ""
    if "_" in cell or any(ord(ch) > 127 for ch in cell):
        hint = " (only ASCII decimal numbers such as 1.5e-3 are read)"
    elif "," in cell:
        hint = (" (decimal commas are read only in a file separated by semicolons, tabs or "
                "spaces with no decimal points; save the file with decimal points)")
    what = "a complex number like 1+2j" if col.role == "complex" else "a number"
    raise DataError(f"{table_path!r} line {line}, column {col.label!r}: {shown_cell(cell)} is not "
                    f"{what}{hint}")


def _decimal_commas(rows, sep):
    """``rows`` with decimal commas (``0,5``) written as points, when the separator is a
    semicolon or a tab (a European spreadsheet's export), or whitespace with every row
    holding one made of numbers only (:func:`_spaced_commas`), and no row holding one also
    holds a point (which would make the comma a thousands separator); else ``rows``
    unchanged."""
    if sep not in (";", "\t", None):
        return rows
    marked = [bool(_DECIMAL_COMMA.search(text)) for _, text in rows]
    if not any(marked) or any(m and "." in text for m, (_, text) in zip(marked, rows)):
        return rows
    if sep is None and not all(_spaced_commas(t) for m, (_, t) in zip(marked, rows) if m):
        return rows
    return [(k, _DECIMAL_COMMA.sub(".", text)) for k, text in rows]


def _units_row(first, rows, split):
    """Header cells and rows with a second header line of units (``Hz  dB  deg``, as some
    acquisition software writes) merged into the header as ``name [unit]``."""
    units = [unquoted(c).strip("[]()").strip().lower() for c in split(rows[1][1])]
    if len(units) != len(first) or not all(u in _UNITS or u == "-" for u in units) \
            or all(u in ("", "-") for u in units):
        return first, rows
    named = [c if u in ("", "-") else f"{unquoted(c)} [{u}]" for c, u in zip(first, units)]
    return named, rows[:1] + rows[2:]


#: Lines searched for the start of the data (the longest preamble read).
_PREAMBLE_LINES = 200
#: Lines between a header and its data (a unit line, ``Units:``, a blank-ish line).
_HEADER_GAP = 6
_FREQ_UNITS = {"hz": "hz", "rad/s": "rad/s", "rad/sec": "rad/s", "rads": "rad/s"}
_META = re.compile(r"^[^,;\t]{1,60}?\s*[:=]")


def _row_cells(text):
    """Cells of one line split by its own separator (decimal commas read as points in a
    semicolon- or tab-separated line)."""
    sep = _separator(text)
    if sep in (";", "\t") and "." not in text or sep is None and _spaced_commas(text):
        text = _DECIMAL_COMMA.sub(".", text)
    return _splitter(sep)(text)


def _data_start(rows):
    """Index of the first of three consecutive rows of numbers with one cell count (or of
    the last rows, if fewer), searched in the first :data:`_PREAMBLE_LINES`; None if the
    file's top holds no such block."""
    counts = []
    for k, (_, text) in enumerate(rows[:_PREAMBLE_LINES + 3]):
        cells = _row_cells(text)
        counts.append(len(cells) if len(cells) >= 2 and all(_is_value(c) for c in cells)
                      else 0)
        if k >= 2 and counts[k - 2] and counts[k - 2] == counts[k - 1] == counts[k]:
            return k - 2
    n = len(counts)
    if n < len(rows) or not n or not counts[-1]:
        return None
    j = n - 1
    while j > 0 and counts[j - 1] == counts[-1]:
        j -= 1
    return j


def _header_at(text, sep, ncols):
    """Header cells of ``text`` when it names ``ncols`` columns of a valid layout, else
    None (split by the data's separator, or its own, or whitespace)."""
    for how in (sep, _separator(text), None):
        if how is not None and how not in text:
            continue
        cells = _splitter(how)(text)
        cols = one_layout([recognise(unquoted(c)) or Column("skip", None, unquoted(c))
                           for c in cells])      # (names it does not know: see _known_layout)
        if len(cells) == ncols and [c.role for c in cols].count("freq") == 1 \
                and not _layout_problem(cols):
            return cells
    return None


def _unit_tokens(text):
    tokens = text.replace(";", "\t").replace(",", "\t").split("\t") if any(
        c in text for c in ";,\t") else text.split()
    return [t.strip().strip("[]()").strip().lower() for t in tokens if t.strip()]


def _with_units(cells, between):
    """Header ``cells`` completed by the unit lines ``between`` header and data: a line
    whose first token is a frequency unit (``Hz  (m/s\u00b2)(N)``, ``Hz dB deg``) gives the
    frequency unit, and dB / deg / rad of aligned columns; other lines (``Units:``) are
    ignored."""
    for _, text in between:
        if not _unit_line(text):
            continue
        tokens = _unit_tokens(text)
        if len(tokens) == len(cells):        # each column's unit under it
            units = [_FREQ_UNITS.get(t, "") if getattr(recognise(unquoted(c)), "role", None)
                     == "freq" else t if _UNITS.get(t) in ("db", "deg", "rad") else ""
                     for c, t in zip(cells, tokens)]
        elif tokens[0] in _FREQ_UNITS:
            units = [_FREQ_UNITS[tokens[0]]] + [""] * (len(cells) - 1)
        else:
            continue
        out = []
        for cell, unit in zip(cells, units):
            col = recognise(unquoted(cell))
            if col is None:                  # a column of a name the reader does not know
                out.append(unquoted(cell))
                continue
            has = col.unit is not None and col.role in ("freq", "phase") or (
                col.role == "mag" and _UNIT_IN.search(cell))
            out.append(f"{unquoted(cell)} [{unit}]" if unit and not has else unquoted(cell))
        return out
    return [unquoted(c) for c in cells]


_UNIT_IN = re.compile(r"db|[\[(]", re.IGNORECASE)


def _preamble(path, rows, columns):
    """``rows`` from the header on: metadata lines before it (``Units: Ratio``, channel
    and date lines, as analysers export) are dropped, and the unit line between header
    and data (``Hz  (m/s\u00b2)(N)``) is merged into the header; both stated by a
    :class:`DataWarning`. Unchanged when the first line is data or the header line itself
    is followed by data."""
    if all(_is_value(c) for c in _row_cells(rows[0][1])):
        return rows
    i = _data_start(rows)
    if i is None:
        return rows
    sep = _separator(rows[i][1])
    ncols = len(_row_cells(rows[i][1]))
    found = [k for k in range(i - 1, max(-1, i - 1 - _HEADER_GAP), -1)
             if _header_at(rows[k][1], sep, ncols)]
    # a unit line names every column too ('Hz  dB  deg'): the names above it come first
    h = next((k for k in found if not _unit_line(rows[k][1])), found[0] if found else None)
    if h is None or columns is not None:
        if i > 1 and columns is not None or _metadata(rows[:i]):
            _note_preamble(path, rows[:i], "the data")
            return rows[i:]
        k = next((k for k in range(i - 1, 0, -1)          # the header's error names it
                  if len(_row_cells(rows[k][1])) == ncols and not _unit_line(rows[k][1])),
                 0)
        return rows[k:]
    if h == 0 and i == 1:
        return rows
    between = rows[h + 1:i]
    if not all(_META.match(t) or _unit_line(t) or len(_row_cells(t)) == 1 or _END.match(t)
               for _, t in between):             # (ZPlot's 'End Comments' line too)
        return rows              # the rows under the header are bad data: say so there
    cells = _with_units(_header_at(rows[h][1], sep, ncols), between)
    if h:                     # (a header with its unit line alone is the file's own layout)
        _note_preamble(path, rows[:h], f"the header on line {rows[h][0]}")
        if between:
            _note_units(path, between, cells)
    if sep is None:            # whitespace-separated data: keep 'Real Part' one cell
        cells = ["_".join(c.split()) for c in cells]
    return [(rows[h][0], (sep or " ").join(cells))] + rows[i:]


#: A closing line after the data: ``[End]``, ``End of data``, ``ENDOFFILE`` (a VNA
#: script's last line), ``Key: value``.
_END = re.compile(r"^\s*(?:\[.*\]|\**\s*end(?:offile)?\b.*"
                  r"|[^,;\t\d.+-][^,;\t]{0,59}?\s*[:=].*)$", re.IGNORECASE)


def _one_run(path, rows, record):
    """``(rows, True)``: the rows of one run of an LTspice export with ``.step`` runs (a
    ``Step Information: Hu=40 T=0  (Step: 1/2)`` line before each), run ``record`` (0-based;
    the only one when None); ``(rows, False)`` unchanged when it has no such line (a
    ``record`` is then a sweep's, :func:`~freqid_casadi.io._sweeps.one_sweep`).

    Raises
    ------
    DataError
        Several runs and no ``record``: the message lists them.
    OptionError
        ``record`` out of range.
    """
    # (only LTspice writes them, below its header 'Freq.': other files are not scanned)
    ltspice = rows[0][1].lstrip().startswith("Freq.")
    marks = [k for k, (_, text) in enumerate(rows) if ltspice and _LT_STEP.match(text)]
    if not marks:
        return rows, False
    runs = [rows[a + 1:b] for a, b in zip(marks, marks[1:] + [len(rows)])]
    names = [_LT_STEP.match(rows[k][1]).group(1) or f"run {j + 1}" for j, k in enumerate(marks)]
    if record is None and len(runs) > 1:
        shown = "; ".join(f"{j}: {n}" for j, n in enumerate(names[:6]))
        raise DataError(f"{path!r} holds {len(runs)} runs of an LTspice .step ({shown}"
                        f"{'; ...' if len(runs) > 6 else ''}): pass record=0..{len(runs) - 1} "
                        "to load() (command line --record K) to read one")
    k = 0 if record is None else record
    if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(runs):
        raise OptionError(f"record={record!r} is out of range: {path!r} holds {len(runs)} "
                          f"run(s), numbered 0..{len(runs) - 1}")
    return rows[:marks[0]] + runs[k], True


#: Most closing lines after the data that :func:`_footer` drops (a Brüel & Kjær PULSE
#: ASCII export ends with 7: ``TagsBegin:``, ``OverLoad:``, ... ``TagScalesEnd:``).
MAX_FOOTER = 16


def _footer(path, rows):
    """``rows`` without up to :data:`MAX_FOOTER` closing lines after the data that are no
    data (``[End]``, ``End of data``, ``Key: value``), stated by a DataWarning."""
    n = len(rows)
    k = n
    while k > 1 and n - k < MAX_FOOTER and _END.match(rows[k - 1][1]):
        k -= 1
    if k == n or not all(_is_value(c) for c in _row_cells(rows[k - 1][1])):
        return rows
    warnings.warn(f"{path!r}: skipped {n - k} line(s) after the data "
                  f"({_lines(rows[k][0], rows[-1][0])}, the first "
                  f"{shown_cell(rows[k][1].strip())})",
                  DataWarning, stacklevel=5)
    return rows[:k]


def _metadata(rows):
    """True if every row is a ``Key: value`` / ``Key = value`` line or a single cell."""
    return all(_META.match(t) or len(_row_cells(t)) == 1 for _, t in rows)


def _unit_line(text):
    """Whether ``text`` is a line of units under a header: its first token a frequency
    unit (``Hz  dB  deg``), or a frequency unit among tokens none of which is a number
    (Gamry's ``#  s  Hz  ohm  ohm  V  ohm  °``)."""
    tokens = _unit_tokens(text)
    return bool(tokens) and (tokens[0] in _FREQ_UNITS or len(tokens) > 1 and any(
        t in _FREQ_UNITS for t in tokens) and not any(_is_value(t) for t in tokens) and all(
        t in _UNITS or recognise(t) is None for t in tokens))   # no name: 'Freq Hz Gain dB'


def _note_preamble(path, skipped, what):
    first = " ".join(skipped[0][1].split())
    gaps = skipped[-1][0] - skipped[0][0] + 1 - len(skipped)     # blank and comment lines
    warnings.warn(f"{path!r}: skipped {len(skipped)} line(s) of metadata before {what} "
                  f"({_lines(skipped[0][0], skipped[-1][0])}"
                  f"{f' less {gaps} blank or comment line(s)' if gaps else ''}, the first "
                  f"{shown_cell(first)})", DataWarning, stacklevel=5)


def _lines(first, last):
    """``'line 3'`` or ``'lines 3-7'``."""
    return f"line {first}" if first == last else f"lines {first}-{last}"


def _note_units(path, between, cells):
    """Which lines between header and data were read as units, and which skipped (a point
    count, ZPlot's ``End Comments``)."""
    units = ", ".join(str(k) for k, text in between if _unit_line(text))
    other = [(k, text) for k, text in between if not _unit_line(text)]
    if units:
        warnings.warn(f"{path!r}: read the units of line(s) {units} into the header: "
                      f"{', '.join(cells)}", DataWarning, stacklevel=5)
    if other:
        shown = ", ".join(f"{k} ({shown_cell(' '.join(t.split()))})" for k, t in other[:3])
        warnings.warn(f"{path!r}: skipped line(s) {shown} between the header and the data",
                      DataWarning, stacklevel=5)


def read_table(path, payload, columns, freq_unit, max_rows, parameter=None, record=None):
    """Parse delimited UTF-8 text into a :class:`Table` (see ``loaders.load_text``)."""
    rows, ltspice_runs = _one_run(
        path, _tab_led_tables(_content(path, decode_text(path, payload), max_rows)), record)
    rows = _footer(path, _preamble(path, rows, columns))
    sep = _separator(rows[0][1])
    rows = _decimal_commas(rows, sep)
    split = _splitter(sep)
    first = split(rows[0][1])
    header = not all(_is_value(c) for c in first)
    if header and len(rows) > 1:
        first, rows = _units_row(first, rows, split)
    if columns is not None:
        cols = columns
    elif header:
        cols = _header_columns(path, first, parameter, rows[0][0])
    else:
        cols = _default_columns(path, first)
    if parameter is not None and not (header and columns is None):
        with_parameter(cols, parameter, repr(path))     # (raises: no header names one)
    if header:
        rows = rows[1:]
        if not rows:
            raise DataError(f"{path!r} has a header but no data rows")
    cols = _resolve_units(path, cols, freq_unit,
                          ",".join(unquoted(c) for c in first) if header else None)
    fast = _fast_values(rows, cols, sep)
    if fast is not None:
        values = {c.role: fast[:, j] for j, c in enumerate(cols)}
    else:
        values = _slow_values(path, rows, cols, split)
    values = written_values(cols, values)           # "-Im(Z)", "Freq [MHz]"
    values, rows = one_sweep(path, values, rows, None if ltspice_runs else record)
    dc = values["freq"] == 0      # rows at 0 Hz are dropped later (a DataWarning); their
    for role, v in values.items():  # response, often -inf dB or NaN there, is not checked
        if role != "freq" and dc.any():
            v[dc] = 1.0
    table = Table(path, cols, values, np.array([r[0] for r in rows]))
    _check_finite(table)
    if any(c.same for c in cols):
        check_same(table, rows, split, _response(table), _parse_cell)
    if not header and columns is None and [c.label for c in cols] == [
            "frequency", "real", "imag"]:
        check_guessed(path, values)
    return table


def _slow_values(path, rows, cols, split):
    labels = ",".join(c.label for c in cols)
    values = {c.role: [] for c in cols if c.role != "skip"}
    for k, (line, text) in enumerate(rows):
        cells = split(text)
        if len(cells) != len(cols):
            _second_block(path, rows, k)
            raise DataError(f"{path!r} line {line}: expected {len(cols)} columns ({labels}), "
                            f"got {len(cells)}")
        try:
            for col, cell in zip(cols, cells):
                if col.role != "skip":
                    values[col.role].append(_parse_cell(path, line, col, cell))
        except DataError:
            _second_block(path, rows, k)
            raise
    return {k: np.array(v, complex if k == "complex" else float) for k, v in values.items()}


#: A trace's block header, as the HP/Agilent 4294A writes each trace of its ASCII export
#: (``"TRACE: A"`` ... ``"TRACE: B"``).
_TRACE_BLOCK = re.compile(r"^\W*trace\s*:\s*\w+", re.IGNORECASE)


def _second_block(path, rows, k):
    """Refuse, saying so, when the bad row ``rows[k]`` is text that starts a second block of
    data: rows of numbers with as many cells as the first block's follow the text (three
    in a row, or the rest of the file), as in an export of several sweeps or traces, each
    with its own header lines. The text is two or more lines, or one that names columns
    (a repeated header); one stray line amid the data is not a block. Return (the
    caller's error follows) otherwise.

    Raises
    ------
    DataError
        Naming the line the second block starts on, the line its data start on, the
        number of blocks when the block's first line recurs, and the first block's lines.
    """
    if k == 0 or all(_is_value(c) for c in _row_cells(rows[k][1])):
        return
    start = _data_start(rows[k:])
    if start is None or len(_row_cells(rows[k + start][1])) != len(_row_cells(rows[0][1])):
        return
    if start == 1 and None in [recognise(unquoted(c)) for c in _row_cells(rows[k][1])]:
        return
    blocks = 1 + sum(text == rows[k][1] for _, text in rows[k:])
    trace = ("; the analyser writes each trace as its own block: export one trace in a "
             "complex display format, whose Real and Imag columns then hold the response"
             if _TRACE_BLOCK.match(rows[k][1]) else "")
    raise DataError(
        f"{path!r} line {rows[k][0]} starts a second block ("
        f"{f'a header repeated before each of {blocks} blocks: ' if blocks > 2 else ''}"
        f"{shown_cell(rows[k][1].strip())}{f' and {start - 1} more line(s)' if start > 1 else ''}"
        f", then data again from line {rows[k + start][0]}): this reader reads one sweep: "
        f"cut the file to one block (the first is lines {rows[0][0]}-{rows[k - 1][0]}){trace}")


def _check_finite(table):
    for col in table.columns:
        if col.role == "skip":
            continue
        bad = ~np.isfinite(table.values[col.role])
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            what = "omega" if col.role == "freq" else "response"
            raise DataError(
                f"{table.at(i)}, column {col.label!r}: {table.values[col.role][i].item()!r} is not "
                f"finite: {what} must be finite; remove or re-measure that point")


# --------------------------------------------------------------------------- response

def table_response(table):
    """``omega`` (rad/s) and the complex response of a :class:`Table`, with checks that
    name the line: negative or unsorted frequencies, dB overflow, zero responses."""
    f = table.values["freq"]
    neg = f < 0
    if neg.any():
        i = int(np.flatnonzero(neg)[0])
        raise DataError(f"{table.at(i)}, column {table.label('freq')!r}: frequency {float(f[i])!r} "
                        "is negative; give frequencies >= 0 (omega must be > 0)")
    with np.errstate(over="ignore"):
        omega = 2 * np.pi * f if table.unit("freq") == "hz" else f
    if not np.all(np.isfinite(omega)):
        i = int(np.flatnonzero(~np.isfinite(omega))[0])
        raise DataError(f"{table.at(i)}: frequency {float(f[i])!r} Hz overflows in rad/s; check "
                        "the frequency unit")
    pos = np.flatnonzero(omega > 0)
    step = np.diff(omega[pos])
    if np.any(step <= 0) and not np.all(step < 0):       # descending rows: reversed later
        bad = step == 0 if np.all(step <= 0) else step <= 0      # descending + duplicates
        j = int(np.flatnonzero(bad)[0])
        i, p = pos[j + 1], pos[j]
        what = "duplicated" if step[j] == 0 else "unsorted"
        raise DataError(
            f"{table.at(i)}, column {table.label('freq')!r}: the frequencies must be "
            f"strictly increasing ({what} rows): {float(f[i])!r} after {float(f[p])!r} on "
            f"{table.where} {int(table.rows[p])}; sort the file by frequency and drop "
            "duplicates (FrequencyData.sorted does both, and says when duplicates differ)")
    response = _response(table)
    zero = response == 0
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        raise DataError(
            f"{table.at(i)}: response must be nonzero (the relative error divides by it): "
            f"response[{i}]=0 at omega={float(omega[i])!r}; remove that point")
    return omega, response


def _check_radians(table, phase):
    """DataError when a phase column said to be in radians wraps as degrees do: within
    +-180, beyond a turn, and jumping by more than ``WRAP_JUMP`` between two rows."""
    jumps = np.abs(np.diff(phase))
    if phase.size < 3 or np.max(np.abs(phase)) > 180 or np.max(np.abs(phase)) <= 2 * np.pi \
            or not np.any(jumps > WRAP_JUMP):
        return
    j = int(np.argmax(jumps > WRAP_JUMP))
    cols = tuple(replace(c, unit="deg") if c.role == "phase" else c for c in table.columns)
    raise DataError(
        f"{table.path!r}: column {table.label('phase')!r} is read in radians, but its values "
        f"wrap as a phase in degrees does ({float(phase[j]):g} then {float(phase[j + 1]):g} "
        f"on {table.where}s {int(table.rows[j])} and {int(table.rows[j + 1])}, all within "
        f"+-180); if it is in degrees, pass columns='{columns_option(cols)}' (command "
        "line --columns)")


def _response(table):
    v = table.values
    if "complex" in v:
        return v["complex"]
    if "re" in v:
        response = np.empty(v["re"].size, complex)       # keeps signed zeros (not re + 1j*im)
        response.real, response.imag = v["re"], v["im"]
        return response
    mag = v["mag"]
    if table.unit("mag") == "db":
        with np.errstate(over="ignore", under="ignore"):
            mag = 10.0 ** (mag / 20.0)
        bad = ~np.isfinite(mag) | (mag == 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataError(
                f"{table.at(i)}, column {table.label('mag')!r}: {float(v['mag'][i])!r} dB is "
                "outside the range of floating point (|G| = 10^(dB/20) is "
                f"{'infinite' if mag[i] else 'zero'}); check that the column is in dB")
    elif np.any(mag < 0):
        i = int(np.flatnonzero(mag < 0)[0])
        raise DataError(f"{table.at(i)}, column {table.label('mag')!r}: magnitude "
                        f"{float(mag[i])!r} is negative; give |G| >= 0 (a sign belongs in the "
                        "phase)")
    if table.unit("phase") == "rad":
        _check_radians(table, v["phase"])
    phase = v["phase"] if table.unit("phase") == "rad" else np.deg2rad(v["phase"])
    with np.errstate(over="ignore", invalid="ignore"):
        response = mag * np.exp(1j * phase)
    bad = ~np.isfinite(response)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"{table.at(i)}: magnitude {float(mag[i])!r} with phase "
                        f"{float(v['phase'][i])!r} gives a non-finite response; check the columns")
    return response
