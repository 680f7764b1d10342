"""Trace-block exports of HP/Agilent impedance and network analysers (layer L1).

The HP/Agilent 4294A's ASCII save (and the 4395A's and 4396B's) writes a measurement as one
block per trace, after a preamble of key lines (``"MEASURE PARAMETER: IMPEDANCE MAG PHASE
(DEG)"``): a ``"TRACE: A"`` line, key lines (``"FORMAT: LOG"``), the header
``"Frequency"  "Data Trace Real"  "Data Trace Imag"`` and the rows, tab-separated. A trace
of a complex quantity fills both columns; a trace of a scalar one (|Z|, θ, R, X, a
magnitude in dB, a phase) fills Real and writes 0 in Imag, so that a response takes two
traces: trace A holds the first quantity the measure parameter names, trace B the second.
:func:`read_traces` reads such a file into the
:class:`~freqid_casadi.io._table.Table` of one response (used by
:func:`freqid_casadi.io.loaders.load_text`).
"""

import re
import warnings
from dataclasses import dataclass

import numpy as np

from ._columns import Column, recognise, unquoted
from ._readfile import DataWarning
from ._decode import decode_text
from ._table import NUMBER, Table, _lines, _row_cells, shown_cell
from ..errors import DataError, OptionError

__all__ = ["read_traces", "is_trace_export"]

#: The column header of a trace block, looked for in the raw bytes first.
_HEAD = re.compile(rb"data[ \t]*trace[ \t]*real", re.IGNORECASE)
_KEY = re.compile(r"^([A-Za-z][A-Za-z0-9 ._/-]*?)\s*:\s*(.*?)\s*$")
#: Keys of the line that starts a block and names it (``"TRACE: A"``, ``"CHANNEL: 1"``).
_MARKS = ("trace", "channel", "chan")
#: A trace's display format (the key line ``FORMAT``) that says what it holds; a format
#: that gives only the scale of the axis (the 4294A's ``LOG``, ``LINEAR``) says nothing.
_FORMATS = {"log mag": ("mag", "db"), "logmag": ("mag", "db"), "lin mag": ("mag", "lin"),
            "linmag": ("mag", "lin"), "phase": ("phase", "deg"),
            "expanded phase": ("phase", "deg"), "unwrapped phase": ("phase", "deg"),
            "real": ("re", None), "imag": ("im", None), "imaginary": ("im", None)}
#: The words of a measure parameter (``IMPEDANCE MAG PHASE (DEG)``, ``|Z|-θ``, ``R-X``,
#: ``G-B``): the quantity of each trace in order; the others name the response or a unit.
_QUANTITIES = {"mag": ("mag", "lin"), "magnitude": ("mag", "lin"), "abs": ("mag", "lin"),
               "|z|": ("mag", "lin"), "|y|": ("mag", "lin"), "phase": ("phase", None),
               "θ": ("phase", None), "theta": ("phase", None), "real": ("re", None),
               "r": ("re", None), "resistance": ("re", None), "g": ("re", None),
               "conductance": ("re", None), "imag": ("im", None),
               "imaginary": ("im", None), "x": ("im", None), "reactance": ("im", None),
               "b": ("im", None), "susceptance": ("im", None)}
_NAMING = {"impedance", "admittance", "z", "y", "deg", "degree", "degrees", "rad", "radian",
           "radians"}
_SAYS = {("mag", "lin"): "magnitude", ("mag", "db"): "magnitude in dB",
         ("phase", "deg"): "phase in degrees", ("phase", "rad"): "phase in radians",
         ("re", None): "real part", ("im", None): "imaginary part"}
_PAIRS = ({"mag", "phase"}, {"re", "im"})


@dataclass
class _Block:
    """One trace: its name (``trace A``), the key lines before its header
    (``[(line, key, value)]``), the file line of each row, the columns, the label of the
    first and the header's line."""

    name: str
    meta: list
    lines: np.ndarray
    freq: np.ndarray
    real: np.ndarray
    imag: np.ndarray
    freq_label: str
    header: int

    @property
    def span(self):
        return _lines(int(self.lines[0]), int(self.lines[-1]))

    def key(self, *names):
        """The value of the last key line named one of ``names`` (lower case), or None."""
        return next((v for _, k, v in reversed(self.meta) if k in names), None)


def is_trace_export(payload):
    """Whether a file's bytes hold a trace block's header (``Data Trace Real``).

    Parameters
    ----------
    payload : bytes

    Returns
    -------
    bool
    """
    return _HEAD.search(payload) is not None


