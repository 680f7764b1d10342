"""Touchstone network-parameter files of any number of ports, v1.x and v2.x (layer L1).

Version 1 (``.s1p``, ``.s2p``, ..., ``.sNp``; the port count from the extension): an option
line ``# <Hz|kHz|MHz|GHz> <S|Y|Z|H|G> <DB|MA|RI> R <ohms>`` (defaults GHz, S, MA, 50 ohm;
``R`` without a value is 50 ohm; version 1.1: one ``R`` value per port), ``!`` comments,
then per frequency ``f`` and ``N^2`` pairs: for 2 ports ``11 21 12 22`` on one line; for 3
and more the matrix row by row (``11 12 ... 1N``, ``21 ...``), each row on its own line(s),
wrapped after 4 pairs. Every record starts on a new line and is read line by line: a record
short of its numbers, or a line running past its end, is an error naming the line. A 2-port
file may end with noise parameters (a block whose frequencies start again lower), which are
not read. Version 1 Z, Y, H and G values are normalised to ``R``; they are returned in ohms
and siemens: ``Z_ij`` times ``sqrt(R_i R_j)`` (``R`` for one value), ``Y_ij`` divided by it,
``h11`` times ``R_1`` and ``h22`` divided by ``R_2``, ``g11`` divided by ``R_1`` and ``g22``
times ``R_2``; h12, h21, g12, g21 (ratios) and S as stored.

Version 2 (``[Version] 2.0``; any extension, e.g. ``.ts``): keywords ``[Number of Ports]``,
``[Two-Port Data Order] 12_21|21_12``, ``[Number of Frequencies]``, ``[Matrix Format]
Full|Lower|Upper`` (a triangle stored row by row, the other half by symmetry),
``[Reference]``, ``[Network Data]``, ``[Noise Data]``, ``[End]``; information blocks
(``[Begin Information]`` ... ``[End Information]``) are skipped. The numbers after
``[Network Data]`` are read as one stream, ``1 + 2 M`` per frequency; numeric rows after the
keywords without a ``[Network Data]`` line are read as the network data with a DataWarning
(unless a ``[Reference]`` keyword could own them: then a DataError). Values are stored
un-normalised (ohms, siemens) and read as stored.

Re-exported by :mod:`freqid_casadi.io.loaders`.
"""

import re
import warnings

import numpy as np

from ._decode import decode_text
from ._table import NUMBER, shown_cell
from ..errors import DataError, OptionError

__all__ = ["load_touchstone", "is_touchstone"]

_UNITS = {"hz": 1.0, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}
_SHOWN = {"hz": "Hz", "khz": "kHz", "mhz": "MHz", "ghz": "GHz"}
_EXT = re.compile(r"\.s(\d{1,3})p$", re.IGNORECASE)
_PARAM = re.compile(r"^([syzhg])_?(\d{1,3})(?:[,_ ](\d{1,3}))?$", re.IGNORECASE)
_OPTION_WORDS = {*_UNITS, "db", "ma", "ri", "s", "y", "z", "h", "g", "r"}
#: What the one value of a 1-port file is, by kind.
_ONE_PORT = {"s": "a reflection", "z": "an input impedance", "y": "an input admittance"}
#: Most ports read (a file claiming more is damaged or not a Touchstone file).
MAX_PORTS = 200


def is_touchstone(path):
    """True if the file name ends in ``.sNp`` (N ports) or ``.ts`` (Touchstone 2).

    Parameters
    ----------
    path : str
    """
    lower = str(path).lower()
    return bool(_EXT.search(lower)) or lower.endswith(".ts")


