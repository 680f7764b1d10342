"""Touchstone 1.x ``.s1p``/``.s2p`` network-parameter files, parsed as text (layer L1).

Option line ``# <Hz|kHz|MHz|GHz> <S|Y|Z|H|G> <DB|MA|RI> R <ohms>`` (defaults GHz, S, MA);
``!`` starts a comment. A 1-port row is ``f a b``; a 2-port row ``f 11 21 12 22`` (pairs in
that order, the standard's). Re-exported by :mod:`freqid_casadi.io.loaders`.
"""

import numpy as np

from ._table import NUMBER, decode_text, shown_cell
from ..errors import DataError, OptionError

__all__ = ["load_touchstone"]

_UNITS = {"hz": 1.0, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}
_ORDER = {1: ("11",), 2: ("11", "21", "12", "22")}


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
    return _UNITS[unit], fmt, kind


def _pair(fmt, a, b):
    if fmt == "ri":
        return complex(a, b)
    with np.errstate(all="ignore"):
        mag = np.float64(10.0) ** (a / 20.0) if fmt == "db" else np.float64(a)
        return complex(mag * np.cos(np.deg2rad(b)), mag * np.sin(np.deg2rad(b)))


def load_touchstone(path, name=None, *, parameter=None):
    """Read one network parameter of a Touchstone 1.x ``.s1p`` or ``.s2p`` file.

    Parameters
    ----------
    path : str or path-like
    name : str, optional
    parameter : str, optional
        Which parameter, e.g. ``"S21"`` (the letter must be the file's). Default: ``"11"`` of
        the file's kind (S11 for S-parameters; a 2-port file then warns, DataWarning).

    Returns
    -------
    FrequencyData
        ``omega = 2 pi f`` (rad/s) with ``f`` in the option line's unit.

    Raises
    ------
    DataError
        Not 1 or 2 ports, a bad option line, a row with the wrong count of numbers, a cell
        that is not an ASCII number, values outside the floating-point range.
    OptionError
        An unknown ``parameter``.
    """
    from ._readfile import _finish, read_regular_file

    path, payload = read_regular_file(path)
    ports = {".s1p": 1, ".s2p": 2}.get(path.lower()[-4:])
    if ports is None:
        raise DataError(f"{path!r}: only 1- and 2-port Touchstone files (.s1p, .s2p) are read")
    rows, opts = [], None
    for k, text in enumerate(decode_text(path, payload).split("\n")):
        text = text.split("!", 1)[0].strip()
        if not text:
            continue
        if text.startswith("#"):
            opts = opts or _options(path, k + 1, text)
            continue
        if text.startswith("["):
            raise DataError(f"{path!r} line {k + 1}: Touchstone 2.0 keywords are not read; "
                            "save as Touchstone 1.1")
        cells = text.split()
        if len(cells) != 1 + 2 * ports ** 2:
            raise DataError(f"{path!r} line {k + 1}: expected {1 + 2 * ports ** 2} numbers for "
                            f"a {ports}-port row, got {len(cells)}")
        for c in cells:
            if not NUMBER.fullmatch(c):
                raise DataError(f"{path!r} line {k + 1}: {shown_cell(c)} is not a number")
        rows.append((k + 1, [float(c) for c in cells]))
    if not rows:
        raise DataError(f"{path!r} holds no data rows")
    scale, fmt, kind = opts or _options(path, 0, "#")
    which = (parameter or f"{kind}11").lower()
    if which[:1] != kind or which[1:] not in _ORDER[ports]:
        raise OptionError(f"parameter={parameter!r} is not in this {ports}-port "
                          f"{kind.upper()}-parameter file; choose one of "
                          f"{', '.join(kind.upper() + p for p in _ORDER[ports])}")
    j = 1 + 2 * _ORDER[ports].index(which[1:])
    values = np.array([r[1] for r in rows])
    with np.errstate(over="ignore"):
        omega = 2 * np.pi * scale * values[:, 0]
    response = np.array([_pair(fmt, v[j], v[j + 1]) for v in values])
    bad = ~np.isfinite(omega) | ~np.isfinite(response)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"{path!r} line {rows[i][0]}: the frequency or {which.upper()} is "
                        "outside the floating-point range; check the option line's units")
    if ports == 2 and parameter is None:
        import warnings

        from ._readfile import DataWarning
        warnings.warn(f"{path!r}: read {which.upper()}, the default, of a 2-port file; pass "
                      f"parameter='{kind.upper()}21' (command line --parameter "
                      f"{kind.upper()}21) for the transfer from port 1 to port 2",
                      DataWarning, stacklevel=3)
    return _finish(path, omega, response, name, lines=[r[0] for r in rows])
