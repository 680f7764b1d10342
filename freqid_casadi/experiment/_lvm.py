"""The layout of a LabVIEW measurement file (``.lvm``): headers and segments (layer L1).

After NI's "Specification for the LabVIEW Measurement File (.lvm)": a file header
(``LabVIEW Measurement`` first; ``Separator`` Tab or Comma, ``Decimal_Separator``,
``Multi_Headings``, ``X_Columns``, ...) ending in ``***End_of_Header***``, then the data in
segments, one per call of the Write LabVIEW Measurement File express VI. With
``Multi_Headings Yes`` each segment has a header of its own (``Channels``, ``Samples``,
``Date``, ``Time``, ``X0``, ``Delta_X``: one cell per column of its table, closed by
``***End_of_Header***``), then its table (the heading ``X_Value ... Comment``, then one row
per sample); with ``No`` only the first segment has one and the rows of the later ones
follow in the first table. Special blocks (``***Start_Special***`` to
``***End_Special***``) are skipped. :func:`freqid_casadi.experiment.load_records_table`
reads the tables, :func:`freqid_casadi.experiment.lvm_segments` describes the segments.
"""

import datetime
import math
import os
from dataclasses import dataclass

from ..errors import DataError
from ..io import NUMBER

__all__ = ["LvmPart", "lvm_layout", "column_rate", "column_start", "heading"]

_END = "***End_of_Header***"


@dataclass(frozen=True)
class LvmPart:
    """One segment as read: ``number`` (1 for the first), ``line`` (of its table's heading,
    from 1), ``rows`` (``(line, text)`` of its table, the heading first) and ``fields``
    (a header tag to its cells, cell ``j`` for column ``j`` of the table)."""

    number: int
    line: int
    rows: tuple
    fields: dict


def lvm_layout(path, lines):
    """``(separator, decimal comma, parts)`` of a LabVIEW measurement file, ``parts`` a list
    of :class:`LvmPart`; None when ``lines`` are not such a file (first line other than
    ``LabVIEW Measurement``).

    Parameters
    ----------
    path : str or os.PathLike
        The file, for messages.
    lines : list of str
        Its lines.
    """
    if not lines or not lines[0].lstrip("\ufeff").startswith("LabVIEW Measurement"):
        return None
    ends = [k for k, t in enumerate(lines) if t.startswith(_END)]
    if not ends:
        raise DataError(f"{os.fspath(path)!r}: a LabVIEW measurement file without "
                        f"'{_END}'; export it again")
    sep = "," if any(t.startswith("Separator,") for t in lines[:ends[0]]) else "\t"
    head = _fields(lines[1:ends[0]], sep)
    comma = (head.get("Decimal_Separator") or ["", "."])[1:2] == [","]
    seg_ends = ends[1:] or ends            # one End_of_Header: a table without a header
    starts = [ends[0] + 1] + [_header_start(lines, e, prev, sep)
                              for prev, e in zip(seg_ends, seg_ends[1:])]
    parts = []
    for k, e in enumerate(seg_ends):
        stop = starts[k + 1] if k + 1 < len(seg_ends) else len(lines)
        parts.append(LvmPart(k + 1, e + 2, tuple(_table_rows(lines, e + 1, stop)),
                             _fields(lines[starts[k]:e], sep)))
    return sep, comma, parts


def _header_start(lines, end, prev, sep):
    """First line of the segment header that ``***End_of_Header***`` at ``end`` closes: the
    run of tag lines before it (after the previous segment's table, which ends at a blank
    line or at a row of numbers)."""
    j = end
    while j - 1 > prev and _is_tag(lines[j - 1], sep):
        j -= 1
    return j


def _is_tag(text, sep):
    cell = text.split(sep)[0].strip()
    return bool(cell) and not NUMBER.fullmatch(cell.replace(",", "."))


def _table_rows(lines, start, stop):
    """``(line, text)`` of the non-blank lines ``start`` to ``stop`` outside special blocks
    and comments."""
    rows, special = [], False
    for k in range(start, stop):
        text = lines[k]
        cell = text.strip()
        if cell.startswith("***Start_Special***"):
            special = True
        elif special:
            special = not cell.startswith("***End_Special***")
        elif cell and not cell.startswith(("#", "%")):
            rows.append((k + 1, text))
    return rows


def _fields(lines, sep):
    fields = {}
    for text in lines:
        cells = [c.strip() for c in text.rstrip("\r").split(sep)]
        fields.setdefault(cells[0], cells)
    return fields


def heading(text, sep):
    """Column names of a table heading ``text`` (quotes and a trailing separator dropped).

    Parameters
    ----------
    text : str
        The heading line.
    sep : str or None
        The separator (None: whitespace).
    """
    names = [c.strip().strip("\"'").strip() for c in text.split(sep)]
    while names and not names[-1]:
        names.pop()
    return names


def _cell(fields, tag, column):
    """The ``tag`` cell of ``column``, else the first one given (None if none)."""
    cells = fields.get(tag) or []
    if 0 < column < len(cells) and cells[column]:
        return cells[column]
    return next((c for c in cells[1:] if c), None)


def column_rate(fields, column, comma):
    """Hz from the ``Delta_X`` of ``column`` (seconds per sample), else None.

    Parameters
    ----------
    fields : dict
        :attr:`LvmPart.fields`.
    column : int
        Column of the table.
    comma : bool
        The file writes decimal commas.
    """
    dx = _cell(fields, "Delta_X", column)
    dx = dx.replace(",", ".") if dx and comma else dx
    if not dx or not NUMBER.fullmatch(dx):
        return None
    value = float(dx)
    return 1.0 / value if math.isfinite(value) and value > 0 else None


def column_start(fields, column):
    """``(day, seconds)`` of the segment's start from ``Date`` (``YYYY/MM/DD``, the day's
    ordinal) and ``Time`` (``HH:MM:SS.frac``, a decimal comma too, seconds after midnight)
    of ``column``; None when either is missing or unreadable.

    Parameters
    ----------
    fields : dict
        :attr:`LvmPart.fields`.
    column : int
        Column of the table.
    """
    date, time = _cell(fields, "Date", column), _cell(fields, "Time", column)
    try:
        day = datetime.date(*(int(p) for p in date.split("/"))).toordinal()
        h, m, s = time.replace(",", ".").split(":")
        seconds = 3600 * int(h) + 60 * int(m) + float(s)
    except (AttributeError, TypeError, ValueError):
        return None
    return (day, seconds) if math.isfinite(seconds) else None