def _options(path, line_no, text):
    """Unit, format, kind and reference resistances (the tokens after ``R``) of the option
    line.

    ``R`` takes one value or, Touchstone 1.1, one number per port; ``R`` without a value,
    or no ``R``, is the default 50 ohm. One value that is not a number (e.g. scikit-rf's
    ``(50+50j)``) is kept as written: S-parameters do not use it, :func:`_denormalise`
    refuses it. The count is checked against the ports by the caller.
    """
    unit, fmt, kind, rs = "ghz", "ma", "s", ["50"]
    tokens = text[1:].lower().split()
    k = 0
    while k < len(tokens):
        tok = tokens[k]
        if tok in _UNITS:
            unit = tok
        elif tok in ("db", "ma", "ri"):
            fmt = tok
        elif tok in ("s", "y", "z", "h", "g"):
            kind = tok
        elif tok == "r":
            values = []
            while k + 1 < len(tokens) and NUMBER.fullmatch(tokens[k + 1]):
                k += 1
                values.append(tokens[k])
            if not values and k + 1 < len(tokens) and tokens[k + 1] not in _OPTION_WORDS:
                k += 1
                values.append(tokens[k])
            rs = values or ["50"]
        else:
            raise DataError(f"{path!r} line {line_no}: unknown option {tok!r} in the Touchstone "
                            "option line; expected e.g. '# GHz S MA R 50'")
        k += 1
    return unit, fmt, kind, rs


def _denormalise(path, line_no, kind, i, j, rs):
    """Factor that turns a version-1 value (normalised to the reference resistance) into
    ohms (Z, h11, g22), siemens (Y, h22, g11) or the stored ratio (S, h12, h21, g12, g21).

    ``rs`` are the option line's resistances in ohms (one, or one per port; the tokens as
    written), ``line_no`` its line: ``Z_ij`` is multiplied by ``sqrt(R_i R_j)``, ``Y_ij``
    divided by it; ``h11`` times ``R_1``, ``h22`` divided by ``R_2``; ``g11`` divided by
    ``R_1``, ``g22`` times ``R_2``.
    """
    for tok in rs:
        if not (NUMBER.fullmatch(tok) and np.isfinite(float(tok)) and float(tok) > 0):
            raise DataError(f"{path!r} line {line_no}: reference resistance R {tok} is not a "
                            f"positive number of ohms, and the {kind.upper()}-parameters of a "
                            "version 1 file are normalised to it; write e.g. 'R 50'")
    r_i, r_j = (float(rs[0]),) * 2 if len(rs) == 1 else (float(rs[i]), float(rs[j]))
    if kind == "z":
        return float(np.sqrt(r_i * r_j))
    if kind == "y":
        return 1.0 / float(np.sqrt(r_i * r_j))
    if kind in ("h", "g") and i == j:
        return r_i if (kind == "h") == (i == 0) else 1.0 / r_i
    if kind in ("h", "g") and r_i != r_j:
        raise DataError(f"{path!r}: {kind.upper()}{i + 1}{j + 1} of a version 1 file with "
                        f"reference resistances {r_i:g} and {r_j:g} ohm per port is not read "
                        "(its normalisation is not defined); use one R for both ports or "
                        "export S-parameters")
    return 1.0


def _pairs(fmt, a, b):
    """Complex values of the number pairs ``a``, ``b`` (arrays) in format ``fmt``."""
    if fmt == "ri":
        return a + 1j * b
    with np.errstate(all="ignore"):
        mag = 10.0 ** (a / 20.0) if fmt == "db" else a
        return mag * np.exp(1j * np.deg2rad(b))


def _scan(path, text):
    """Option line, keywords and the numeric lines of a Touchstone text.

    Returns ``(opts, keywords, lines, loose)``: ``opts`` the option line's tokens (or None)
    with its line number, ``keywords`` a dict of lower-case keyword -> (value, line),
    ``lines`` the ``(line number, numbers)`` of the network data (noise data and information
    blocks left out), ``loose`` those of numeric lines among the version-2 keywords (outside
    ``[Network Data]``: the arguments of a keyword continued on later lines, or network
    data whose ``[Network Data]`` line is missing).
    """
    opts, keywords, lines, loose, section = None, {}, [], [], "network"
    for k, raw in enumerate(text.split("\n")):
        line = raw.split("!", 1)[0].strip()
        if not line:
            continue
        if line.startswith("#"):
            opts = opts or (k + 1, line)
            continue
        if line.startswith("["):
            key, _, value = line[1:].partition("]")
            key = " ".join(key.lower().split())
            keywords.setdefault(key, (value.strip(), k + 1))
            section = {"version": "keywords", "network data": "network",
                       "begin information": "info", "end information": "keywords",
                       "noise data": "noise", "end": "end"}.get(key, section)
            continue
        if section not in ("network", "keywords"):
            continue
        cells = line.split()
        if section == "keywords":                    # text among the keywords: not read
            if all(NUMBER.fullmatch(c) for c in cells):
                loose.append((k + 1, [float(c) for c in cells]))
            continue
        for c in cells:
            if not NUMBER.fullmatch(c):
                raise DataError(f"{path!r} line {k + 1}: {shown_cell(c)} is not a number")
        lines.append((k + 1, [float(c) for c in cells]))
    return opts, keywords, lines, loose