def read_traces(path, payload, columns, freq_unit, parameter=None, record=None):
    """The response of a trace-block export (see the module's docstring), or None when the
    file holds no trace block.

    Parameters
    ----------
    path : str
        The file, for messages.
    payload : bytes
        Its content.
    columns : tuple of Column or None
        The user's ``columns=``: the frequency and the quantity of each trace in order
        (``freq_hz,mag,phase_deg``: trace A the magnitude, trace B the phase), needed when
        the file's key lines do not say; of a file of one complex trace, its three columns.
    freq_unit : {"hz", "rad/s"} or None
        The unit of the frequency column (default Hz, the analysers' unit).
    parameter, record : optional
        Refused (they choose an S-parameter and an LTspice run or UFF record).

    Returns
    -------
    Table or None
        Frequencies and the two traces as the response's parts (the file lines of trace
        A), or the one complex trace's Real and Imag columns.

    Raises
    ------
    DataError
        A bad cell, traces of different frequencies, key lines that do not say what the
        traces are (nor ``columns=``), a trace that cannot be what they say (a phase beyond
        a turn, a negative magnitude), one scalar trace only, or several complex ones.
    OptionError
        ``parameter`` or ``record`` given; ``columns`` not of the trace layout.
    """
    if not is_trace_export(payload):
        return None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        blocks = _blocks(path, decode_text(path, payload))
    if not blocks or len(blocks) == 1 and columns is not None:
        return None          # (the table reader reads the columns named, or says what is wrong)
    for w in caught:                        # the decoder's note, once
        warnings.warn(w.message, w.category, stacklevel=3)
    if parameter is not None or record is not None:
        what = "parameter=" if parameter is not None else "record="
        raise OptionError(f"{path!r} is an analyser's export of trace blocks "
                          f"({', '.join(b.name for b in blocks)}): {what} does not apply; "
                          "drop it")
    for b in blocks:
        _check_sweep(path, b)
        _check_finite(path, b)
    unit = _freq_unit(columns, freq_unit, blocks[0].freq_label)
    complex_ = [b for b in blocks if np.any(b.imag != 0)]
    if len(blocks) == 1 and complex_:
        b = blocks[0]
        return Table(path, (Column("freq", unit, b.freq_label),
                            Column("re", None, f"{b.name}: Data Trace Real"),
                            Column("im", None, f"{b.name}: Data Trace Imag")),
                     {"freq": b.freq, "re": b.real, "im": b.imag}, b.lines)
    if complex_ or len(blocks) != 2:
        raise DataError(_not_two(path, blocks, complex_))
    a, b = blocks
    _same_sweep(path, a, b)
    roles, source = _roles(path, a, b, columns)
    for block, role in zip((a, b), roles):
        _check_role(path, block, role, source)
    warnings.warn(f"{path!r}: read {a.name} ({a.span}) as the {_SAYS[roles[0]]} and {b.name} "
                  f"({b.span}) as the {_SAYS[roles[1]]}, as {source} says", DataWarning,
                  stacklevel=3)
    return Table(path, (Column("freq", unit, a.freq_label),
                        Column(roles[0][0], roles[0][1], f"{a.name}: Data Trace Real"),
                        Column(roles[1][0], roles[1][1], f"{b.name}: Data Trace Real")),
                 {"freq": a.freq, roles[0][0]: a.real, roles[1][0]: b.real}, a.lines)


def _freq_unit(columns, freq_unit, label):
    """The unit of the frequency column: ``columns``' (``freq_hz``), else its header's
    (``Frequency (Hz)``), else ``freq_unit``, else Hz (the analysers write Hz)."""
    given = columns[0].unit if columns and columns[0].role == "freq" else None
    col = recognise(label)
    if given is None and col is not None and col.scale != 1.0:
        raise DataError(f"the trace's frequency column {label!r} is not in Hz: the trace "
                        "reader reads Hz and rad/s; export the traces in Hz")
    return given or col.unit or freq_unit or "hz"


def _check_sweep(path, block):
    """Refuse a block whose first column is not a frequency (a sweep of the DC bias or of
    the oscillator's level)."""
    col = recognise(block.freq_label)
    if col is None or col.role != "freq":
        raise DataError(f"{path!r} line {block.header}: the first column of {block.name} is "
                        f"{block.freq_label!r}, not a frequency: the analyser swept another "
                        "quantity; save a frequency sweep")


# --------------------------------------------------------------------------- parsing

def _blocks(path, text):
    """Every trace block of ``text``, with the key lines before each."""
    lines = text.split("\n")
    blocks, meta, k = [], [], 0
    while k < len(lines):
        raw = lines[k].strip()
        cells = [unquoted(c) for c in _row_cells(raw)] if raw else []
        low = [c.lower() for c in cells]
        if "data trace real" in low and "data trace imag" in low:
            block, k = _block(path, lines, k, cells, meta, len(blocks))
            blocks.append(block)
            meta = []
            continue
        m = _KEY.match(unquoted(raw)) if raw else None
        if m:
            meta.append((k + 1, m.group(1).strip().lower(), m.group(2).strip()))
        k += 1
    return blocks


