"""Tables that hold several sweeps one after another (layer L1): an impedance analyser's
export of repeated cycles (EC-Lab's ``cycle number`` column), whose frequency starts
again at each sweep, read one sweep at a time (``record=``)."""

import numpy as np

from ..errors import DataError, OptionError

__all__ = ["sweep_starts", "one_sweep"]


def sweep_starts(f):
    """Row indices where a new sweep begins in the frequencies ``f`` (shape (M,)), or an
    empty list: each sweep strictly monotone, in one direction, of at least 3 rows, and
    each new one starting back by at least half the span of all the frequencies (a point
    out of order within one sweep is no new sweep).

    Parameters
    ----------
    f : ndarray of float, shape (M,)

    Returns
    -------
    list of int
        The first row of each sweep after the first.
    """
    f = np.asarray(f, float)
    d = np.diff(f)
    if d.size < 5 or not np.all(np.isfinite(f)) or not np.all(d != 0):
        return []
    direction = 1.0 if np.count_nonzero(d > 0) >= np.count_nonzero(d < 0) else -1.0
    back = np.flatnonzero(d * direction < 0)
    span = float(np.max(f) - np.min(f))
    starts, first = [], 0
    for i in back:
        if i + 1 - first < 3 or abs(d[i]) < 0.5 * span:
            return []
        starts.append(int(i) + 1)
        first = int(i) + 1
    return starts if starts and f.size - first >= 3 else []


def one_sweep(path, values, rows, record):
    """``(values, rows)`` of sweep ``record`` (0-based) of a table of several sweeps;
    unchanged for a table of one sweep without ``record``.

    Parameters
    ----------
    path : str
        The file, for messages.
    values : dict of str to ndarray
        The table's columns by role (``"freq"`` among them), each shape (M,).
    rows : list of (int, str)
        Each row's file line and text.
    record : int or None

    Returns
    -------
    (dict, list)

    Raises
    ------
    DataError
        Several sweeps and no ``record``: the message names where each starts.
    OptionError
        ``record`` out of range, or given for a table of one sweep.
    """
    starts = sweep_starts(values["freq"])
    if not starts:
        if record is not None:
            raise OptionError(f"record={record!r} chooses a record of a UFF file, a run of an "
                              "LTspice export with .step runs or a sweep of a table of "
                              f"several; {path!r} has none: drop it")
        return values, rows
    bounds = [0] + starts + [len(rows)]
    n = len(bounds) - 1
    if record is None:
        lines = ", ".join(str(rows[s][0]) for s in starts[:6])
        raise DataError(
            f"{path!r} holds {n} sweeps one after another (the frequency starts again on "
            f"line(s) {lines}{', ...' if n > 7 else ''}): pass record=0..{n - 1} to load() "
            "(command line --record K) to read one sweep; if they are parts of one "
            "measurement (a coarse sweep, then a fine one), merge them in Python: "
            "FrequencyData.sorted(omega, response)")
    if isinstance(record, bool) or not isinstance(record, (int, np.integer)):
        raise OptionError(f"record must be an integer (0-based), got {record!r}")
    if not 0 <= record < n:
        raise OptionError(f"record={record!r} is out of range: {path!r} holds {n} sweeps, "
                          f"numbered 0..{n - 1}")
    a, b = bounds[record], bounds[record + 1]
    return {k: v[a:b] for k, v in values.items()}, rows[a:b]