def _unmarked(path, keywords, lines, loose):
    """The network lines of a version-2 file: ``lines``, or the numeric lines after the
    keywords (``loose``) when the ``[Network Data]`` line is missing; read with a
    DataWarning when no keyword could own them (no ``[Reference]``, whose values may
    continue on later lines), else a DataError saying what is missing."""
    from ._readfile import DataWarning

    if lines or not loose or "network data" in keywords:
        return lines
    where = f"lines {loose[0][0]}-{loose[-1][0]}" if len(loose) > 1 else f"line {loose[0][0]}"
    if "reference" in keywords:
        raise DataError(f"{path!r}: {len(loose)} numeric rows after the keywords ({where}) but "
                        "no [Network Data] keyword; write [Network Data] on its own line "
                        "before the first row of network data")
    warnings.warn(f"{path!r}: {len(loose)} numeric rows after the keywords ({where}) but no "
                  "[Network Data] keyword: read them as the network data", DataWarning,
                  stacklevel=4)
    return loose


def _ports(path, keywords):
    """Number of ports: ``[Number of Ports]`` (v2) or the ``.sNp`` extension (v1)."""
    if "number of ports" in keywords:
        value, line = keywords["number of ports"]
        if not value.isdigit() or not 1 <= int(value) <= MAX_PORTS:
            raise DataError(f"{path!r} line {line}: [Number of Ports] {value!r} is not a "
                            f"number of ports 1..{MAX_PORTS}")
        return int(value)
    m = _EXT.search(path)
    if m is None or not 1 <= int(m.group(1)) <= MAX_PORTS:
        raise DataError(f"{path!r}: the number of ports is unknown; name a Touchstone 1 "
                        "file .sNp (N ports, e.g. .s4p) or give [Number of Ports] (version 2)")
    return int(m.group(1))


def _order(ports, fmt_matrix, two_port):
    """(i, j) of the stored values of one frequency, in file order (0-based)."""
    if ports == 2 and fmt_matrix == "full":
        return [(0, 0), (0, 1), (1, 0), (1, 1)] if two_port == "12_21" else \
            [(0, 0), (1, 0), (0, 1), (1, 1)]
    if fmt_matrix == "lower":
        return [(i, j) for i in range(ports) for j in range(i + 1)]
    if fmt_matrix == "upper":
        return [(i, j) for i in range(ports) for j in range(i, ports)]
    return [(i, j) for i in range(ports) for j in range(ports)]


def _v1_noise_cut(lines, ports):
    """Network lines of a 2-port v1 file without its noise block (lines of 5 numbers whose
    frequency is not above the last network frequency)."""
    if ports != 2:
        return lines
    for n, (_, nums) in enumerate(lines):
        if n and len(nums) == 5 and nums[0] <= lines[n - 1][1][0]:
            return lines[:n]
    return lines


def _walk(path, lines, per, ports):
    """Frequency records of ``per`` numbers, each starting on a new line (a record's first
    line holds the frequency and pairs: an odd count; its further lines pairs only).

    Returns the records' ``(first line, numbers)``. Raises a DataError naming the line
    where a record ends short of ``per`` (the next line starts a record, or the file
    ends) or runs past it, with the counts.
    """
    pairs = (per - 1) // 2
    need = (f"a {ports}-port record needs {per} (1 frequency + {pairs} "
            f"pair{'s' if pairs > 1 else ''})")
    records, start, nums, last = [], None, [], (None, 0)
    for ln, row in lines:
        if start is not None and len(row) % 2:               # a new record starts here
            _short(path, start, nums, last, need, ln)
        if start is None:
            start, nums = ln, []
        nums = nums + row
        if len(nums) > per:
            span = f"line {start}" if last[0] == start else f"lines {start}-{last[0]}"
            before = f" after {len(nums) - len(row)} on {span}" if ln != start else ""
            raise DataError(f"{path!r} line {ln}: {len(row)} numbers{before} run past the "
                            f"record's end: {need}; a line holds too many numbers or a "
                            "record's lines are merged: fix the line")
        last = (ln, len(row))
        if len(nums) == per:
            records.append((start, nums))
            start = None
    if start is not None:
        _short(path, start, nums, last, need, None)
    return records