def _block(path, lines, h, cells, meta, index):
    """The block whose header is line ``h`` (0-based) and the index of the line after its
    rows: the lines that follow with as many cells as the header, a number first (blank
    lines before them skipped; a blank or other line ends them)."""
    low = [c.lower() for c in cells]
    cols = (0, low.index("data trace real"), low.index("data trace imag"))
    mark = next(((k, v) for _, k, v in reversed(meta) if k in _MARKS), None)
    name = f"{mark[0]} {mark[1]}" if mark else f"block {index + 1}"
    rows, k = [], h + 1
    while k < len(lines):
        raw = lines[k].strip()
        row = _row_cells(raw) if raw else []
        if len(row) != len(cells) or not NUMBER.fullmatch(unquoted(row[0])):
            if raw or rows:
                break
            k += 1
            continue
        rows.append((k + 1, [_number(path, k + 1, cells[j], row[j]) for j in cols]))
        k += 1
    if not rows:
        raise DataError(f"{path!r} line {h + 1}: the header of {name} "
                        f"({', '.join(cells)}) has no data rows under it")
    values = np.array([v for _, v in rows], float)
    return _Block(name, meta, np.array([n for n, _ in rows]), values[:, 0], values[:, 1],
                  values[:, 2], cells[0], h + 1), k


def _number(path, line, label, cell):
    cell = unquoted(cell)
    if not NUMBER.fullmatch(cell):
        raise DataError(f"{path!r} line {line}, column {label!r}: {shown_cell(cell)} is not "
                        "a number")
    return float(cell)


def _check_finite(path, block):
    for label, x in (("Frequency", block.freq), ("Data Trace Real", block.real),
                     ("Data Trace Imag", block.imag)):
        bad = ~np.isfinite(x)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataError(f"{path!r} line {int(block.lines[i])}, column {label!r} of "
                            f"{block.name}: {float(x[i])!r} is not finite; remove or "
                            "re-measure that point")


def _same_sweep(path, a, b):
    """Refuse traces of different frequencies, naming the first point that differs."""
    if a.freq.size != b.freq.size:
        raise DataError(f"{path!r}: {a.name} has {a.freq.size} points ({a.span}), {b.name} "
                        f"{b.freq.size} ({b.span}): the two traces must be of one sweep; save "
                        "both traces of one measurement")
    off = ~np.isclose(a.freq, b.freq, rtol=1e-9, atol=0.0)
    if off.any():
        i = int(np.flatnonzero(off)[0])
        raise DataError(f"{path!r}: the traces' frequencies differ: {a.freq[i]:.12g} on line "
                        f"{int(a.lines[i])} ({a.name}), {b.freq[i]:.12g} on line "
                        f"{int(b.lines[i])} ({b.name}); the two traces must be of one sweep: "
                        "save both traces of one measurement")


# --------------------------------------------------------------------------- what each holds

def _roles(path, a, b, columns):
    """``((role, unit) of trace A, of trace B)`` and the source that says so: the blocks'
    FORMAT lines, else the measure parameter, else ``columns``; a ``columns`` that
    contradicts the file is refused."""
    told = _told(a, b)
    user = _user_roles(path, a, b, columns) if columns is not None else None
    if told is None and user is None:
        shown = "; ".join(f"{b_.name}: FORMAT {b_.key('format')!r}" for b_ in (a, b))
        measured = a.key("measure parameter", "parameter", "measurement")
        raise DataError(
            f"{path!r} holds two traces of scalar quantities ({a.name}, {a.span}; {b.name}, "
            f"{b.span}), and its key lines ({shown}; measure parameter {measured!r}) do not "
            "say which is which: pass columns= (command line --columns) naming the "
            "frequency and each trace in order, e.g. columns='freq_hz,mag,phase_deg' "
            "(trace A the magnitude, trace B the phase in degrees) or 'freq_hz,re,im'; a "
            "derived quantity (Ls, Cp, Q, D) is not the response: measure |Z|-θ or R-X")
    if told is None:
        if any(r == "phase" and u is None for r, u in user):
            raise DataError(f"{path!r}: columns= does not give the phase's unit, nor does the "
                            "file; name it phase_deg or phase_rad")
        return user, "columns="
    if user is not None and any(u[0] != t[0] or u[1] not in (None, t[1])
                                for u, t in zip(user, told[0])):
        raise DataError(f"{path!r}: columns= reads {a.name} as the {_SAYS.get(user[0], '?')} "
                        f"and {b.name} as the {_SAYS.get(user[1], '?')}, but {told[1]} says "
                        f"they are the {_SAYS[told[0][0]]} and the {_SAYS[told[0][1]]}: drop "
                        "columns= (the file says what its traces are)")
    return told


