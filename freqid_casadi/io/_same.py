"""Columns that give the response again in another form (an analyser's second trace, its
dB or degree column), checked against the response read (layer L1)."""

import warnings

import numpy as np

from ._columns import Column, columns_option
from ..errors import DataError, DataWarning

__all__ = ["check_same", "SAME_RTOL", "SAME_DEGREES"]


#: How closely a column that repeats the response in another form (an analyser's second
#: trace, its dB or degree column) must agree with the response read: the printing
#: precision of such columns (0.01 dB is 0.12 %, 0.01 degree 1.7e-4 rad) with a wide
#: margin; two different measurements differ by far more.
SAME_RTOL, SAME_DEGREES = 0.01, 1.0


def check_same(table, rows, split, response, parse_cell):
    """The skipped columns that give the response again (``Column.same``) agree with the
    response read, to :data:`SAME_RTOL` of ``|G|`` and :data:`SAME_DEGREES`; a
    :class:`DataWarning` says which columns were read.

    Parameters
    ----------
    table : Table
        As read (its ``columns``, ``values``, ``path``).
    rows : list of (int, str)
        Each data row's file line and text.
    split : callable
        ``split(text) -> cells``.
    response : ndarray of complex, shape (M,)
        The response read.
    parse_cell : callable
        ``parse_cell(path, line, column, cell) -> value``.
    """
    size, phase = np.abs(response), np.angle(response)
    cells = [(line, split(text)) for line, text in rows]
    empty = []
    for j, col in enumerate(table.columns):
        if col.same is None or col.same == "phase" and col.unit is None:
            continue
        as_read = Column(col.same, col.unit, col.label)
        x = np.array([parse_cell(table.path, line, as_read, row[j]) for line, row in cells])
        if not np.any(x):
            empty.append(repr(col.label))   # (an analyser's |Z| never filled in: all 0)
            continue
        x = -x if col.negated else x
        with np.errstate(over="ignore", invalid="ignore"):
            if col.same == "phase":
                turn = np.angle(np.exp(1j * ((x if col.unit == "rad" else np.deg2rad(x))
                                             - phase)))
                off = np.abs(turn) > np.deg2rad(SAME_DEGREES)
            else:
                y = {"re": response.real, "im": response.imag, "complex": response,
                     "mag": size}[col.same]
                x = 10.0 ** (x / 20.0) if col.same == "mag" and col.unit == "db" else x
                off = ~(np.abs(x - y) <= SAME_RTOL * size)
        off &= table.values["freq"] != 0
        if off.any():
            i = int(np.flatnonzero(off)[0])
            read = ", ".join(repr(c.label) for c in table.columns
                             if c.role not in ("skip", "freq"))
            raise DataError(
                f"{table.at(i)}: column {col.label!r} is not the response of columns {read} "
                f"in another form (they differ by more than {SAME_RTOL:.0%} or "
                f"{SAME_DEGREES:g} degree): the file holds two measurements; name the "
                f"columns to read, e.g. columns='{columns_option(table.columns)}' (command "
                "line --columns), 'skip' for the others")
    same = [repr(c.label) for c in table.columns if c.same and repr(c.label) not in empty]
    read = ", ".join(repr(c.label) for c in table.columns if c.role != "skip")
    if empty:
        warnings.warn(f"{table.path!r}: read {read}; left out {', '.join(empty)}, whose "
                      "values are all 0 (not filled in)", DataWarning, stacklevel=4)
    if not same:
        return
    one = len(same) == 1
    warnings.warn(f"{table.path!r}: read {read}; {'column' if one else 'columns'} "
                  f"{', '.join(same)} {'gives' if one else 'give'} the same response in "
                  f"another form (checked: within {SAME_RTOL:.0%} and {SAME_DEGREES:g} "
                  "degree)", DataWarning, stacklevel=4)