def _short(path, start, nums, last, need, after):
    """The DataError of a record that ends short (``last``: its last line and count)."""
    then = f"line {after} starts the next record" if after else "the file ends"
    last, count = last
    if start == last:
        raise DataError(f"{path!r} line {start}: {len(nums)} numbers, but {need}, and {then}; "
                        "a number is missing or the line is cut: fix or remove the line")
    raise DataError(f"{path!r} line {last}: the record that starts on line {start} ends here "
                    f"with {len(nums)} numbers (line {last} holds {count}), but {need}, and "
                    f"{then}; a number is missing: fix or remove that record")


def _records(path, lines, per, ports, version):
    """The frequency records as an array of ``per`` numbers a row and the first line of
    each record, for messages: version 1 walked record by record (:func:`_walk`),
    version 2 read as one stream (a count that is not whole records is located by the
    walk when it can be)."""
    if version.startswith("1"):
        records = _walk(path, lines, per, ports)
        return (np.array([r for _, r in records], float).reshape(-1, per),
                [k for k, _ in records])
    stream = np.array([v for _, nums in lines for v in nums], float)
    starts = np.cumsum([0] + [len(nums) for _, nums in lines])
    if stream.size % per:
        _walk(path, lines, per, ports)
        k = stream.size // per * per
        line = lines[int(np.searchsorted(starts, k, side="right")) - 1][0]
        raise DataError(f"{path!r}: the network data hold {stream.size} numbers, not a "
                        f"multiple of {per} (1 frequency + {(per - 1) // 2} pairs); the "
                        f"record that starts on line {line} is incomplete")
    first = np.searchsorted(starts, np.arange(0, stream.size, per), side="right") - 1
    return stream.reshape(-1, per), [lines[i][0] for i in first]


def _which(parameter, kind, ports):
    """0-based (i, j) of ``parameter`` (``"S21"``, ``"s2,1"``, ``"S10_11"``)."""
    default = parameter is None
    text = f"{kind}11" if default else str(parameter).strip()
    m = _PARAM.match(text)
    if m and m.group(3) is None and len(m.group(2)) == 2:
        i, j = int(m.group(2)[0]), int(m.group(2)[1])
    elif m and m.group(3) is not None:
        i, j = int(m.group(2)), int(m.group(3))
    else:
        i = j = 0
    letter = text[:1].lower()
    if not m or letter != kind or not (1 <= i <= ports and 1 <= j <= ports):
        shown = (f"{kind.upper()}11 ... {kind.upper()}{ports}{ports}" if ports < 10 else
                 f"{kind.upper()}1,1 ... {kind.upper()}{ports},{ports}")
        if ports == 1:
            raise OptionError(f"parameter={parameter!r} is not in this 1-port "
                              f"{kind.upper()}-parameter file: it holds {kind.upper()}11 "
                              f"only ({_ONE_PORT.get(kind, 'its only value')}); leave "
                              "parameter out to read it")
        raise OptionError(f"parameter={parameter!r} is not in this {ports}-port "
                          f"{kind.upper()}-parameter file; choose one of {shown} (row = "
                          f"receiving port, column = driving port: {kind.upper()}21 is from "
                          "port 1 to 2)")
    return i - 1, j - 1