def _told(a, b):
    """``(roles, source)`` from the blocks' key lines, or None when they do not say."""
    formats = [_format_role(x.key("format")) for x in (a, b)]
    if None not in formats and {r for r, _ in formats} in _PAIRS:
        shown = ", ".join(repr(x.key("format")) for x in (a, b))
        return tuple(formats), f"their FORMAT lines ({shown})"
    for key in ("measure parameter", "parameter", "measurement"):
        value = b.key(key) or a.key(key)
        pair = _parameter_roles(value) if value else None
        if pair:
            return pair, f"its line '{key.upper()}: {value}'"
    return None


def _format_role(value):
    """``(role, unit)`` a trace's FORMAT value names, or None (a scale, or unknown)."""
    if not value:
        return None
    words = re.findall(r"[a-z]+", value.lower())
    unit = "rad" if {"rad", "radian", "radians"} & set(words) else "deg"
    words = [w for w in words if w not in _NAMING]
    role = _FORMATS.get(" ".join(words))          # (a scale, LOG or LINEAR: None)
    return ("phase", unit) if role and role[0] == "phase" else role


def _parameter_roles(value):
    """The quantities of trace A and B a measure parameter names (``IMPEDANCE MAG PHASE
    (DEG)``: magnitude, phase in degrees), or None when a word is not one of them."""
    words = re.findall(r"\|[^|]{1,3}\||[a-zθ]+", value.lower())
    unit = "rad" if {"rad", "radian", "radians"} & set(words) else "deg"
    roles = []
    for w in words:
        if w in _QUANTITIES:
            role = _QUANTITIES[w]
            roles.append(("phase", unit) if role[0] == "phase" else role)
        elif w not in _NAMING:
            return None
    return tuple(roles) if len(roles) == 2 and {r for r, _ in roles} in _PAIRS else None


def _user_roles(path, a, b, columns):
    """The roles of trace A and B as ``columns`` names them (frequency first)."""
    roles = [(c.role, c.unit) for c in columns]
    if len(roles) != 3 or roles[0][0] != "freq" or {r for r, _ in roles[1:]} not in _PAIRS:
        raise OptionError(f"columns=: {path!r} holds two traces ({a.name}, {b.name}): name the "
                          "frequency and each trace in order, e.g. columns='freq_hz,mag,"
                          "phase_deg' (trace A the magnitude, trace B the phase in degrees) "
                          "or 'freq_hz,re,im'")
    return tuple(roles[1:])


def _check_role(path, block, role, source):
    """Refuse a trace that cannot be what ``source`` says: a magnitude below 0, a phase
    beyond a turn (an unwrapped phase's format excepted)."""
    x = block.real
    if role == ("mag", "lin") and np.any(x < 0):
        i = int(np.flatnonzero(x < 0)[0])
        raise DataError(f"{path!r} line {int(block.lines[i])}: {block.name} holds {x[i]:g}, "
                        f"not a magnitude (below 0), as {source} says; name the traces with "
                        "columns=")
    unwrapped = re.search(r"expanded|unwrapped", block.key("format") or "", re.IGNORECASE)
    if role[0] == "phase" and not unwrapped:
        turn = 360.0 if role[1] == "deg" else 2 * np.pi
        big = np.abs(x) > turn * (1 + 1e-9)
        if big.any():
            i = int(np.flatnonzero(big)[0])
            raise DataError(f"{path!r} line {int(block.lines[i])}: {block.name} holds "
                            f"{x[i]:g}, more than a turn for a phase in {role[1]}, as "
                            f"{source} says; name the traces with columns=")


def _not_two(path, blocks, complex_):
    """The message for trace blocks that do not make one response."""
    shown = ", ".join(f"{b.name} ({b.span}, FORMAT {b.key('format')!r})" for b in blocks)
    if len(blocks) == 1:
        return (f"{path!r} holds one trace, of a scalar quantity ({shown}: its Imag column is "
                "0): a response needs two (magnitude and phase, or real and imaginary part); "
                "save both traces of the measurement in one file (the analyser writes each "
                "as a block), or one trace in a complex format (its Real and Imag columns "
                "then hold the response)")
    if complex_:
        return (f"{path!r} holds {len(blocks)} traces ({shown}), of which "
                f"{', '.join(b.name for b in complex_)} complex: this reader reads one "
                "complex trace, or two scalar ones: save the trace to read alone")
    return (f"{path!r} holds {len(blocks)} traces ({shown}): this reader reads two, the "
            "magnitude and phase (or real and imaginary part) of one response; save those "
            "two alone")
