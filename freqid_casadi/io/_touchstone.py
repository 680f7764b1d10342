"""Touchstone network-parameter files of any number of ports, v1.x and v2.x (layer L1).

Version 1 (``.s1p``, ``.s2p``, ..., ``.sNp``; the port count from the extension): an option
line ``# <Hz|kHz|MHz|GHz> <S|Y|Z|H|G> <DB|MA|RI> R <ohms>`` (defaults GHz, S, MA), ``!``
comments, then per frequency ``f`` and ``N^2`` pairs: for 2 ports ``11 21 12 22`` on one
line; for 3 and more the matrix row by row (``11 12 ... 1N``, ``21 ...``), each row on its
own line(s), wrapped after 4 pairs. A 2-port file may end with noise parameters (a block
whose frequencies start again lower), which are not read.

Version 2 (``[Version] 2.0``; any extension, e.g. ``.ts``): keywords ``[Number of Ports]``,
``[Two-Port Data Order] 12_21|21_12``, ``[Number of Frequencies]``, ``[Matrix Format]
Full|Lower|Upper`` (a triangle stored row by row, the other half by symmetry),
``[Reference]``, ``[Network Data]``, ``[Noise Data]``, ``[End]``; information blocks
(``[Begin Information]`` ... ``[End Information]``) are skipped. The numbers after
``[Network Data]`` are read as one stream, ``1 + 2 M`` per frequency.

Re-exported by :mod:`freqid_casadi.io.loaders`.
"""

import re
import warnings

import numpy as np

from ._table import NUMBER, decode_text, shown_cell
from ..errors import DataError, OptionError

__all__ = ["load_touchstone", "is_touchstone"]

_UNITS = {"hz": 1.0, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}
_SHOWN = {"hz": "Hz", "khz": "kHz", "mhz": "MHz", "ghz": "GHz"}
_EXT = re.compile(r"\.s(\d{1,3})p$", re.IGNORECASE)
_PARAM = re.compile(r"^([syzhg])_?(\d{1,3})(?:[,_ ](\d{1,3}))?$", re.IGNORECASE)
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
    unit, fmt, kind = "ghz", "ma", "s"
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
        elif tok == "r" and k + 1 < len(tokens):
            k += 1
        else:
            raise DataError(f"{path!r} line {line_no}: unknown option {tok!r} in the Touchstone "
                            "option line; expected e.g. '# GHz S MA R 50'")
        k += 1
    return unit, fmt, kind


def _pairs(fmt, a, b):
    """Complex values of the number pairs ``a``, ``b`` (arrays) in format ``fmt``."""
    if fmt == "ri":
        return a + 1j * b
    with np.errstate(all="ignore"):
        mag = 10.0 ** (a / 20.0) if fmt == "db" else a
        return mag * np.exp(1j * np.deg2rad(b))


def _scan(path, text):
    """Option line, keywords and the numeric lines of a Touchstone text.

    Returns ``(opts, keywords, lines)``: ``opts`` the option line's tokens (or None) with
    its line number, ``keywords`` a dict of lower-case keyword -> (value, line), ``lines``
    the ``(line number, numbers)`` of the network data (noise data and information blocks
    left out).
    """
    opts, keywords, lines, section = None, {}, [], "network"
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
        if section != "network":
            continue
        cells = line.split()
        for c in cells:
            if not NUMBER.fullmatch(c):
                raise DataError(f"{path!r} line {k + 1}: {shown_cell(c)} is not a number")
        lines.append((k + 1, [float(c) for c in cells]))
    return opts, keywords, lines


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


def _records(path, lines, per):
    """The stream of numbers cut into frequency records of ``per`` numbers; the first
    line of each record, for messages."""
    stream = np.array([v for _, nums in lines for v in nums], float)
    starts = np.cumsum([0] + [len(nums) for _, nums in lines])
    if stream.size % per:
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
                              f"only (a reflection); leave parameter out to read it")
        raise OptionError(f"parameter={parameter!r} is not in this {ports}-port "
                          f"{kind.upper()}-parameter file; choose one of {shown} (row = "
                          "receiving port, column = driving port: S21 is from port 1 to 2)")
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
        ``omega = 2 pi f`` (rad/s) with ``f`` in the option line's unit.

    Raises
    ------
    DataError
        An unknown number of ports, a bad option line or keyword, data that are not whole
        records (1 + 2 M numbers per frequency), a cell that is not an ASCII number,
        values outside the floating-point range.
    OptionError
        An unknown ``parameter``.
    """
    from ._readfile import DataWarning, _finish, parse_band, read_regular_file

    band = parse_band(band)
    path, payload = read_regular_file(path)
    opts, keywords, lines = _scan(path, decode_text(path, payload))
    version = keywords.get("version", ("1", 0))[0]
    ports = _ports(path, keywords)
    unit, fmt, kind = _options(path, *(opts or (0, "#")))
    matrix = keywords.get("matrix format", ("full", 0))[0].lower()
    two_port = keywords.get("two-port data order", ("21_12", 0))[0].replace(" ", "").lower()
    if matrix not in ("full", "lower", "upper") or two_port not in ("12_21", "21_12"):
        raise DataError(f"{path!r}: [Matrix Format] {matrix!r} / [Two-Port Data Order] "
                        f"{two_port!r} is not Full/Lower/Upper / 12_21/21_12")
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
    values, first = _records(path, lines, 1 + 2 * len(order))
    count, line = keywords.get("number of frequencies", (None, 0))
    if count is not None and count != str(len(values)):
        raise DataError(f"{path!r} line {line}: [Number of Frequencies] {count} but the "
                        f"network data hold {len(values)} frequencies; fix the count")
    want = (i, j) if (i, j) in order else (j, i)          # a triangle: by symmetry
    col = 1 + 2 * order.index(want)
    with np.errstate(over="ignore"):
        omega = 2 * np.pi * _UNITS[unit] * values[:, 0]
    response = _pairs(fmt, values[:, col], values[:, col + 1])
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