def load_touchstone(path, name=None, *, parameter=None, band=None):
    """Read one network parameter of a Touchstone file (v1 ``.sNp`` or v2, any ports).

    Parameters
    ----------
    path : str or path-like
    name : str, optional
    parameter : str, optional
        Which parameter, e.g. ``"S21"`` (row 2, column 1: the transfer from port 1 to port
        2), ``"S2,1"`` or ``"S10,11"`` for ten and more ports; the letter must be the
        file's. Default: ``"11"`` of the file's kind (a file of 2 or more ports then warns,
        DataWarning).
    band : (float, float), optional
        Keep only the frequencies ``lo <= f <= hi`` in the option line's unit (GHz by
        default).

    Returns
    -------
    FrequencyData
        ``omega = 2 pi f`` (rad/s) with ``f`` in the option line's unit; the response as a
        ratio (S, h12, h21, g12, g21), in ohms (Z, h11, g22) or siemens (Y, h22, g11):
        version 1 values are multiplied or divided by the option line's ``R`` (module
        docstring).

    Raises
    ------
    DataError
        An unknown number of ports, a bad option line or keyword (a count of ``R`` values
        that is neither 1 nor the number of ports), data that are not whole records (1 + 2
        M numbers per frequency; the line named), a cell that is not an ASCII number,
        values outside the floating-point range, rows out of frequency order or repeated.
    OptionError
        An unknown ``parameter``.
    """
    from ._readfile import DataWarning, _finish, parse_band, read_regular_file

    band = parse_band(band)
    path, payload = read_regular_file(path)
    opts, keywords, lines, loose = _scan(path, decode_text(path, payload))
    version = keywords.get("version", ("1", 0))[0]
    ports = _ports(path, keywords)
    unit, fmt, kind, rs = _options(path, *(opts or (0, "#")))
    if len(rs) not in (1, ports):
        raise DataError(f"{path!r} line {opts[0]}: the option line gives {len(rs)} reference "
                        f"resistances for a {ports}-port file; give one (e.g. 'R 50') or one "
                        f"per port ({ports})")
    matrix = keywords.get("matrix format", ("full", 0))[0].lower()
    two_port = keywords.get("two-port data order", ("21_12", 0))[0].replace(" ", "").lower()
    if matrix not in ("full", "lower", "upper") or two_port not in ("12_21", "21_12"):
        raise DataError(f"{path!r}: [Matrix Format] {matrix!r} / [Two-Port Data Order] "
                        f"{two_port!r} is not Full/Lower/Upper / 12_21/21_12")
    if not version.startswith("1"):
        lines = _unmarked(path, keywords, lines, loose)
    if not lines:
        raise DataError(f"{path!r} holds no data rows")
    if "mixed-mode order" in keywords:
        raise DataError(f"{path!r} line {keywords['mixed-mode order'][1]}: mixed-mode "
                        "parameters ([Mixed-Mode Order]) are not read; export single-ended "
                        "S-parameters")
    i, j = _which(parameter, kind, ports)
    order = _order(ports, matrix, two_port)
    if version.startswith("1"):
        lines = _v1_noise_cut(lines, ports)
    values, first = _records(path, lines, 1 + 2 * len(order), ports, version)
    count, line = keywords.get("number of frequencies", (None, 0))
    if count is not None and count != str(len(values)):
        raise DataError(f"{path!r} line {line}: [Number of Frequencies] {count} but the "
                        f"network data hold {len(values)} frequencies; fix the count")
    want = (i, j) if (i, j) in order else (j, i)          # a triangle: by symmetry
    col = 1 + 2 * order.index(want)
    with np.errstate(over="ignore"):
        omega = 2 * np.pi * _UNITS[unit] * values[:, 0]
    response = _pairs(fmt, values[:, col], values[:, col + 1])
    if version.startswith("1") and kind != "s":
        response = response * _denormalise(path, opts[0] if opts else 0, kind, i, j, rs)
    bad = ~np.isfinite(omega) | ~np.isfinite(response)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{path!r} line {first[k]}: the frequency or "
                        f"{kind.upper()}{i + 1}{j + 1} is outside the floating-point range; "
                        "check the option line's units")
    if ports >= 2 and parameter is None:
        warnings.warn(f"{path!r}: read {kind.upper()}11, the default, of a {ports}-port file; "
                      f"pass parameter='{kind.upper()}21' (command line --parameter "
                      f"{kind.upper()}21) for the transfer from port 1 to port 2",
                      DataWarning, stacklevel=3)
    return _finish(path, omega, response, name, lines=first, band=band,
                   scale=2 * np.pi * _UNITS[unit], file_unit=_SHOWN[unit])
